"""ellroll-plot and the reader on the inputs that meet them outside a
tidy campaign, every subcommand over each: a shard's file (--case is the
global case index, as `ellroll summary` and /case/index give it), an HDF5
file with one flipped bit in its tables (seeded), a killed run's work file
(OUT.h5.partial, kill -9), bad numeric options (seeded), and a FIFO
named as the file. Each ends in
the figure or text asked for (exit 0) or in one line naming the file and
the reason (exit 2), never a traceback."""
import contextlib
import csv
import io
import os
import pathlib
import random
import shutil
import signal
import subprocess
import sys
import time
import traceback

import h5py
import numpy as np
import pytest

matplotlib = pytest.importorskip("matplotlib")
matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402

import ellroll_post  # noqa: E402
from conftest import ROOT, in_turn, plot_in_process, run  # noqa: E402
from test_campaign import kill_after_records, record_bytes  # noqa: E402

CUP = """&geometry    a = 1.0, b = 0.4, c = 0.2 /
&ball        radius = 0.2, weight = 2620.0 /
&initial     x = 0.0, y = 0.0, omega = 0.0, 0.0, 0.0 /
&integration method = 'rk4', dt = 1.0e-3, t_end = {t_end}{estimate} /
&output      file = '{name}.h5', interval = 0.02, fields = 'all' /
"""
# a harmonic sweep: every per-case figure applies (spectrum: a moving cup), and
# transmissibility, sweep and workprecision (error_estimate = 'reference') too
SHAKEN = ("&excitation kind = 'harmonic', amplitude = 0.3, 0.1, 0.0, frequency = 0.5 /\n"
          "&sweep name = 'excitation_frequency', values = 0.3, 0.4, 0.5, 0.6, 0.7, 0.8 /\n")
SUITE = ("&excitation kind = 'record' /\n"
         "&record name = 'SYN1', record_file = 'records/SYN1_H1.AT2', 'records/SYN1_H2.AT2' /\n"
         "&record name = 'SYN3', record_file = 'records/SYN3_H1.AT2', 'records/SYN3_H2.AT2', factor = 1.5 /\n"
         "&sweep name = 'scale', values = 1.0, 2.0, 4.0 /\n"
         "&limit_state name = 'drift', figure = 'displacement_max', capacity = 0.05 /\n")
PER_CASE = ["trace", "nutation", "reaction", "energy", "spectrum", "report"]
SUBCOMMANDS = PER_CASE + ["sweep", "transmissibility", "suite", "fragility", "workprecision", "summary"]
SHARDS = 3


def write(folder, name, extra, t_end=2.0, estimate=True):
    text = CUP.format(name=name, t_end=t_end, estimate=", error_estimate = 'reference'" if estimate else "")
    (folder / f"{name}.nml").write_text(text + extra)
    return f"{name}.nml"


@pytest.fixture(scope="module")
def files(ellroll, tmp_path_factory):
    """The shaken sweep whole (whole.h5) and as shards (shard_I.h5), and a
    record suite (suite.h5)."""
    folder = tmp_path_factory.mktemp("plot_inputs")
    shutil.copytree(ROOT / "input" / "records", folder / "records")
    shaken = write(folder, "whole", SHAKEN)
    suite = write(folder, "suite", SUITE, t_end=4.0, estimate=False)
    runs = [(shaken, ["-o", "whole.h5"]), (suite, [])]
    runs += [(shaken, ["--shard", f"{i}/{SHARDS}", "-o", f"shard_{i}.h5"]) for i in range(SHARDS)]
    for name, options in runs:
        result = run(ellroll, "run", name, "-q", "--threads", 2, *options, cwd=folder)
        assert result.returncode == 0, result.stderr
    return folder


def cli(*args):
    """ellroll-plot in this process: (exit code, stdout, stderr); a
    traceback is returned as standard error with code 'traceback'."""
    try:
        result = plot_in_process(*args)
    except Exception as exc:           # noqa: BLE001 - a traceback is the failure asserted against
        return "traceback", "", "Traceback (most recent call last):\n" + "".join(traceback.format_exception(exc))
    return result.returncode, result.stdout, result.stderr


