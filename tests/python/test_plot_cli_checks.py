"""ellroll-plot on the inputs and options that are not what a subcommand
reads: work-precision CSVs that are not bench/workprecision.py's table
(seeded), --out that is a file or lies under a missing folder, a run's
journal, option values that say nothing (--x, --percentiles without
--suite); and where its tables go: `fragility --format csv|json|table -o
FILE` writes FILE with the same care as a figure. Each bad input ends in
one line naming the file or the option and the reason, exit 2, nothing
written; never a traceback."""
import csv
import io
import math
import os
import random
import re
import shutil
import signal
import subprocess
import sys
import time
import urllib.parse
import warnings

import numpy as np
import pandas as pd
import pytest

pytest.importorskip("matplotlib")

from ellroll_post import suite  # noqa: E402
from ellroll_post.cli import workprecision_points  # noqa: E402
from conftest import FULL, ROOT, pairs_in_turn  # noqa: E402
# (the fixtures: the shaken sweep whole.h5 and the record suite suite.h5; a killed run's files)
from test_plot_cli_inputs import PER_CASE, SUBCOMMANDS, arguments, cli, files, killed, one_line_error  # noqa: E402,F401

HEADER = ["method", "setting", "error_m", "time_s", "rhs_evaluations"]
NUMERIC = ["error_m", "time_s", "rhs_evaluations"]
NOT_NUMBERS = ["abc", "", "1e", "--", "0x10", "1,5", "one", "1.2.3", "e3", "1e3e3", "[1]", "'1'", "1 2"]


def good_rows(rng, count):
    """A table as bench/workprecision.py writes it: per method, error falls as time and RHS rise."""
    rows = []
    for i in range(count):
        method = rng.choice(["ellroll rk4", "ellroll dop853", "SciPy DOP853"])
        rhs = rng.randint(100, 10**6)
        rows.append([method, f"dt={rng.choice([0.1, 0.01, 0.001])}", repr(rng.uniform(1e-12, 1e-2)),
                     repr(rng.uniform(1e-5, 1.0)), str(rhs)])
    return rows


def table_text(header, rows):
    out = io.StringIO()
    writer = csv.writer(out, lineterminator="\n")
    writer.writerow(header)
    writer.writerows(rows)
    return out.getvalue()


def bad_table(rng, folder, trial):
    """A seeded CSV that is not a drawable work-precision table: (path, words its error line must hold)."""
    name = folder / f"wp{trial}.csv"
    rows = good_rows(rng, rng.randint(1, 6))
    kind = rng.choice(["columns", "value", "short", "binary", "empty", "header", "no_point", "missing"])
    if kind == "columns":
        dropped = sorted(rng.sample(["method", *NUMERIC], rng.randint(1, 4)), key=HEADER.index)
        keep = [i for i, c in enumerate(HEADER) if c not in dropped]
        rng.shuffle(keep)
        name.write_text(table_text([HEADER[i] for i in keep], [[r[i] for i in keep] for r in rows]))
        return name, ["missing columns " + ", ".join(dropped)]
    if kind == "value":
        row, column = rng.randrange(len(rows)), rng.choice(NUMERIC)
        value = rng.choice(NOT_NUMBERS)
        rows[row][HEADER.index(column)] = value
        name.write_text(table_text(HEADER, rows))
        return name, [f"{name}:{row + 2}: {column} = {value!r} is not a number"]
    if kind == "short":
        row, cut = rng.randrange(len(rows)), rng.randint(1, 3)
        rows[row] = rows[row][:len(HEADER) - cut]
        name.write_text(table_text(HEADER, rows))
        return name, [f"{name}:{row + 2}: no {HEADER[len(HEADER) - cut]}"]
    if kind == "binary":
        data = bytes(rng.randrange(256) for _ in range(rng.randint(1, 200))) + b"\xff\xfe"
        name.write_bytes(rng.choice([b"", b"\x89HDF\r\n\x1a\n", table_text(HEADER, rows).encode()]) + data)
        return name, ["not text"]
    if kind == "empty":
        name.write_bytes(b"")
        return name, ["an empty file"]
    if kind == "header":
        name.write_text(table_text(HEADER, []))
        return name, ["no rows"]
    if kind == "no_point":
        for row in rows:
            row[HEADER.index(rng.choice(["error_m", "time_s"]))] = rng.choice(["0", "-1e-3", "nan", "inf", "-inf"])
        name.write_text(table_text(HEADER, rows))
        return name, ["no point to draw"]
    return name, [f"{name}: no such file"]


def test_bad_workprecision_tables_are_one_line_and_write_nothing(tmp_path):
    """60 seeded CSVs that are not bench/workprecision.py's table (columns
    missing, a value that is not a number, a short row, binary bytes, an
    empty file, a header alone, no positive finite point, no file): exit 2,
    one line naming the file (and the row and column of a bad value), no
    figure."""
    rng = random.Random(20261127)
    out = tmp_path / "figures"
    out.mkdir()
    for trial in range(60):
        path, words = bad_table(rng, tmp_path, trial)
        code, stdout, err = cli("workprecision", path, "--out", out, "--overwrite")
        one_line_error(code, err, str(path), *words)
        assert not stdout and list(out.iterdir()) == [], (path, err)


def test_a_good_workprecision_table_draws_its_points(tmp_path):
    """A table as the bench writes it (seeded), its columns in any order:
    the points read are its numbers, per method; the figure is written."""
    rng = random.Random(5)
    rows = good_rows(rng, 12)
    order = HEADER[:]
    rng.shuffle(order)
    path = tmp_path / "wp.csv"
    path.write_text(table_text(order, [[r[HEADER.index(c)] for c in order] for r in rows]))
    expected = {}
    for r in rows:
        expected.setdefault(r[0], []).append(tuple(float(r[HEADER.index(c)]) for c in NUMERIC))
    assert workprecision_points([path]) == expected
    code, stdout, err = cli("workprecision", path, "--out", tmp_path)
    assert code == 0 and stdout.strip() == str(tmp_path / "wp_workprecision.png"), err


# ------------------------------------------------------------------ --out
def out_arguments(command, files, out):
    path = files / ("suite.h5" if command in ("suite", "fragility") else "whole.h5")
    if command == "workprecision":
        path = files / "whole.h5"
    args = [command, path, "--out", out]
    return args + (["--bootstrap", 0] if command == "fragility" else [])


FIGURES = [c for c in SUBCOMMANDS if c != "summary"]


@pytest.mark.parametrize("command", FIGURES)
def test_out_must_be_a_folder_and_only_its_last_level_is_made(files, tmp_path, command):
    """--out naming a file: one line saying --out must be a folder, the file
    as it was. --out under a folder that is not there (seeded depths): one
    line naming the missing parent, nothing made. --out whose parent is
    there: made, the figures in it."""
    rng = random.Random(command)
    existing = tmp_path / "l.nml"
    existing.write_text("&geometry a = 1.0 /\n")
    code, stdout, err = cli(*out_arguments(command, files, existing))
    one_line_error(code, err, f"--out {existing}", "not a folder")
    assert existing.read_text() == "&geometry a = 1.0 /\n" and not stdout
    for _ in range(3):
        depth = rng.randint(2, 5)
        deep = tmp_path.joinpath("typo", *(f"d{rng.randrange(100)}" for _ in range(depth - 1)))
        code, stdout, err = cli(*out_arguments(command, files, deep))
        one_line_error(code, err, f"--out {deep}", f"no folder {deep.parent}")
        assert not (tmp_path / "typo").exists() and not stdout
    fresh = tmp_path / "fresh"
    code, stdout, err = cli(*out_arguments(command, files, fresh))
    assert fresh.is_dir()
    if command == "transmissibility":       # (whole.h5's cases are too short for one: one line, the file's)
        one_line_error(code, err, "whole.h5", "no transmissibility")
        return
    assert code == 0, err
    assert stdout and all(pathlib_under(line, fresh) for line in stdout.split()), stdout


def pathlib_under(text, folder):
    return os.path.dirname(os.path.abspath(text)) == str(folder)