def one_line_error(code, err, *words):
    """Exit 2 and one line on standard error holding every word."""
    lines = err.strip().splitlines()
    assert code == 2 and "Traceback" not in err and len(lines) == 1, (code, err)
    assert lines[0].startswith("ellroll-plot"), err
    for word in words:
        assert word in lines[0], (word, err)


def arguments(command, path, out):
    """The arguments of a subcommand on a file (figures into out)."""
    if command == "summary":
        return [command, path]
    if command == "fragility":
        return [command, path, "--out", out, "--bootstrap", 0]
    return [command, path, "--out", out, "--overwrite"]


def held_cases(index, shards=SHARDS, cases=6):
    return list(range(index, cases, shards))


# -------------------------------------------------------- shards and --case
@pytest.mark.parametrize("command", PER_CASE)
def test_case_is_the_global_index_on_a_shard(files, tmp_path, command):
    """On shard 1/3 (cases 1 and 4) --case 4 draws global case 4 and says
    so; no --case draws the shard's first case (1); a case the shard does
    not hold (0, 2, 5, the row counts 0 and 1 among them) is refused,
    naming the file and the cases it holds."""
    shard = files / "shard_1.h5"
    with h5py.File(shard, "r") as f:
        assert f["case/index"][:].tolist() == held_cases(1)
    for case, stem in ((4, "_case4"), (None, "_case1")):
        code, out, err = cli(*arguments(command, shard, tmp_path), *(["--case", case] if case is not None else []))
        assert code == 0 and "Traceback" not in err, err
        if command != "report":
            assert out.strip().endswith(f"{stem}.png"), out
        else:
            index = (tmp_path / "index.html").read_text()
            assert f"Per-case figures show case {stem[5:]}." in index, index
    for case in (0, 2, 5, 6, -1):
        code, _, err = cli(*arguments(command, shard, tmp_path), "--case", case)
        one_line_error(code, err, "shard_1.h5", f"case {case} ", "holds cases 1, 4")


@pytest.mark.parametrize("figure", ["trace", "nutation", "reaction", "energy", "spectrum"])
def test_a_shards_case_draws_that_cases_data(files, figure):
    """The API's case arguments are global indices too: a shard's case 4
    draws the same lines, under the same title, as case 4 of the whole
    campaign's file; its trajectories, inputs, summary and status are
    those of case 4."""
    draw = getattr(ellroll_post, f"plot_{figure}")

    def drawn(path, case):
        with ellroll_post.open(path) as f:
            fig, axes = plt.subplots(3, 1) if figure == "reaction" else plt.subplots()
            draw(axes, f, case)
            axes = np.atleast_1d(axes)
            lines = [(ln.get_label(), np.asarray(ln.get_xydata())) for ax in axes for ln in ax.get_lines()]
            titles = [ax.get_title() for ax in axes]
            plt.close(fig)
        return lines, titles

    for shard, case in ((1, 4), (2, 2), (2, 5)):
        lines, titles = drawn(files / f"shard_{shard}.h5", case)
        whole_lines, whole_titles = drawn(files / "whole.h5", case)
        assert [t.replace(f"shard_{shard}.h5", "whole.h5") for t in titles] == whole_titles
        assert any(f"case {case}: completed" in t for t in titles), titles
        assert len(lines) == len(whole_lines)
        for (label, xy), (whole_label, whole_xy) in zip(lines, whole_lines):
            assert label == whole_label
            np.testing.assert_array_equal(xy, whole_xy)
    with ellroll_post.open(files / "shard_1.h5") as s, ellroll_post.open(files / "whole.h5") as w:
        assert s.cases.tolist() == [1, 4]
        for case in (1, 4):
            np.testing.assert_array_equal(s.trajectory("contact", case), w.trajectory("contact", case))
            assert s.case_input("excitation_frequency", case) == w.case_input("excitation_frequency", case)
            assert s.summary("theta_max", case) == w.summary("theta_max", case)
            assert s.status_name(case) == w.status_name(case)
        np.testing.assert_array_equal(s.trajectory("contact"), w.trajectory("contact", 1))
        for case in (0, 2, 3, 5):
            with pytest.raises(ellroll_post.NotAnEllrollFile, match=f"case {case} is not in this file"):
                s.trajectory("contact", case)