# ------------------------------------------------------- fragility -o FILE
@pytest.mark.parametrize("fmt", ["csv", "json", "table"])
def test_fragility_tables_go_to_o_with_a_figures_care(files, tmp_path, fmt):
    """`fragility --format csv|json|table -o FILE` writes FILE, its text the
    one printed without -o or with -o - (-o '' and a figure to - are one
    line each; the CSV read back gives the same fits), and
    prints FILE; kept without --overwrite, replaced with it; never written
    through a symbolic link, never over a file ellroll-plot did not make;
    a missing folder above it is one line."""
    suite_file = files / "suite.h5"
    common = ["fragility", suite_file, "--bootstrap", 20, "--seed", 3, "--format", fmt]
    code, printed, err = cli(*common)
    assert code == 0, err
    cwd = os.getcwd()
    os.chdir(tmp_path)
    try:
        code, dashed, err = cli(*common, "-o", "-")          # standard output, as the usual tools take '-'
        assert code == 0 and dashed == printed, err
        code, stdout, err = cli(*common, "-o", "")
        one_line_error(code, err, "-o '': give a file name")
        assert not stdout
        code, stdout, err = cli("fragility", suite_file, "--bootstrap", 20, "--format", "png", "-o", "-")
        one_line_error(code, err, "-o -: a png figure goes to a file")
    finally:
        os.chdir(cwd)
    assert not list(tmp_path.iterdir())
    target = tmp_path / f"frag.{fmt}"
    code, stdout, err = cli(*common, "-o", target)
    assert code == 0 and stdout.strip() == str(target), err
    assert target.read_text() == printed
    if fmt == "csv":
        rows = list(csv.DictReader(io.StringIO(target.read_text())))
        assert {r["limit_state"] for r in rows} == {"drift", "model_limit"}
        assert all(float(r["theta"]) > 0 or math.isnan(float(r["theta"])) for r in rows)
    stamp = target.stat().st_mtime_ns
    code, stdout, err = cli(*common, "-o", target)
    one_line_error(code, err, str(target), "give --overwrite")
    assert target.stat().st_mtime_ns == stamp and not stdout
    code, stdout, err = cli(*common, "-o", target, "--overwrite")
    assert code == 0 and target.read_text() == printed, err
    victim = tmp_path / "victim.txt"
    victim.write_text("mine\n")
    link = tmp_path / f"link.{fmt}"
    link.symlink_to(victim)
    foreign = tmp_path / f"foreign.{fmt}"
    foreign.write_text("theta,beta\n1,2\n")
    for path, words in ((link, "symbolic link"), (foreign, "not made by ellroll-plot")):
        code, stdout, err = cli(*common, "-o", path, "--overwrite")
        one_line_error(code, err, str(path), words)
        assert not stdout
    assert victim.read_text() == "mine\n" and foreign.read_text() == "theta,beta\n1,2\n" and link.is_symlink()
    code, stdout, err = cli(*common, "-o", tmp_path / "no" / "such" / "f.csv")
    one_line_error(code, err, f"no folder {tmp_path / 'no'}")
    assert not (tmp_path / "no").exists()
    assert sorted(p.name for p in tmp_path.iterdir()) == sorted([target.name, victim.name, link.name, foreign.name])


# ---------------------------------------------------------------- journal
@pytest.mark.parametrize("command", SUBCOMMANDS)
def test_a_runs_journal_is_named_as_such(killed, tmp_path, command):
    """Each subcommand on a killed run's OUT.h5.journal: one line saying it
    is the journal of an unfinished run, with the command that finishes
    it (its lock's, with --resume); not HDF5's 'file signature not found'.
    A file that only has the journal's name is not called one."""
    code, _, err = cli(*arguments(command, killed / "k.h5.journal", tmp_path))
    one_line_error(code, err, "k.h5.journal", "journal of an unfinished run",
                   "'ellroll run k.nml -q --threads 1 --resume'", "then read", "k.h5")
    assert "signature" not in err
    other = tmp_path / "notes.journal"
    other.write_text("a diary\n")
    code, _, err = cli(*arguments(command, other, tmp_path))
    one_line_error(code, err, "notes.journal", "cannot open as HDF5")
    assert "journal of" not in err