@pytest.mark.parametrize("command", SUBCOMMANDS)
def test_every_subcommand_reads_a_shard(files, tmp_path, command):
    """A shard's file is an ellroll file: each subcommand draws or prints
    from it, or says in one line why it cannot (the 2 cases of a shard of
    a suite are not a suite, for one)."""
    code, _, err = cli(*arguments(command, files / "shard_1.h5", tmp_path))
    assert code == 0 or (code == 2 and len(err.strip().splitlines()) == 1 and "shard_1.h5" in err), (code, err)
    assert "Traceback" not in err, err
    if command in PER_CASE + ["summary", "sweep", "workprecision"]:
        assert code == 0, err


# ------------------------------------------------------------ damaged files
def table_bytes(path):
    """The offsets of the bytes of a file outside its datasets' data: its
    superblock, object headers, B-trees, heaps (HDF5's tables)."""
    data = np.zeros(path.stat().st_size, bool)

    def visit(_, item):
        if isinstance(item, h5py.Dataset):
            if item.chunks:
                for i in range(item.id.get_num_chunks()):
                    info = item.id.get_chunk_info(i)
                    data[info.byte_offset:info.byte_offset + info.size] = True
            elif item.id.get_offset() is not None:
                data[item.id.get_offset():item.id.get_offset() + item.id.get_storage_size()] = True
    with h5py.File(path, "r") as f:
        f.visititems(visit)
    return np.flatnonzero(~data)


def flipped(source, target, rng, places):
    """source with one seeded bit flipped among `places` written to target."""
    data = bytearray(source.read_bytes())
    at = int(places[rng.randrange(places.size)])
    data[at] ^= 1 << rng.randrange(8)
    target.write_bytes(data)
    return at


@pytest.mark.parametrize("command", ["summary", "report", "suite", "transmissibility"])
def test_a_parent_that_ignores_sigchld_changes_nothing(files, tmp_path, command):
    """With SIGCHLD ignored (inherited from a daemon or a shell that set it:
    the system then reaps children itself), ellroll-plot reads a case's and
    a suite's file, draws, or refuses, as it does otherwise: the reader's child that times HDF5's
    reads is gone when it is waited for, which is no error."""
    source = files / ("suite.h5" if command in ("suite", "fragility") else "whole.h5")
    expected = cli(*arguments(command, source, tmp_path / "usual"))
    before = signal.signal(signal.SIGCHLD, signal.SIG_IGN)
    try:
        got = cli(*arguments(command, source, tmp_path / "ignored"))
    finally:
        signal.signal(signal.SIGCHLD, before)
    assert expected[0] == 0 or command == "transmissibility", expected   # (a sweep too short for it)
    assert (got[0], got[1].replace("ignored", "usual"), got[2]) == expected


@pytest.mark.parametrize("source", ["whole", "suite"])
def test_a_flipped_bit_in_the_tables_is_one_line(files, tmp_path, source):
    """12 seeded flips of one bit in a file's HDF5 tables, a subcommand on
    each in turn (every one on each with ELLROLL_TEST_FULL): exit 0 (the
    flip hit nothing read) or 2 with one line naming the file; never a
    traceback. The reader opens each file or raises NotAnEllrollFile, and
    what it opens reads whole."""
    rng = random.Random(8088 + len(source))
    places = table_bytes(files / f"{source}.h5")
    refused = 0
    for flip in range(12):
        damaged = tmp_path / f"d{flip}.h5"
        at = flipped(files / f"{source}.h5", damaged, rng, places)
        for command in in_turn(SUBCOMMANDS, flip):
            code, _, err = cli(*arguments(command, damaged, tmp_path / "out"))
            assert "Traceback" not in err, (at, command, err)
            assert code in (0, 2) and (code == 0 or len(err.strip().splitlines()) == 1), (at, command, code, err)
            assert code == 0 or f"d{flip}.h5" in err, (at, command, err)
        try:
            with ellroll_post.open(damaged) as f:
                f.summary_names, f.fields, f.swept_inputs(), f.status_names(), f.trajectory("contact", f.cases[-1])
        except ellroll_post.NotAnEllrollFile as exc:
            refused += 1
            assert str(exc).startswith(str(damaged)) and "\n" not in str(exc), exc
    assert refused >= 5                     # most flips in the tables damage what is read