# ---------------------------------------------------- options that say nothing
def test_sweep_x_names_one_or_two_different_inputs(files, tmp_path):
    """--x of `sweep`: seeded lists with an empty name, a name twice, or
    more than two names: exit 2, one line naming --x, no figure."""
    rng = random.Random(66)
    names = ["excitation_frequency", "omega_z", "radius", "theta_max"]
    values = ["", ",", "excitation_frequency,", ",excitation_frequency", "excitation_frequency,excitation_frequency"]
    for _ in range(12):
        picked = [rng.choice(names + [""]) for _ in range(rng.randint(1, 4))]
        if len(picked) == 1:
            picked.append(picked[0])
        values.append(",".join(picked))
    for value in values:
        count = len(value.split(","))
        if count <= 2 and all(value.split(",")) and len(set(value.split(","))) == count:
            continue
        code, stdout, err = cli("sweep", files / "whole.h5", "--out", tmp_path, "--x", value)
        one_line_error(code, err, "--x")
        assert not stdout
    assert list(tmp_path.iterdir()) == []
    code, stdout, err = cli("sweep", files / "whole.h5", "--out", tmp_path, "--x", "excitation_frequency")
    assert code == 0 and stdout.strip().endswith("whole_sweep_excitation_frequency.png"), err


@pytest.mark.parametrize("value", ["linear", "lognormal"])
def test_percentiles_without_suite_is_refused(files, value):
    """--percentiles is what `summary --suite` computes: without --suite it
    is one line, exit 2, nothing printed; with it the suite's table."""
    code, stdout, err = cli("summary", files / "suite.h5", "--percentiles", value)
    one_line_error(code, err, "--percentiles", "--suite")
    assert not stdout
    code, stdout, err = cli("summary", files / "suite.h5", "--suite", "--percentiles", value, "--format", "csv")
    assert code == 0 and stdout.startswith("scale,"), err


# ------------------------------------------------------------------- docs
def test_the_suite_csv_writes_nan_as_the_per_case_csv_does(files):
    """docs/output.md: NaN in the CSVs. A suite table with seeded NaN cells
    (and the suite file's CSV): every undefined cell is written NaN, never
    nan, and reads back as the same numbers."""
    rng = np.random.default_rng(11)
    values = rng.normal(size=(5, 4))
    values[rng.random(values.shape) < 0.4] = np.nan
    table = pd.DataFrame(values, columns=["scale", "x_p16", "x_p50", "x_p84"])
    text = suite.format_suite(table, "csv")
    cells = [c for line in text.splitlines()[1:] for c in line.split(",")]
    assert "nan" not in cells and cells.count("NaN") == int(np.isnan(values).sum())
    np.testing.assert_array_equal(pd.read_csv(io.StringIO(text)).to_numpy(), values)
    code, stdout, _ = cli("summary", files / "suite.h5", "--suite", "--format", "csv")
    assert code == 0 and not re.search(r"(^|,)nan(,|$)", stdout, re.M), stdout


def test_the_readme_table_lists_every_subcommand():
    """post/README.md's ellroll-plot table has a row per subcommand of
    `ellroll-plot --help`, and no other."""
    code, stdout, _ = cli("--help")
    assert code == 0
    listed = re.search(r"\{([a-z,]+)\}", stdout).group(1).split(",")
    text = (ROOT / "post" / "README.md").read_text()
    rows = re.findall(r"^\| `([a-z]+) ", text, re.M)
    assert sorted(rows) == sorted(listed), (rows, listed)
    assert set(PER_CASE) < set(listed)


def plot_process(args, **options):
    """ellroll-plot of the checkout (python -m ellroll_post.cli) as its own process."""
    environment = {**os.environ, "PYTHONPATH": os.pathsep.join([str(ROOT / "post"),
                                                                os.environ.get("PYTHONPATH", "")])}
    return subprocess.run([sys.executable, "-m", "ellroll_post.cli", *map(str, args)], stderr=subprocess.PIPE,
                          text=True, env=environment, timeout=300, **options)


@pytest.mark.parametrize("command, lost", pairs_in_turn(["nutation", "sweep", "suite", "report", "fragility",
                                                        "fragility-csv", "summary", "workprecision"],
                                                       ["full", "closed"]))
def test_standard_output_that_cannot_be_written_is_one_line(files, tmp_path, command, lost):
    """ellroll-plot with its standard output on a full device (/dev/full)
    or closed (`>&-`, as a daemon or a cron line may start it; Python then
    has no sys.stdout): every subcommand, a figure's or the text's, with
    one of the two in turn (both with ELLROLL_TEST_FULL), ends in one line
    naming standard output and the system's reason, exit 2, never a
    traceback."""
    if lost == "full" and not os.path.exists("/dev/full"):
        pytest.skip("no /dev/full")
    source = files / ("suite.h5" if command.startswith(("suite", "fragility")) else "whole.h5")
    args = arguments(command.split("-")[0], source, tmp_path / "out")
    if command == "fragility-csv":
        args += ["--format", "csv"]
    if lost == "full":
        with open("/dev/full", "w") as full:
            result = plot_process(args, stdout=full)
        reason = "No space left on device"
    else:
        result = plot_process(args, preexec_fn=lambda: os.close(1))
        reason = "Bad file descriptor"
    one_line_error(result.returncode, result.stderr, "cannot write the standard output", reason)