def heap_damages(data):
    """(offset, new bytes) per global heap collection (HDF5's store of the
    variable-length texts, signature GCOL, version 1): its last object's size
    two bytes larger, where its data then takes 8 more bytes, so that the next
    header falls inside the free space's (the damage of a flipped bit on
    which HDF5 1.10 loops for ever)."""
    damages, at = [], -1
    while (at := data.find(b"GCOL", at + 1)) >= 0:
        if data[at + 4] != 1:
            continue
        end = at + int.from_bytes(data[at + 8:at + 16], "little")
        place, last = at + 16, None
        while place + 16 <= end and int.from_bytes(data[place:place + 2], "little") != 0:
            size = int.from_bytes(data[place + 8:place + 16], "little")
            last = (place, size)
            place += 16 + (size + 7) // 8 * 8
        if last is not None and last[1] % 8 in (0, 7):
            damages.append((last[0] + 8, (last[1] + 2).to_bytes(8, "little")))
    return damages


def test_a_damaged_text_store_never_hangs_a_reader(ellroll, files, tmp_path):
    """A damaged global heap on which HDF5 loops for ever inside one call
    (the paper's file, a shaken sweep's, a suite's): `ellroll summary`
    (every format, --suite), ellroll_post.open and so every ellroll-plot
    command refuse the file after a bounded time, in one line (exit 2), or
    read it; never hang. (The readers of every file wait side by side.)"""
    assert run(ellroll, "run", ROOT / "input" / "legeza1990.nml", "-q", "-o", "paper.h5", cwd=tmp_path).returncode == 0
    readers = []
    for source in ("paper", "whole", "suite"):
        original = (tmp_path / "paper.h5" if source == "paper" else files / f"{source}.h5").read_bytes()
        damages = heap_damages(original)
        assert damages, source
        readers += damaged_text_readers(ellroll, tmp_path, source, original, damages)
    for at, command, reader in readers:
        _, err = reader.communicate(timeout=60)
        label = (at, command[1:], err[-500:])
        assert reader.returncode in (0, 2) and "Traceback" not in err, label
        assert reader.returncode == 0 or len(err.strip().splitlines()) == 1, label


def damaged_text_readers(ellroll, tmp_path, source, original, damages):
    """Each damage of `original` written to its own file, and every reader
    of it started: [(offset, command, process)]."""
    readers = []
    for k, (at, data) in enumerate(damages):
        damaged = tmp_path / f"{source}_heap{k}.h5"
        damaged.write_bytes(original[:at] + data + original[at + 8:])
        commands = [[sys.executable, "-m", "ellroll_post.cli", "summary", damaged]]
        commands += [[ellroll, "summary", damaged, *options] for options in ([], ["--format", "csv"], ["--suite"])]
        readers += [(at, command, subprocess.Popen(command, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
                                                   cwd=tmp_path)) for command in commands]
    return readers


# ------------------------------------------------------- a killed run's file
@pytest.fixture(scope="module")
def killed(ellroll, tmp_path_factory):
    """A run of 40 cases killed -9 after its second case: its work file
    OUT.h5.partial (marked open for write), journal and lock are left."""
    folder = tmp_path_factory.mktemp("killed")
    name = write(folder, "k", "&sweep name = 'omega_z', start = 5, stop = 50, count = 40 /\n", t_end=3.0,
                 estimate=False)
    assert kill_after_records([str(ellroll), "run", name, "-q", "--threads", "1"], folder, folder / "k.h5.journal",
                              2, record_bytes())
    assert (folder / "k.h5.partial").exists() and not (folder / "k.h5").exists()
    return folder