@pytest.mark.parametrize("args", [["--help"], ["trace", "--help"], ["report", "-h"]])
def test_help_that_cannot_be_written_is_one_line(args):
    """--help of ellroll-plot and of a subcommand with standard output on
    a full device: one line, exit 2, as any other output."""
    if not os.path.exists("/dev/full"):
        pytest.skip("no /dev/full")
    with open("/dev/full", "w") as full:
        result = plot_process(args, stdout=full)
    one_line_error(result.returncode, result.stderr, "cannot write the standard output", "No space left on device")


def folder_state(folder):
    """{name: bytes} of every file in a folder (hidden ones included)."""
    return {p.name: p.read_bytes() for p in folder.iterdir()} if folder.exists() else None


@pytest.mark.parametrize("source", ["whole", "suite"])
def test_a_report_that_fails_leaves_its_folder_as_it_was(files, tmp_path, source):
    """`report --out DIR` where some of the report's files are there already
    (seeded: which ones, and whether ellroll-plot made them or a user did):
    without --overwrite, or over a user's file, one line, exit 2, and DIR
    holds what it held, byte for byte, no new or hidden file; with
    --overwrite over its own files, the whole report, nothing else. (Each
    of the four kinds of trial once; six trials with ELLROLL_TEST_FULL.)"""
    reference = tmp_path / "reference"
    code, out, err = cli("report", files / f"{source}.h5", "--out", reference)
    assert code == 0, err
    names = sorted(p.name for p in reference.iterdir())
    assert len(names) >= 4 and "index.html" in names and not any(n.startswith(".") for n in names), names
    rng = random.Random(1210 + len(source))
    for trial in range(6) if FULL else (0, 1, 2, 5):
        folder = tmp_path / f"out{trial}"
        folder.mkdir()
        (folder / "notes.txt").write_text("a user's file\n")
        there = rng.sample(names, rng.randint(1, 2))
        users = trial % 3 == 2
        for name in there:
            (folder / name).write_bytes(b"a user's file\n" if users else (reference / name).read_bytes())
        before = folder_state(folder)
        overwrite = trial % 2 == 1
        code, out, err = cli("report", files / f"{source}.h5", "--out", folder, *(["--overwrite"] * overwrite))
        if overwrite and not users:
            assert code == 0, err
            assert sorted(folder_state(folder)) == sorted(names + ["notes.txt"]), trial
            continue
        one_line_error(code, err, folder.name)
        assert folder_state(folder) == before, (trial, there, sorted(folder_state(folder)))


def test_a_report_of_a_file_with_no_case_makes_nothing(ellroll, files, tmp_path):
    """An empty shard (7/8 of six cases): `report` says it holds no case,
    exit 2, and makes no FILE_report folder (nor any other file)."""
    shutil.copytree(files / "records", tmp_path / "records")
    shutil.copy(files / "whole.nml", tmp_path / "whole.nml")
    result = subprocess.run([str(ellroll), "run", "whole.nml", "-q", "--shard", "7/8", "-o", "e.h5"], cwd=tmp_path,
                            capture_output=True, text=True)
    assert result.returncode == 0, result.stderr
    before = sorted(p.name for p in tmp_path.iterdir())
    code, _, err = cli("report", tmp_path / "e.h5")
    one_line_error(code, err, "e.h5", "holds no case")
    assert sorted(p.name for p in tmp_path.iterdir()) == before