@pytest.mark.parametrize("command", SUBCOMMANDS)
def test_a_killed_runs_work_file_says_resume(killed, tmp_path, command):
    """Each subcommand on a killed run's OUT.h5.partial: one line saying it
    is an unfinished run's work file and the command that finishes it (the
    one its lock names, with --resume); not HDF5's advice to h5clear it."""
    code, _, err = cli(*arguments(command, killed / "k.h5.partial", tmp_path))
    one_line_error(code, err, "k.h5.partial", "unfinished run's work file",
                   "'ellroll run k.nml -q --threads 1 --resume'", "then read", "k.h5")
    assert "may use <h5clear" not in err


def test_ellroll_summary_of_a_killed_runs_work_file_says_resume(ellroll, killed):
    """`ellroll summary` on the killed run's OUT.h5.partial names the command
    its lock holds, with --resume, as ellroll-plot does (the same words);
    not HDF5's advice to h5clear it."""
    result = subprocess.run([str(ellroll), "summary", "k.h5.partial"], cwd=killed, capture_output=True, text=True)
    assert result.returncode == 3, result.stderr
    assert "k.h5.partial: an unfinished run's work file" in result.stderr and "h5clear file" not in result.stderr
    advice = "finish it with 'ellroll run k.nml -q --threads 1 --resume' (the command k.h5.lock names, from its folder)"
    assert f"{advice}, then read k.h5; do not h5clear it" in result.stderr, result.stderr
    _, _, err = cli("summary", killed / "k.h5.partial")
    assert "finish it with 'ellroll run k.nml -q --threads 1 --resume' (the command " in err, err


def test_the_output_of_a_killed_run_is_said_to_be_unfinished_not_missing(ellroll, killed):
    """`ellroll summary OUT.h5` and a merge naming it, where only the killed
    run's OUT.h5.partial is: not 'no such file', but its work file and the
    command that finishes it."""
    for command in (["summary", "k.h5"], ["merge", "m.h5", "k.h5"]):
        result = subprocess.run([str(ellroll), *command], cwd=killed, capture_output=True, text=True)
        assert result.returncode == 2, result.stderr
        assert ("k.h5: not there: k.h5.partial is its unfinished run's work file; finish it with 'ellroll run k.nml "
                "-q --threads 1 --resume' (the command k.h5.lock names, from its folder), then read k.h5") \
            in result.stderr, result.stderr
    assert not (killed / "m.h5").exists()
    with pytest.raises(ellroll_post.NotAnEllrollFile, match=r"k\.h5: not there: \S*k\.h5\.partial is its unfinished "
                       r"run's work file; finish it with 'ellroll run k\.nml -q --threads 1 --resume'"):
        ellroll_post.open(killed / "k.h5")


def test_the_output_of_a_running_run_names_the_process_that_writes_it(ellroll, tmp_path):
    """`ellroll summary OUT.h5` while a run still writes OUT.h5.partial: the
    process its lock names, and to read it when that run ends."""
    name = write(tmp_path, "live", "&sweep name = 'omega_z', start = 5, stop = 50, count = 400 /\n", t_end=30.0,
                 estimate=False)
    process = subprocess.Popen([str(ellroll), "run", name, "-q", "--threads", "1"], cwd=tmp_path,
                               stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    try:
        deadline = time.monotonic() + 20
        # (the lock first, then the work file, once the input is checked)
        while not (tmp_path / "live.h5.partial").exists() or "pid" not in (tmp_path / "live.h5.lock").read_text():
            assert time.monotonic() < deadline and process.poll() is None
            time.sleep(0.02)
        result = subprocess.run([str(ellroll), "summary", "live.h5"], cwd=tmp_path, capture_output=True, text=True)
        assert result.returncode == 2, result.stderr
        assert "live.h5: not there yet: a running ellroll writes it (" in result.stderr and \
            f"pid {process.pid}" in result.stderr and "read it when that run ends" in result.stderr, result.stderr
        with pytest.raises(ellroll_post.NotAnEllrollFile, match=f"live\\.h5: not there yet: a running ellroll "
                           f"writes it \\(.*pid {process.pid}"):
            ellroll_post.open(tmp_path / "live.h5")
    finally:
        process.send_signal(signal.SIGTERM)
        process.wait(timeout=30)


def test_ellroll_summary_of_a_killed_run_without_its_lock_names_the_generic_command(ellroll, killed, tmp_path):
    """Without a lock of ellroll's beside it (none, or a FIFO there, not
    read): the generic command, at once."""
    shutil.copy(killed / "k.h5.partial", tmp_path / "k.h5.partial")
    for lock in ("none", "fifo"):
        if lock == "fifo":
            os.mkfifo(tmp_path / "k.h5.lock")
        result = subprocess.run([str(ellroll), "summary", "k.h5.partial"], cwd=tmp_path, capture_output=True,
                                text=True, timeout=20)
        assert result.returncode == 3, result.stderr
        assert "finish it with 'ellroll run INPUT -o k.h5 --resume' (the run's input and options)" in result.stderr
    os.remove(tmp_path / "k.h5.lock")       # a lock naming a run with --overwrite, which a resume refuses
    (tmp_path / "k.h5.lock").write_text("ellroll lock\nnode7 pid 4242: ellroll run k.nml --overwrite -q\n")
    result = subprocess.run([str(ellroll), "summary", "k.h5.partial"], cwd=tmp_path, capture_output=True, text=True)
    assert "finish it with 'ellroll run k.nml -q --resume' (the command k.h5.lock names" in result.stderr, result.stderr


def test_the_reader_says_resume_and_so_does_it_after_h5clear(killed, tmp_path):
    """The reader raises NotAnEllrollFile naming the work file and
    --resume; with its consistency flags cleared (what h5clear -s does:
    the superblock's byte 11) the file opens where it can, and every
    subcommand draws or refuses it in one line."""
    with pytest.raises(ellroll_post.NotAnEllrollFile, match="unfinished run's work file.*--resume"):
        ellroll_post.open(killed / "k.h5.partial")
    cleared = tmp_path / "c.h5.partial"
    data = bytearray((killed / "k.h5.partial").read_bytes())
    assert data[:8] == b"\x89HDF\r\n\x1a\n" and data[8] >= 2 and data[11] != 0   # superblock v2+: flags at 11
    data[11] = 0
    cleared.write_bytes(data)
    for command in SUBCOMMANDS:
        code, _, err = cli(*arguments(command, cleared, tmp_path / "out"))
        assert "Traceback" not in err and code in (0, 2), (command, err)
        assert code == 0 or (len(err.strip().splitlines()) == 1 and "c.h5.partial" in err), (command, err)


# ------------------------------------------------------------ bad options
def bad_values(rng, count, huge=True):
    """Seeded values no numeric option takes: negatives, non-integers,
    texts, and (huge) integers past any case index or bootstrap count."""
    makers = [lambda: str(-rng.randint(1, 10**rng.randint(1, 30))), lambda: f"{rng.uniform(-5, 5):.3f}",
              lambda: rng.choice(["nan", "inf", "-inf", "", "abc", "1e3", "0x10", "2.0", "1/2", "--"])]
    if huge:
        makers.append(lambda: str(rng.randint(100_001, 10**rng.randint(6, 60))))
    return [rng.choice(makers)() for _ in range(count)]


NUMERIC = {command: ["--case"] for command in PER_CASE} | {"fragility": ["--bootstrap", "--seed"]}


@pytest.mark.parametrize("command, option", [(c, o) for c, options in NUMERIC.items() for o in options])
def test_bad_numeric_options_are_one_line(files, tmp_path, command, option):
    """Seeded bad values of each numeric option: exit 2 and one line naming
    the option (a bad text or bound) or the file (a case it does not hold),
    nothing written."""
    path = files / ("suite.h5" if command == "fragility" else "whole.h5")
    rng = random.Random(f"{command}{option}")
    for value in bad_values(rng, 10, huge=option != "--seed"):     # (a seed may be any size)
        for fmt in (["--format", "table"], []) if command == "fragility" else ([],):
            code, out, err = cli(*arguments(command, path, tmp_path), *fmt, f"{option}={value}")
            one_line_error(code, err)
            assert option in err or (option == "--case" and "whole.h5: case" in err), (value, err)
            assert not out
    assert not list(tmp_path.glob("*.png"))


def test_an_unknown_limit_state_is_refused_in_every_format(files, tmp_path):
    """--limit-state names a limit state of the file, for the figure and
    the printed fits alike; a known one prints only its rows."""
    path = files / "suite.h5"
    for fmt in ("png", "table", "csv", "json"):
        code, out, err = cli("fragility", path, "--out", tmp_path, "--bootstrap", 0, "--format", fmt,
                             "--limit-state", "no_such_state")
        one_line_error(code, err, "suite.h5", "no limit state no_such_state", "known: drift, model_limit")
        assert not out
    code, out, err = cli("fragility", path, "--bootstrap", 0, "--format", "csv", "--limit-state", "model_limit")
    assert code == 0, err
    chosen = list(csv.DictReader(io.StringIO(out)))
    assert chosen and {row["limit_state"] for row in chosen} == {"model_limit"}, out
    code, out, err = cli("fragility", path, "--bootstrap", 0, "--format", "csv")
    every = list(csv.DictReader(io.StringIO(out)))
    assert code == 0 and {row["limit_state"] for row in every} == {"drift", "model_limit"}, out
    assert [row for row in every if row["limit_state"] == "model_limit"] == chosen


# ------------------------------------------------------------------- FIFOs
@contextlib.contextmanager
def unblocked_after(fifo, seconds=5.0):
    """A watchdog: where something still waits in an open of `fifo` after
    `seconds`, open its other end (so that the wait ends) and say so in the
    list yielded. (A process of its own: a wait inside h5py holds the GIL.)"""
    mark = pathlib.Path(f"{fifo}.hung")
    script = f'sleep {seconds}; : > "$2"; while :; do exec 3<>"$1"; sleep 0.05; exec 3>&-; done'
    watcher = subprocess.Popen(["sh", "-c", script, "sh", str(fifo), str(mark)])
    hung = []
    try:
        yield hung
    finally:
        watcher.kill()
        watcher.wait()
        if mark.exists():
            hung.append(str(fifo))
            mark.unlink()


@pytest.mark.parametrize("name", ["ff.h5", "ff.h5.partial", "ff.h5.journal", "ff.csv"])
def test_a_fifo_given_as_a_file_is_refused_at_once(files, tmp_path, name):
    """A FIFO named as the file, every subcommand (and the reader): one
    line naming it as a FIFO, exit 2, never waiting for a writer."""
    fifo = tmp_path / name
    os.mkfifo(fifo)
    for command in SUBCOMMANDS:
        with unblocked_after(fifo) as hung:
            code, _, err = cli(*arguments(command, fifo, tmp_path / "out"))
        assert not hung, (command, err)
        one_line_error(code, err, f"{name}: a FIFO (named pipe)")
    with unblocked_after(fifo) as hung:
        with pytest.raises(ellroll_post.NotAnEllrollFile, match=r"ff\.\S*: a FIFO \(named pipe\), not a regular"):
            ellroll_post.open(fifo)
    assert not hung


def test_a_fifo_at_a_killed_runs_lock_is_not_read(killed, tmp_path):
    """A killed run's work file whose OUT.h5.lock is a FIFO: the reader names
    the work file with the generic command that finishes it, at once."""
    shutil.copy(killed / "k.h5.partial", tmp_path / "k.h5.partial")
    os.mkfifo(tmp_path / "k.h5.lock")
    with unblocked_after(tmp_path / "k.h5.lock") as hung:
        with pytest.raises(ellroll_post.NotAnEllrollFile, match="unfinished run's work file.*'ellroll run INPUT"):
            ellroll_post.open(tmp_path / "k.h5.partial")
    assert not hung


# ------------------------------------------------- a file changed by h5py
def tampered(source, target, rng):
    """source with one seeded dataset of /case, /summary or /trajectory
    remade by h5py at a wrong length (or a trajectory at a wrong sample
    count), or a status attribute deleted: what was changed."""
    shutil.copy(source, target)
    with h5py.File(target, "r+") as f:
        rows = f["summary/status"].shape[0]
        if rng.random() < 0.15:
            name = rng.choice(["flag_values", "flag_meanings"])
            del f["summary/status"].attrs[name]
            return name
        names = [f"{g}/{n}" for g in ("case", "summary", "trajectory") for n, v in f[g].items()
                 if isinstance(v, h5py.Dataset) and v.ndim >= 1 and v.dtype.kind in "fi"]
        name = rng.choice(names)
        shape = list(f[name].shape)
        if name.startswith("trajectory/") and len(shape) >= 2 and rng.random() < 0.5:
            shape[1] = max(1, shape[1] + rng.choice([-3, -1, 1, 5]))
        else:
            shape[0] = max(0, rows + rng.choice([-rows, -2, -1, 1, 3]))
        dtype = f[name].dtype
        del f[name]
        f.create_dataset(name, data=np.zeros(shape, dtype=dtype))
    return name


def test_a_file_changed_by_another_program_is_one_line(files, tmp_path):
    """12 seeded files, each with one dataset remade at a wrong length (rows
    or samples) or a status attribute removed by h5py: the reader refuses
    each at open with one line naming the file and what is wrong, and so do
    summary_frame and a subcommand in turn (every one with
    ELLROLL_TEST_FULL; exit 2); never a traceback."""
    rng = random.Random(1214)
    for trial in range(12):
        source = files / rng.choice(["whole.h5", "suite.h5"])
        target = tmp_path / f"t{trial}.h5"
        what = tampered(source, target, rng)
        with pytest.raises(ellroll_post.NotAnEllrollFile) as raised:
            ellroll_post.open(target)
        message = str(raised.value)
        assert message.startswith(f"{target}: ") and "\n" not in message and what.split("/")[-1] in message, \
            (what, message)
        with pytest.raises(ellroll_post.NotAnEllrollFile):
            ellroll_post.summary_frame(target)
        for command in in_turn(SUBCOMMANDS, trial):
            code, _, err = cli(*arguments(command, target, tmp_path / "out"))
            one_line_error(code, err, f"t{trial}.h5")


def test_a_killed_merge_s_work_file_says_run_it_again(ellroll, killed, tmp_path):
    """A merge killed before it closed its file leaves OUT.h5.partial and a
    lock naming the merge: both readers say to run that merge again, as it
    stands (merge takes no --resume; `run --resume` would run the campaign
    anew)."""
    shutil.copy(killed / "k.h5.partial", tmp_path / "m.h5.partial")
    (tmp_path / "m.h5.lock").write_text("ellroll lock\nnode7 pid 4242: ellroll merge m.h5 s0.h5 s1.h5\n")
    code, _, err = cli("summary", tmp_path / "m.h5.partial")
    one_line_error(code, err, "m.h5.partial", "unfinished run's work file",
                   "finish it by running 'ellroll merge m.h5 s0.h5 s1.h5' again", "then read", "m.h5")
    assert "--resume" not in err
    result = subprocess.run([str(ellroll), "summary", "m.h5.partial"], cwd=tmp_path, capture_output=True, text=True)
    assert result.returncode == 3, result.stderr
    assert ("finish it by running 'ellroll merge m.h5 s0.h5 s1.h5' again (the command m.h5.lock names, from its "
            "folder), then read m.h5") in result.stderr and "--resume" not in result.stderr, result.stderr