def test_suite_statistics_of_a_shard_say_they_are_over_part_of_the_campaign(ellroll, files, tmp_path):
    """The record suite's shards (seeded I/N): `summary --suite`, `suite` and
    `fragility` (figure and table) on a shard's file each print what they
    print for it and one warning line naming the shard, the cases it holds
    of the campaign's and `ellroll merge`; suite_statistics and
    suite_fragility warn (PartOfTheCampaign) likewise; on the whole suite
    and on the merged shards, no warning."""
    from ellroll_post.suite import PartOfTheCampaign, suite_fragility, suite_statistics
    import ellroll_post
    shutil.copytree(files / "records", tmp_path / "records")
    shutil.copy(files / "suite.nml", tmp_path / "suite.nml")
    rng = random.Random(1211)
    shards = rng.choice([2, 3])
    for i in range(shards):
        result = subprocess.run([str(ellroll), "run", "suite.nml", "-q", "--shard", f"{i}/{shards}", "-o",
                                 f"s{i}.h5"], cwd=tmp_path, capture_output=True, text=True)
        assert result.returncode == 0, result.stderr
    assert subprocess.run([str(ellroll), "merge", "m.h5", *(f"s{i}.h5" for i in range(shards))], cwd=tmp_path,
                          capture_output=True).returncode == 0
    commands = [["summary", "--suite"], ["suite", "--out", tmp_path / "o", "--overwrite"],
                ["fragility", "--bootstrap", 0, "--out", tmp_path / "o", "--overwrite"],
                ["fragility", "--bootstrap", 0, "--format", "csv"]]
    warned = 0
    for path in [files / "suite.h5", tmp_path / "m.h5", *(tmp_path / f"s{i}.h5" for i in range(shards))]:
        shard = path.name.startswith("s") and path.name != "suite.h5"
        with ellroll_post.open(path) as run_:
            held = len(run_.cases)
            with warnings.catch_warnings(record=True) as caught:
                warnings.simplefilter("always")
                suite_statistics(run_)
                try:
                    suite_fragility(run_)
                except suite.NoStripes:
                    pass                # (a shard of one scale: no fragility, but the same warning first)
            notes = [str(w.message) for w in caught if issubclass(w.category, PartOfTheCampaign)]
            assert bool(notes) == shard, (path, notes)
        for command in commands:
            code, out, err = cli(command[0], path, *command[1:])
            if shard and code == 2 and ("hold" in err or "not a record suite" in err or "no stripes" in err):
                assert len(err.strip().splitlines()) == 1, err
                continue                # (a shard of one record or one scale: no suite's figure, one line)
            assert code == 0 and out, (path, command, err)
            lines = err.strip().splitlines()
            if not shard:
                assert lines == [], (path, command, err)
                continue
            index = path.stem[1:]
            assert lines == [f"ellroll-plot: warning: {path}: over {held} of the campaign's 6 cases only: shard "
                             f"{index}/{shards} (merge the shards first: ellroll merge)"], (command, err)
            warned += 1
        # ellroll's own `summary --suite` (no Python needed) says the same
        for form in ("table", "csv", "json"):
            result = subprocess.run([str(ellroll), "summary", str(path), "--suite", "--format", form],
                                    capture_output=True, text=True)
            assert result.returncode == 0 and result.stdout, (path, form, result.stderr)
            expected = [f"ellroll: warning: {path}: over {held} of the campaign's 6 cases only: shard "
                        f"{path.stem[1:]}/{shards} (merge the shards first: ellroll merge)"] if shard else []
            assert result.stderr.strip().splitlines() == expected, (path, form, result.stderr)
    assert warned >= shards                 # (summary --suite of every shard at least)


def test_plot_transmissibility_refuses_what_the_command_refuses(files, tmp_path):
    """plot_transmissibility on each file: where `ellroll-plot
    transmissibility` refuses it (no sweep of the excitation frequency), the
    function raises NotAnEllrollFile with the command's line; where the
    command draws, so does the function."""
    import matplotlib.pyplot as plt
    import ellroll_post
    from ellroll_post import plots
    for name in ["whole.h5", "suite.h5", "shard_0.h5", "shard_2.h5"]:
        code, _, err = cli("transmissibility", files / name, "--out", tmp_path, "--overwrite")
        fig, ax = plt.subplots()
        with ellroll_post.open(files / name) as run_:
            try:
                plots.plot_transmissibility(ax, run_)
                refused = None
            except ellroll_post.NotAnEllrollFile as exc:
                refused = str(exc)
        plt.close(fig)
        if code == 0:
            assert refused is None, (name, refused)
        else:
            one_line_error(code, err, name)
            assert err.strip() == f"ellroll-plot: error: {refused}", (name, err, refused)
    code, _, err = cli("transmissibility", files / "suite.h5", "--out", tmp_path)
    one_line_error(code, err, "needs a sweep of excitation_frequency")


@pytest.mark.parametrize("stop", ["SIGTERM", "SIGINT"])
@pytest.mark.parametrize("overwrite", [False, True])
def test_a_report_stopped_by_a_signal_leaves_nothing_and_says_so_in_one_line(files, tmp_path, stop, overwrite):
    """`report` stopped by SIGTERM (a batch system's time limit) or SIGINT
    while it draws, in a new folder or over its own report (--overwrite):
    one line naming the signal, exit 128 + its number, no hidden temporary
    folder left anywhere, and an existing report as it was, byte for byte."""
    source = tmp_path / "whole.h5"
    shutil.copy(files / "whole.h5", source)
    report = tmp_path / "whole_report"
    environment = {**os.environ, "PYTHONPATH": os.pathsep.join([str(ROOT / "post"),
                                                                os.environ.get("PYTHONPATH", "")])}
    command = [sys.executable, "-m", "ellroll_post.cli", "report", str(source)]
    if overwrite:
        assert plot_process(command[3:], cwd=tmp_path).returncode == 0
        command.append("--overwrite")
    before = folder_state(report)
    process = subprocess.Popen(command, cwd=tmp_path, env=environment, stderr=subprocess.PIPE, text=True)
    deadline = time.monotonic() + 60
    # the signal once its temporary folder is there: it is drawing
    while not any(p.name.startswith(".") for p in [*tmp_path.iterdir(), *(report.iterdir() if report.is_dir() else [])]):
        assert process.poll() is None and time.monotonic() < deadline, "it ended before it drew"
        time.sleep(0.005)
    process.send_signal(getattr(signal, stop))
    _, err = process.communicate(timeout=60)
    number = getattr(signal, stop).value
    assert process.returncode == 128 + number, err
    assert err == f"ellroll-plot: stopped by {stop}; nothing half written is left\n", err
    hidden = [p for p in [*tmp_path.iterdir(), *(report.iterdir() if report.is_dir() else [])] if p.name.startswith(".")]
    assert hidden == [], hidden
    assert folder_state(report) == before


@pytest.mark.parametrize("name", [os.fsdecode(b"r\xe9.h5"), "x$^$y.h5"])
def test_a_file_name_not_utf8_or_with_dollars_is_drawn_as_it_is(files, tmp_path, name):
    """A file name whose bytes are not UTF-8 (an old archive's Latin-1) or
    that holds '$' pairs (matplotlib's mathtext): the figures that name the
    file draw it as text, and the report's page shows it with its bytes as
    \\xNN, a valid UTF-8 page whose links reach the figures."""
    shutil.copy(files / "suite.h5", tmp_path / name)
    for command in ("reaction", "energy", "spectrum", "fragility", "report"):
        code, _, err = cli(*arguments(command, tmp_path / name, tmp_path / "out"))
        assert code == 0 and err == "", (command, err)
    report = tmp_path / "out" if (tmp_path / "out" / "index.html").exists() else tmp_path / (name[:-3] + "_report")
    page = (report / "index.html").read_bytes().decode("utf-8")
    shown = os.fsencode(name).decode("utf-8", "backslashreplace")
    assert f"/{shown}</title>" in page
    for link in re.findall(r'<img src="([^"]+)"', page):
        assert (report / os.fsdecode(urllib.parse.unquote_to_bytes(link))).is_file(), link


def test_an_unknown_option_is_named_by_the_subcommand_it_follows(files, tmp_path):
    """`ellroll-plot SUBCOMMAND FILE --no-such 3` (every subcommand): one
    line, exit 2, naming the subcommand and its --help, as its other option
    errors do; an unknown option before the subcommand is ellroll-plot's."""
    for command in SUBCOMMANDS:
        source = files / ("suite.h5" if command in ("suite", "fragility") else "whole.h5")
        code, _, err = cli(*arguments(command, source, tmp_path / "out"), "--no-such", 3)
        one_line_error(code, err, f"ellroll-plot {command}: error: unrecognized arguments: --no-such 3",
                       f"(see 'ellroll-plot {command} --help')")
    code, _, err = cli("--no-such", "summary", files / "whole.h5")
    one_line_error(code, err, "ellroll-plot: error: unrecognized arguments: --no-such", "(see 'ellroll-plot --help')")
