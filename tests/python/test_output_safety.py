"""No command replaces a file it did not make, follows a link, or destroys
another process's work.

Contract: every writing command (ellroll run, run --overwrite, run --resume,
merge, merge --overwrite, and every ellroll-plot command) against a
symbolic link, a foreign file, a folder or the input at each name it would
write: refused with a message, the file left as it was, no file left behind.
One writer: two starts on one output at seeded random offsets (plain/plain,
plain/resume, overwrite/plain) in a loop: one does the work, the other is
refused at once naming the first's process, and the output is the
undisturbed run's. Input files are fingerprinted: a record changed before a
resume, or shards run with different records, are refused naming the file.
The end of a run: a kill between moving the output into place and removing
its journal leaves a complete output that a resume recognises."""
import os
import pathlib
import random
import re
import shutil
import signal
import socket
import subprocess
import sys
import time

import h5py
import numpy as np
import pytest

import ellroll_post

from conftest import FULL, PAPER_INPUT, ROOT, in_turn, plot_in_process, run
from test_campaign import JOURNAL_HEADER, assert_same_datasets, record_bytes


CAMPAIGN = """&geometry a = 1.0, b = 0.4, c = 0.2 /
&ball radius = 0.2, weight = 2620.0 /
&initial x = 0.0, y = 0.0, omega = -2.0, 2.0, 20.0 /
&integration method = 'rk4', dt = 1.0e-3, t_end = {t_end} /
&output file = 'out.h5', interval = 0.05 /
&sweep name = 'omega_z', values = 5, 10, 20, 40 /
"""
VICTIM = b"somebody's data\n"
LONG = 400.0             # t_end of a run that lasts about a second (4 cases, one thread)
WORK_NAMES = ["out.h5", "out.h5.partial", "out.h5.partial.new", "out.h5.journal", "out.h5.lock"]


def folder_with(tmp_path, name="w", t_end=0.2):
    folder = tmp_path / name
    folder.mkdir()
    (folder / "camp.nml").write_text(CAMPAIGN.format(t_end=t_end))
    return folder


def contents(folder):
    return {p.name: (p.readlink() if p.is_symlink() else p.read_bytes() if p.is_file() else "folder")
            for p in sorted(folder.iterdir())}


def hostile(folder, name, kind):
    """Put a link to a victim, a foreign file or a folder at name."""
    target = folder / name
    if kind == "link":
        (folder / "victim.txt").write_bytes(VICTIM)
        target.symlink_to("victim.txt")
    elif kind == "foreign":
        target.write_bytes(VICTIM)
    elif kind == "foreign_hdf5":         # another program's HDF5 file: not a work file for its signature
        with h5py.File(target, "w", libver=("earliest", "v110")) as f:
            f["precious"] = np.arange(5.0)
    else:
        target.mkdir()


@pytest.mark.parametrize("kind", ["link", "foreign", "foreign_hdf5", "folder"])
@pytest.mark.parametrize("name", WORK_NAMES)
@pytest.mark.parametrize("options", [[], ["--overwrite"], ["--resume"]], ids=["plain", "overwrite", "resume"])
def test_run_never_writes_a_file_it_did_not_make(ellroll, tmp_path, kind, name, options):
    folder = folder_with(tmp_path)
    hostile(folder, name, kind)
    before = contents(folder)
    result = run(ellroll, "run", "camp.nml", "-q", *options, cwd=folder)
    detail = f"{kind} at {name}, {options}: {result.stderr}"
    if name == "out.h5" and kind != "link" and "--overwrite" not in options and "--resume" not in options:
        assert result.returncode == 3 and "out.h5" in result.stderr, detail
    else:
        assert result.returncode == 3, detail
        assert re.search(rf"{re.escape(name)}: (is a symbolic link|exists and is not an ellroll|is a folder|"
                         r"output file exists)", result.stderr), detail
    assert contents(folder) == before, detail


@pytest.mark.parametrize("output", ["camp.nml", "out.h5.partial"])
def test_the_input_is_never_an_output_nor_a_work_file(ellroll, tmp_path, output):
    folder = folder_with(tmp_path)
    if output != "camp.nml":
        shutil.copy(folder / "camp.nml", folder / output)
        command = ["run", output, "-o", "out.h5", "--overwrite"]
    else:
        command = ["run", "camp.nml", "-o", output, "--overwrite"]
    before = contents(folder)
    result = run(ellroll, *command, cwd=folder)
    assert result.returncode == 3 and "is the input file; it is never written" in result.stderr, result.stderr
    assert contents(folder) == before


@pytest.mark.parametrize("kind", ["link", "foreign", "shard", "folder"])
@pytest.mark.parametrize("overwrite", [False, True])
def test_merge_never_replaces_a_file_it_did_not_make(ellroll, tmp_path, kind, overwrite):
    folder = folder_with(tmp_path)
    for shard in ("0", "1"):
        assert run(ellroll, "run", "camp.nml", "-q", "--shard", f"{shard}/2", "-o", f"s{shard}.h5",
                   cwd=folder).returncode == 0
    target = "s0.h5" if kind == "shard" else "merged.csv"
    if kind != "shard":
        hostile(folder, target, kind)
    if kind == "foreign":                      # and another program's HDF5 file at its work file's name
        hostile(folder, target + ".partial", "foreign_hdf5")
    before = contents(folder)
    result = run(ellroll, "merge", target, "s0.h5", "s1.h5", *(["--overwrite"] if overwrite else []), cwd=folder)
    assert result.returncode in (2, 3) and f"{target}: " in result.stderr, result.stderr
    assert contents(folder) == before


def test_merge_replaces_its_own_output_only_with_overwrite(ellroll, tmp_path):
    folder = folder_with(tmp_path)
    assert run(ellroll, "run", "camp.nml", "-q", "-o", "whole.h5", cwd=folder).returncode == 0
    for shard in ("0", "1"):
        assert run(ellroll, "run", "camp.nml", "-q", "--shard", f"{shard}/2", "-o", f"s{shard}.h5",
                   cwd=folder).returncode == 0
    assert run(ellroll, "merge", "out.h5", "s0.h5", "s1.h5", cwd=folder).returncode == 0
    again = run(ellroll, "merge", "out.h5", "s0.h5", "s1.h5", cwd=folder)
    assert again.returncode == 3 and "out.h5: output file exists; pass --overwrite" in again.stderr
    assert run(ellroll, "merge", "out.h5", "s0.h5", "s1.h5", "--overwrite", cwd=folder).returncode == 0
    assert_same_datasets(folder / "whole.h5", folder / "out.h5")
    assert sorted(p.name for p in folder.iterdir()) == ["camp.nml", "out.h5", "s0.h5", "s1.h5", "whole.h5"]


PLOT_COMMANDS = [["trace"], ["nutation"], ["reaction"], ["energy"], ["sweep"], ["report"]]


@pytest.fixture(scope="module")
def plotted(ellroll, tmp_path_factory):
    """A campaign's file, for ellroll-plot (run in this process: main(argv))."""
    folder = folder_with(tmp_path_factory.mktemp("plots"))
    assert run(ellroll, "run", "camp.nml", "-q", cwd=folder).returncode == 0
    return folder


def plot(folder, *argv):
    result = plot_in_process(*argv, cwd=folder)
    return result.returncode, result.stdout, result.stderr


@pytest.mark.parametrize("command", PLOT_COMMANDS, ids=[c[0] for c in PLOT_COMMANDS])
def test_ellroll_plot_never_writes_a_file_it_did_not_make(plotted, command):
    """A figure or report drawn, refused without --overwrite, drawn again
    with it; then a link, a foreign file or a folder put at its name (one in
    turn, each command; all three with ELLROLL_TEST_FULL) is refused in one
    line, and nothing in the folder changes."""
    figures = f"figures_{command[0]}"
    code, out, err = plot(plotted, *command, "out.h5", "--out", figures)
    assert code == 0, err
    written = [os.path.basename(line) for line in out.splitlines() if line]
    code, _, err = plot(plotted, *command, "out.h5", "--out", figures)
    assert code == 2 and "exists; give --overwrite" in err, err
    code, _, err = plot(plotted, *command, "out.h5", "--out", figures, "--overwrite")
    assert code == 0, err
    folder = plotted / figures
    for kind in in_turn(("link", "foreign", "folder"), PLOT_COMMANDS.index(command)):
        (folder / written[0]).unlink() if not (folder / written[0]).is_dir() else (folder / written[0]).rmdir()
        (folder / "victim.txt").unlink(missing_ok=True)
        hostile(folder, written[0], kind)
        before = contents(folder)
        code, _, err = plot(plotted, *command, "out.h5", "--out", figures, "--overwrite")
        assert code == 2 and written[0] in err, (kind, err)
        assert re.search(r"(symbolic link|not made by ellroll-plot|not a regular file)", err), (kind, err)
        assert contents(folder) == before, f"{kind}: a file was replaced or left behind"


@pytest.mark.parametrize("given", [False, True], ids=["default_folder", "out_option"])
@pytest.mark.parametrize("target", ["folder", "dangling"])
def test_a_report_is_never_written_through_a_link_at_its_folder(plotted, tmp_path, target, given):
    """The report's folder (FILE_report, or --out) is the report itself: a
    symbolic link there would put it among another folder's files."""
    elsewhere = tmp_path / "someone_elses"
    if target == "folder":
        elsewhere.mkdir()
        (elsewhere / "notes.txt").write_text("precious\n")
    name = "given_report" if given else "out_report"
    link = plotted / name
    link.unlink(missing_ok=True)
    link.symlink_to(elsewhere)
    try:
        code, _, err = plot(plotted, "report", "out.h5", *(["--out", name] if given else []))
    finally:
        link.unlink()
    lines = err.strip().splitlines()
    assert code == 2 and len(lines) == 1, err
    assert f"{name} is a symbolic link; ellroll-plot never writes a report through one" in lines[0], err
    assert ("--out" in lines[0]) == given, err
    if target == "folder":
        assert sorted(p.name for p in elsewhere.iterdir()) == ["notes.txt"]


@pytest.mark.parametrize("command", [["trace"], ["report"]], ids=["figure", "report"])
def test_a_folder_ellroll_plot_cannot_write_in_is_named_not_its_temporary_file(plotted, monkeypatch, command):
    """A folder the system refuses to write in (read-only, immutable): one
    line naming the file asked for and the folder, exit 2; never the
    name of a temporary file of its own."""
    import tempfile

    def refused(*args, **kwargs):
        raise PermissionError(1, "Operation not permitted", str(kwargs.get("dir", "")) + "/.tmp_name")
    monkeypatch.setattr(tempfile, "mkstemp", refused)
    monkeypatch.setattr(tempfile, "mkdtemp", refused)
    code, _, err = plot(plotted, *command, "out.h5", "--out", "refused_here")
    lines = err.strip().splitlines()
    assert code == 2 and len(lines) == 1, err
    assert "refused_here" in lines[0] and "(Operation not permitted)" in lines[0] and ".tmp_name" not in lines[0], err


def test_a_report_over_an_old_one_that_fails_leaves_the_old_one(ellroll, tmp_path):
    """`ellroll-plot report --overwrite` over an existing report, EIO at
    each rename it makes (its figures into the staging folder, the old
    files kept aside, the new ones moved in): exit 2 and the old report
    byte for byte, nothing hidden left, the message naming the report's own
    folder (the first old file kept aside, the last new file moved in, and,
    with ELLROLL_TEST_FULL, a seeded one of the renames)."""
    if shutil.which("strace") is None:
        pytest.skip("strace is not installed")
    folder = folder_with(tmp_path)
    assert run(ellroll, "run", "camp.nml", "-q", cwd=folder).returncode == 0
    assert plot(folder, "report", "out.h5")[0] == 0
    old = {p.name: p.read_bytes() for p in (folder / "out_report").iterdir()}
    (folder / "camp.nml").write_text(CAMPAIGN.format(t_end=0.3))
    assert run(ellroll, "run", "camp.nml", "-q", "--overwrite", cwd=folder).returncode == 0
    command = [sys.executable, "-m", "ellroll_post.cli", "report", "out.h5", "--overwrite"]
    renames = ["-e", "trace=rename,renameat,renameat2"]
    trace = tmp_path / "renames.txt"
    shutil.copytree(folder, tmp_path / "counting")
    assert subprocess.run(["strace", "-f", "--seccomp-bpf", "-qq", "-o", str(trace), *renames, *command], cwd=tmp_path / "counting",
                          capture_output=True, timeout=300).returncode == 0
    # (strace counts when= in each process: the one that renames most)
    pids = [line.split()[0] for line in trace.read_text().splitlines() if re.search(r"\brename(at2?)?\(", line)]
    count = max(pids.count(pid) for pid in set(pids))
    assert count >= 2 * len(old)           # (each figure into staging; each old file kept aside, each new moved in)
    rng = random.Random(20261127)
    for n in sorted({count - 2 * len(old) + 1, count, *([rng.randrange(1, count + 1)] if FULL else [])}):
        result = subprocess.run(["strace", "-f", "--seccomp-bpf", "-qq", "-o", os.devnull, *renames,
                                 "-e", f"inject=rename,renameat,renameat2:error=EIO:when={n}", *command],
                                cwd=folder, capture_output=True, text=True, timeout=300)
        now = {p.name: p.read_bytes() for p in (folder / "out_report").iterdir()}
        assert not [p for p in folder.rglob(".*")], (n, result.stderr)
        assert result.returncode == 2 and now == old, (n, result.stderr)
        assert result.stderr.startswith("ellroll-plot: error: out_report") and ".out_report." not in result.stderr, \
            result.stderr
    # a disk that fails from then on (EIO at every rename from the n-th, the
    # putting back included): each old file is in the folder or, byte for
    # byte, in the kept folder that the one-line message names
    for n in sorted({count - len(old) + 1, *([rng.randrange(count - 2 * len(old) + 1, count + 1)] if FULL else [])}):
        result = subprocess.run(["strace", "-f", "--seccomp-bpf", "-qq", "-o", os.devnull, *renames,
                                 "-e", f"inject=rename,renameat,renameat2:error=EIO:when={n}+", *command],
                                cwd=folder, capture_output=True, text=True, timeout=300)
        lines = result.stderr.strip().splitlines()
        assert result.returncode == 2 and len(lines) == 1 and lines[0].startswith("ellroll-plot: error: out_report"), \
            (n, result.stderr)
        kept = [p for p in (folder / "out_report").glob(".out_report.kept.*")]
        assert len(kept) <= 1 and (not kept or str(kept[0].relative_to(folder)) in lines[0]), (n, result.stderr)
        for name, data in old.items():
            found = [p.read_bytes() for p in [folder / "out_report" / name, *(k / name for k in kept)] if p.exists()]
            assert data in found, (n, name, result.stderr)
        for p in (folder / "out_report").iterdir():         # (no new file left beside the old ones)
            assert p.is_dir() or p.read_bytes() == old[p.name], (n, p.name, result.stderr)
        for k in kept:                          # (the user puts them back)
            for p in k.iterdir():
                os.replace(p, folder / "out_report" / p.name)
            k.rmdir()


@pytest.mark.parametrize("call, when", in_turn([("unlink,unlinkat", "1"), ("rmdir", "2"), ("rmdir", "1")], 1))
def test_a_report_in_place_names_what_it_could_not_clean_up(ellroll, tmp_path, call, when):
    """`report --overwrite` whose clean-up fails (EIO at removing an old
    file kept aside, or at removing the folder it kept them in or its
    emptied work folder): the new report is in place, exit 0, and one
    warning names the hidden folder left, to remove by hand. (One of the
    three faults, in turn; all three with ELLROLL_TEST_FULL.)"""
    if shutil.which("strace") is None:
        pytest.skip("strace is not installed")
    folder = folder_with(tmp_path)
    assert run(ellroll, "run", "camp.nml", "-q", cwd=folder).returncode == 0
    assert plot(folder, "report", "out.h5", "--out", "fresh")[0] == 0
    assert plot(folder, "report", "out.h5")[0] == 0
    command = [sys.executable, "-m", "ellroll_post.cli", "report", "out.h5", "--overwrite"]
    result = subprocess.run(["strace", "-f", "--seccomp-bpf", "-qq", "-o", os.devnull, "-e", f"trace={call}",
                             "-e", f"inject={call}:error=EIO:when={when}", *command],
                            cwd=folder, capture_output=True, text=True, timeout=300)
    lines = result.stderr.strip().splitlines()
    left = [p for p in (folder / "out_report").iterdir() if p.name.startswith(".")]
    assert result.returncode == 0 and len(lines) == 1 and len(left) == 1, result.stderr
    assert lines[0].startswith("ellroll-plot: warning: the report is in place, but ") and \
        f"out_report/{left[0].name} could not be removed (Input/output error); remove it by hand" in lines[0], lines
    assert (folder / "out_report" / "index.html").read_text() == (folder / "fresh" / "index.html").read_text()


@pytest.mark.parametrize("command", [["trace", "--case", "1"], *([["report"]] if FULL else [])],
                         ids=["figure", *(["report"] if FULL else [])])
def test_a_disk_that_does_not_confirm_a_write_keeps_the_old_output(plotted, tmp_path, command):
    """fsync fails (EIO, strace) on ellroll-plot --overwrite: at the first
    one (the new file's own, before its name replaces the old one's), the
    old figure or report stays, the same file (inode) and bytes, nothing
    hidden left, exit 2 in one line naming it; at the last one (the folder
    that holds the new name), exit 2 in one line saying the new file is
    written but may not last a crash. (A report, whose files are written the
    same way, with ELLROLL_TEST_FULL.)"""
    if shutil.which("strace") is None:
        pytest.skip("strace is not installed")
    folder = tmp_path / "w"
    shutil.copytree(plotted, folder)
    full = [sys.executable, "-m", "ellroll_post.cli", *command[:1], "out.h5", *command[1:], "--overwrite"]
    assert subprocess.run(full, cwd=folder, capture_output=True, timeout=300).returncode == 0
    made = folder / ("out_report" if command[0] == "report" else "out_fig2_trace_case1.png")
    files = sorted(made.iterdir()) if made.is_dir() else [made]
    old = {p: (p.stat().st_ino, p.read_bytes()) for p in files}
    trace = tmp_path / "fsyncs.txt"
    assert subprocess.run(["strace", "-f", "--seccomp-bpf", "-qq", "-o", str(trace), "-e", "trace=fsync", *full], cwd=folder,
                          capture_output=True, timeout=300).returncode == 0
    count = trace.read_text().count("fsync(")
    assert count >= 2 * len(files)                  # (each file, and the folder it is moved into)
    old = {p: (p.stat().st_ino, p.read_bytes()) for p in files}
    for when, expected in ((1, "cannot write"), (count, "written, but the disk did not confirm")):
        result = subprocess.run(["strace", "-f", "--seccomp-bpf", "-qq", "-o", os.devnull, "-e", "trace=fsync",
                                 "-e", f"inject=fsync:error=EIO:when={when}", *full],
                                cwd=folder, capture_output=True, text=True, timeout=300)
        lines = result.stderr.strip().splitlines()
        assert result.returncode == 2 and len(lines) == 1 and expected in lines[0], (when, result.stderr)
        assert made.name in lines[0] and "Input/output error" in lines[0], (when, result.stderr)
        assert not [p for p in folder.rglob(".*")], (when, result.stderr)
        if when == 1:
            assert {p: (p.stat().st_ino, p.read_bytes()) for p in files} == old, result.stderr


def test_ellroll_plot_workprecision_leaves_nothing_when_it_fails(plotted):
    code, _, err = plot(plotted, "workprecision", "out.h5", "--out", "figures_wp")
    assert code == 2 and "no error figures" in err
    assert list((plotted / "figures_wp").iterdir()) == []


# ---- one writer per output

def start(ellroll, folder, *options):
    return subprocess.Popen([str(ellroll), "run", "camp.nml", "-q", "--threads", "1", *options], cwd=folder,
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)


@pytest.mark.parametrize("pair", [("plain", "plain"), ("plain", "resume"), ("overwrite", "plain")])
def test_two_starts_on_one_output_one_writes_the_other_is_refused(ellroll, tmp_path, pair):
    options = {"plain": [], "resume": ["--resume"], "overwrite": ["--overwrite"]}
    rng = random.Random(f"{pair}")
    reference = folder_with(tmp_path, "reference", t_end=LONG)
    assert run(ellroll, "run", "camp.nml", "-q", "-o", "whole.h5", cwd=reference).returncode == 0
    overlapped = 0
    for trial in range(3):
        folder = folder_with(tmp_path, f"trial{trial}", t_end=LONG)
        if pair[0] == "overwrite":
            shutil.copy(reference / "whole.h5", folder / "out.h5")
        first = start(ellroll, folder, *options[pair[0]])
        time.sleep(rng.uniform(0.0, 0.3))
        second = start(ellroll, folder, *options[pair[1]])
        results = [(p.wait(timeout=120), p.stderr.read(), p.pid) for p in (first, second)]
        detail = f"trial {trial}, {pair}: {results}"
        locked_out = [r for r in results if "another ellroll process writes this output" in r[1]]
        if locked_out:
            overlapped += 1
            code, message, _ = locked_out[0]
            winner = next(pid for c, _, pid in results if c == 0)
            assert code == 3 and f"pid {winner}," in message, detail
            assert sorted(c for c, _, _ in results) == [0, 3], detail
        else:       # the second began after the first had ended
            assert all(c == 0 or "output file exists" in m for c, m, _ in results), detail
        assert_same_datasets(reference / "whole.h5", folder / "out.h5")
        assert sorted(p.name for p in folder.iterdir()) == ["camp.nml", "out.h5"], detail
    assert overlapped >= 2, "the starts did not overlap: the test did not try the lock"


def test_a_resume_refused_by_the_lock_leaves_the_run_alone(ellroll, tmp_path):
    folder = folder_with(tmp_path, t_end=LONG)
    writer = start(ellroll, folder)
    while not (folder / "out.h5.journal").exists():
        time.sleep(0.01)
    note = (folder / "out.h5.lock").read_text()
    assert note.startswith("ellroll lock\nhost ") and f"pid {writer.pid}," in note, note
    for options in (["--resume"], ["--overwrite"], []):
        result = run(ellroll, "run", "camp.nml", "-q", *options, cwd=folder)
        assert result.returncode == 3 and f"pid {writer.pid}" in result.stderr, result.stderr
    merged = run(ellroll, "merge", "out.h5", "x.h5", cwd=folder)
    assert merged.returncode == 3 and "another ellroll process" in merged.stderr, merged.stderr
    assert writer.wait(timeout=120) == 0, writer.stderr.read()
    assert sorted(p.name for p in folder.iterdir()) == ["camp.nml", "out.h5"]


@pytest.mark.parametrize("target", ["it's\tout.h5", "./" * 250 + "out.h5"], ids=["quoted", "long"])
def test_the_lock_names_the_holders_whole_command_line(ellroll, tmp_path, target):
    """The refusal gives the holder's command line with its options (its
    output among them): an argument with more than plain characters in
    single quotes, a control character as '?', at most 400 characters."""
    folder = folder_with(tmp_path, t_end=LONG)
    writer = start(ellroll, folder, "-o", target)
    lock = folder / (target.replace("./", "") + ".lock")
    while not (folder / (target.replace("./", "") + ".journal")).exists():
        time.sleep(0.01)
    result = run(ellroll, "run", "camp.nml", "-q", "-o", target, cwd=folder)
    assert writer.wait(timeout=120) == 0, writer.stderr.read()
    assert result.returncode == 3, result.stderr
    if target.startswith("it"):
        command = "ellroll run camp.nml -q --threads 1 -o 'it'\\''s?out.h5'"
        assert f": {command}); nothing of its files was touched" in result.stderr, result.stderr
    else:
        command = ("ellroll run camp.nml -q --threads 1 -o " + target)[:397] + "..."
        assert f": {command}); nothing of its files was touched" in result.stderr, result.stderr
    assert not lock.exists()


def test_reading_the_partial_file_of_a_running_run_says_a_run_writes_it(ellroll, tmp_path):
    """`ellroll summary` of OUT.h5.partial or OUT.h5.journal while the run
    writes them: HDF5's own lock refuses the reader (exit 3), or the journal
    is not an output (exit 2); each message names the running process (its
    pid, from the lock) and says to read out.h5 when that run ends, as the
    Python reader does. Once the run is stopped, the journal's says how to
    finish the run."""
    folder = folder_with(tmp_path, t_end=LONG)
    writer = start(ellroll, folder)
    while not (folder / "out.h5.journal").exists():
        time.sleep(0.01)
    partial = run(ellroll, "summary", "out.h5.partial", cwd=folder)
    journal = run(ellroll, "summary", "out.h5.journal", cwd=folder)
    readers = []
    for name in ("out.h5.partial", "out.h5.journal"):
        with pytest.raises(ellroll_post.NotAnEllrollFile) as caught:
            ellroll_post.open(folder / name)
        readers.append(str(caught.value))
    writer.send_signal(signal.SIGTERM)
    writer.wait(timeout=60)
    stopped = run(ellroll, "summary", "out.h5.journal", cwd=folder)
    holder = f"pid {writer.pid}, started "
    assert partial.returncode == 3
    assert partial.stderr.startswith("ellroll: error: out.h5.partial: a running ellroll writes it (host ")
    assert holder in partial.stderr and "holding out.h5.lock); read it when that run ends" in partial.stderr
    assert journal.returncode == 2
    assert journal.stderr.startswith("ellroll: error: out.h5.journal: ellroll's journal of a running ellroll (host ")
    assert holder in journal.stderr and "not an output file; read out.h5 when that run ends" in journal.stderr
    assert readers[0].startswith(f"{folder / 'out.h5.partial'}: a running ellroll writes it (host ")
    assert readers[1].startswith(f"{folder / 'out.h5.journal'}: ellroll's journal of a running ellroll (host ")
    assert holder in readers[0] and holder in readers[1]
    assert stopped.returncode == 2
    assert ("out.h5.journal: ellroll's journal of an unfinished run (the cases it finished, for --resume), not an "
            "output file; finish it with 'ellroll run INPUT -o out.h5 --resume'") in stopped.stderr, stopped.stderr


@pytest.mark.parametrize("second", ["--overwrite", "--resume"])
def test_a_run_whose_lock_was_removed_moves_nothing_into_place(ellroll, tmp_path, second):
    """Run A's lock file removed by hand while it runs (a 'stale lock'
    cleanup), run B then takes the output (--overwrite, or --resume of A's
    journal) and finishes: A, finishing after it, refuses to commit (exit
    3), and leaves B's output and every file at the output's names as B
    left them."""
    folder = folder_with(tmp_path, t_end=LONG)
    first = start(ellroll, folder)
    while not (folder / "out.h5.journal").exists():
        time.sleep(0.01)
    first.send_signal(signal.SIGSTOP)
    (folder / "out.h5.lock").unlink()
    (folder / "b.nml").write_text(CAMPAIGN.format(t_end=0.2))
    taken = run(ellroll, "run", "b.nml", "-q", "-o", "out.h5", second, cwd=folder)
    if second == "--resume":
        # B resumes A's journal: a changed input is refused, nothing written; run A's input instead
        assert taken.returncode != 0
        taken = run(ellroll, "run", "camp.nml", "-q", "--threads", "1", "--resume", cwd=folder)
    assert taken.returncode == 0, taken.stderr
    left = {p.name: p.read_bytes() for p in folder.iterdir()}
    first.send_signal(signal.SIGCONT)
    assert first.wait(timeout=120) == 3
    message = first.stderr.read()
    assert "out.h5.lock: the output's lock was removed while this process wrote it (another run may write " \
           "out.h5 now); out.h5.partial is not moved into place, and no file at its names is touched" in message, \
        message
    assert "--resume" not in message, message
    assert {p.name: p.read_bytes() for p in folder.iterdir()} == left
    assert "out.h5" in left and "out.h5.lock" not in left and "out.h5.journal" not in left


@pytest.mark.parametrize("reader", ["ellroll", "ellroll-plot"])
def test_without_hdf5_file_locks_the_outputs_lock_tells_a_running_run(ellroll, tmp_path, reader):
    """With HDF5_USE_FILE_LOCKING=FALSE (as clusters set it for their file
    systems) HDF5 cannot tell a work file that a live run writes from a
    killed run's: the readers ask the output's own lock (OUT.h5.lock). While
    the run writes, they name it and its process; after a SIGKILL they call
    the file unfinished, with the resume."""
    folder = folder_with(tmp_path, t_end=LONG)
    writer = start(ellroll, folder)
    while not (folder / "out.h5.journal").exists():
        time.sleep(0.01)
    command = ([str(ellroll)] if reader == "ellroll" else [sys.executable, "-m", "ellroll_post.cli"]) + \
        ["summary", "out.h5.partial"]
    env = dict(os.environ, HDF5_USE_FILE_LOCKING="FALSE")
    writer.send_signal(signal.SIGSTOP)             # (alive, its lock held, while the reader starts)
    running = subprocess.run(command, cwd=folder, capture_output=True, text=True, env=env, timeout=120)
    writer.send_signal(signal.SIGKILL)
    writer.wait(timeout=60)
    killed = subprocess.run(command, cwd=folder, capture_output=True, text=True, env=env, timeout=120)
    assert running.returncode in (2, 3) and \
        f"out.h5.partial: a running ellroll writes it (host {socket.gethostname()}, pid {writer.pid}, started " \
        in running.stderr and "holding out.h5.lock); read it when that run ends" in running.stderr, running.stderr
    assert killed.returncode in (2, 3) and "out.h5.partial: an unfinished run's work file" in killed.stderr and \
        "--resume" in killed.stderr, killed.stderr


# ---- the end of a run, and signals

def test_a_complete_output_beside_its_journal_is_recognised(ellroll, tmp_path):
    """Killed after the output was moved into place, before its journal was
    removed: the next command on it (a plain run, which refuses as for any
    output, or a resume) says the output is complete and removes the stale
    journal; a resume writes nothing."""
    folder = folder_with(tmp_path)
    assert run(ellroll, "run", "camp.nml", "-q", "-o", "whole.h5", cwd=folder).returncode == 0
    killed = subprocess.run(["strace", "-f", "-o", os.devnull, "-e", "trace=unlink", "-e",
                             "inject=unlink:signal=SIGKILL:when=1", str(ellroll), "run", "camp.nml", "-q"],
                            cwd=folder, capture_output=True, text=True)
    if shutil.which("strace") is None:
        pytest.skip("strace is not installed")
    assert killed.returncode != 0
    assert (folder / "out.h5").exists() and (folder / "out.h5.journal").exists()
    shutil.copy(folder / "out.h5.journal", folder / "journal.kept")
    plain = run(ellroll, "run", "camp.nml", "-q", cwd=folder)
    assert plain.returncode == 3 and "output file exists" in plain.stderr, plain.stderr
    assert "out.h5: complete; removing the journal of the run that wrote it" in plain.stderr, plain.stderr
    (folder / "journal.kept").rename(folder / "out.h5.journal")
    resumed = run(ellroll, "run", "camp.nml", "--resume", cwd=folder)
    assert resumed.returncode == 0 and "complete; removing the journal" in resumed.stderr, resumed.stderr
    assert "nothing to do" in resumed.stderr
    assert_same_datasets(folder / "whole.h5", folder / "out.h5")
    assert sorted(p.name for p in folder.iterdir()) == ["camp.nml", "out.h5", "whole.h5"]


def test_repeated_sigterm_is_one_stop(ellroll, tmp_path):
    """scancel and a job script's trap may both send SIGTERM: the run stops
    once, with its message and its finished cases; a second SIGINT still
    ends it at once."""
    folder = folder_with(tmp_path, t_end=LONG)
    assert run(ellroll, "run", "camp.nml", "-q", "-o", "whole.h5", cwd=folder).returncode == 0
    writer = start(ellroll, folder)
    while not (folder / "out.h5.journal").exists():
        time.sleep(0.01)
    time.sleep(0.2)
    for _ in range(3):
        writer.send_signal(signal.SIGTERM)
    assert writer.wait(timeout=60) == 143
    assert "interrupted by SIGTERM" in writer.stderr.read()
    resumed = run(ellroll, "run", "camp.nml", "-q", "--resume", cwd=folder)
    assert resumed.returncode == 0, resumed.stderr
    assert_same_datasets(folder / "whole.h5", folder / "out.h5")


def test_bytes_appended_to_a_journal_rerun_nothing(ellroll, tmp_path):
    folder = folder_with(tmp_path)
    assert run(ellroll, "run", "camp.nml", "-q", "-o", "whole.h5", cwd=folder).returncode == 0
    killed = subprocess.run(["strace", "-f", "-o", os.devnull, "-e", "inject=unlink:signal=SIGKILL:when=1",
                             str(ellroll), "run", "camp.nml", "-q", "--threads", "1"], cwd=folder)
    assert killed.returncode != 0
    (folder / "out.h5").rename(folder / "out.h5.partial")        # every case journaled, none moved into place
    journal = folder / "out.h5.journal"
    with open(journal, "ab") as f:
        f.write(random.Random(7).randbytes(2 * record_bytes()))
    resumed = run(ellroll, "run", "camp.nml", "--resume", cwd=folder)
    assert resumed.returncode == 0, resumed.stderr
    assert "2 damaged records skipped" in resumed.stderr and "0 of 4 cases have no valid record" in resumed.stderr, \
        resumed.stderr
    assert_same_datasets(folder / "whole.h5", folder / "out.h5")


# ---- input files

RECORD_SUITE = """&geometry a = 1.0, b = 0.4, c = 0.2 /
&ball radius = 0.2, weight = 2620.0 /
&initial x = 0.05, y = 0.0, omega = 0.0, 0.0, 0.0 /
&integration method = 'rk4', dt = 1.0e-3, t_end = 1.0 /
&excitation kind = 'record' /
&record name = 'SYN1', record_file = 'records/SYN1_H1.AT2', 'records/SYN1_H2.AT2' /
&record name = 'SYN3', record_file = 'records/SYN3_H1.AT2', 'records/SYN3_H2.AT2' /
&sweep name = 'rolling_resistance', values = 0.0, 1.0e-4, 1.0e-3, 2.0e-3 /
&output file = 'out.h5', interval = 0.05 /
"""


def record_folder(tmp_path):
    folder = tmp_path / "records_run"
    shutil.copytree(ROOT / "input" / "records", folder / "records")
    (folder / "suite.nml").write_text(RECORD_SUITE)
    return folder


def change_a_value(path):
    lines = path.read_text().splitlines(keepends=True)
    lines[5] = lines[5].replace("E", "E", 1)[:-2] + ("1" if lines[5][-2] != "1" else "2") + lines[5][-1]
    path.write_text("".join(lines))


def test_a_record_changed_before_a_resume_is_refused_naming_it(ellroll, tmp_path):
    folder = record_folder(tmp_path)
    killed = subprocess.run(["strace", "-f", "-o", os.devnull, "-e", "inject=pwritev:signal=SIGKILL:when=6",
                             str(ellroll), "run", "suite.nml", "-q", "--threads", "1"], cwd=folder)
    assert killed.returncode != 0 and (folder / "out.h5.journal").exists()
    change_a_value(folder / "records" / "SYN3_H2.AT2")
    result = run(ellroll, "run", "suite.nml", "-q", "--resume", cwd=folder)
    assert result.returncode == 2, result.stderr
    assert "record file records/SYN3_H2.AT2 changed since this run began" in result.stderr, result.stderr
    shutil.copy(ROOT / "input" / "records" / "SYN3_H2.AT2", folder / "records" / "SYN3_H2.AT2")
    assert run(ellroll, "run", "suite.nml", "-q", "--resume", cwd=folder).returncode == 0


def test_shards_run_with_different_records_are_not_merged(ellroll, tmp_path):
    folder = record_folder(tmp_path)
    assert run(ellroll, "run", "suite.nml", "-q", "--shard", "0/2", "-o", "s0.h5", cwd=folder).returncode == 0
    change_a_value(folder / "records" / "SYN1_H1.AT2")
    assert run(ellroll, "run", "suite.nml", "-q", "--shard", "1/2", "-o", "s1.h5", cwd=folder).returncode == 0
    result = run(ellroll, "merge", "out.h5", "s0.h5", "s1.h5", cwd=folder)
    assert result.returncode == 2 and "record file records/SYN1_H1.AT2" in result.stderr, result.stderr
    assert not (folder / "out.h5").exists()


@pytest.mark.parametrize("name", ["r.csv", "r: 5 bytes, crc32c 00000000.csv"])
def test_a_record_changed_between_shards_is_named_whole(ellroll, tmp_path, name):
    """A record whose name holds ': ' (as the fingerprint of a file does
    after the name): the merge's refusal names it whole (as a resume's does)."""
    (tmp_path / name).write_text("0,0,0\n0.5,0.2,0.1\n1,0,0\n")
    (tmp_path / "n.nml").write_text(f"""&geometry a = 1.0, b = 0.4, c = 0.2 /
&ball radius = 0.2, weight = 2620.0 /
&initial omega = 0.0, 0.0, 0.0 /
&integration method = 'rk4', dt = 1e-3, t_end = 1.0 /
&excitation kind = 'record', record_file = '{name}' /
&output interval = 0.1 /
&sweep name = 'scale', values = 1, 2 /
""")
    assert run(ellroll, "run", "n.nml", "-q", "--shard", "0/2", "-o", "s0.h5", cwd=tmp_path).returncode == 0
    (tmp_path / name).write_text("0,0,0\n0.5,0.3,0.1\n1,0,0\n")
    assert run(ellroll, "run", "n.nml", "-q", "--shard", "1/2", "-o", "s1.h5", cwd=tmp_path).returncode == 0
    result = run(ellroll, "merge", "out.h5", "s0.h5", "s1.h5", cwd=tmp_path)
    assert result.returncode == 2, result.stderr
    assert f"s1.h5: ran with other contents of record file {name} than s0.h5;" in result.stderr, result.stderr


def test_a_merge_from_another_folder_says_where_it_reads_the_input_again(ellroll, tmp_path):
    """Shards run in the suite's folder, merged from the folder above it: the
    merge reads the stored input's record files again from there. Without
    them there, and with an edited copy there, it names what it read from
    where and the way out (the folder the shards ran in); from there the
    merge is made."""
    folder = record_folder(tmp_path)
    for k in (0, 1):
        assert run(ellroll, "run", "suite.nml", "-q", "--shard", f"{k}/2", "-o", f"s{k}.h5", cwd=folder).returncode == 0
    above = folder.parent
    shards = [f"{folder.name}/s0.h5", f"{folder.name}/s1.h5"]
    result = run(ellroll, "merge", "out.h5", *shards, cwd=above)
    assert result.returncode == 2, result.stderr
    assert f"merge reads again the input {folder.name}/s0.h5 stores, with its files, from this folder: suite.nml:" \
           in result.stderr and "cannot open records/SYN1_H1.AT2" in result.stderr, result.stderr
    assert "run the merge from the folder the shards ran in (where suite.nml is)" in result.stderr, result.stderr
    shutil.copytree(folder / "records", above / "records")
    change_a_value(above / "records" / "SYN1_H1.AT2")
    result = run(ellroll, "merge", "out.h5", *shards, cwd=above)
    assert result.returncode == 2 and "is not the campaign it ran (a file it reads, such as a record, differs" \
        in result.stderr, result.stderr
    assert not (above / "out.h5").exists()
    assert run(ellroll, "merge", "out.h5", "s0.h5", "s1.h5", cwd=folder).returncode == 0


@pytest.mark.parametrize("what", ["output", "record"])
def test_a_fifo_is_refused_without_waiting(ellroll, tmp_path, what):
    folder = record_folder(tmp_path)
    if what == "output":
        os.mkfifo(folder / "out.h5")
    else:
        (folder / "records" / "SYN1_H1.AT2").unlink()
        os.mkfifo(folder / "records" / "SYN1_H1.AT2")
    for command in ("check", "run"):
        result = run(ellroll, command, "suite.nml", "-q" if command == "run" else "--threads", *(
            [] if command == "run" else ["1"]), cwd=folder, timeout=30)
        assert result.returncode in (2, 3) and "not a regular file" in result.stderr, result.stderr


STDOUT_COMMANDS = [["inputs"], ["methods"], ["--help"], ["run", "--help"], ["check", "w.nml"], ["modes", "w.nml"],
                   ["summary", "w.h5"], ["summary", "w.h5", "--format", "csv"], ["summary", "w.h5", "--format", "json"],
                   ["run", "w.nml", "-o", "again.h5", "-q"]]


def printed_folder(ellroll, tmp_path_factory):
    """A folder with a small campaign (w.nml, 6 cases) and its output w.h5."""
    folder = tmp_path_factory.mktemp("stdout")
    (folder / "w.nml").write_text(
        "&geometry a = 1.0, b = 0.4, c = 0.2 /\n&ball radius = 0.2, weight = 2620.0 /\n"
        "&initial x = 0.0, y = 0.0, omega = -2.0, 2.0, 20.0 /\n"
        "&integration method = 'rk4', dt = 1.0e-3, t_end = 0.2 /\n&output file = 'w.h5', interval = 0.05 /\n"
        "&sweep name = 'omega_z', values = 0, 20, 40, 1000, 1e4, 1e5 /\n")
    result = subprocess.run([str(ellroll), "run", "w.nml", "-q"], cwd=folder, capture_output=True, text=True)
    assert result.returncode == 0, result.stderr
    return folder


@pytest.fixture(scope="module")
def printed(ellroll, tmp_path_factory):
    return printed_folder(ellroll, tmp_path_factory)


@pytest.mark.parametrize("command", STDOUT_COMMANDS, ids=" ".join)
def test_a_lost_standard_output_is_exit_3(ellroll, printed, command):
    """Every command that prints: its standard output on a full device
    (/dev/full: each write fails with ENOSPC) ends in exit 3 with the reason
    on stderr; the same command to a pipe prints and exits 0."""
    (printed / "again.h5").unlink(missing_ok=True)
    fine = subprocess.run([str(ellroll), *command], cwd=printed, capture_output=True, text=True, timeout=60)
    assert fine.returncode == 0 and fine.stdout, fine.stderr
    (printed / "again.h5").unlink(missing_ok=True)
    with open("/dev/full", "w") as full:
        lost = subprocess.run([str(ellroll), *command], cwd=printed, stdout=full, stderr=subprocess.PIPE, text=True,
                              timeout=60)
    assert lost.returncode >= 0, command
    assert lost.returncode == 3, lost.stderr
    assert "cannot write the standard output: No space left on device" in lost.stderr


@pytest.mark.skipif(shutil.which("strace") is None, reason="strace is not installed")
def test_a_run_on_a_file_system_without_locks_leaves_no_lock_file(ellroll, tmp_path):
    """fcntl F_SETLK failing with ENOLCK (a file system without locks): the
    run warns, writes its output, and leaves no OUT.lock (docs/usage.md)."""
    folder = folder_with(tmp_path)
    result = subprocess.run(["strace", "-f", "-o", "/dev/null", "-e", "inject=fcntl:error=ENOLCK",
                             str(ellroll), "run", "camp.nml", "-q"], cwd=folder, capture_output=True, text=True,
                            timeout=120)
    assert result.returncode == 0, result.stderr
    assert "the file system cannot lock files (No locks available)" in result.stderr
    assert sorted(p.name for p in folder.iterdir()) == ["camp.nml", "out.h5"]


def near_misses(rng, own):
    """A user's files that look like ellroll-plot's output without being it:
    texts that mention the tool, tables that begin with `case,`, and the
    tool's own output with its mark moved out of its place (seeded)."""
    filler = "".join(rng.choice(list("abc ,\n")) for _ in range(int(rng.integers(10, 400))))
    yield "#!/bin/sh\nellroll-plot trace run.h5 --out figures\n" + filler
    yield "notes: ellroll-plot made the figures\n" + filler
    yield "case,my_comment\n1,fine\n" + filler
    yield f"case,status\n0,{filler}"
    yield filler + "\n" + own.decode("latin-1")            # the mark no longer in its place
    yield "x" + own.decode("latin-1")


@pytest.mark.parametrize("command", [["trace"], ["report"], ["trace", "--format", "svg"], ["trace", "--format", "pdf"]],
                         ids=["png", "report", "svg", "pdf"])
def test_ellroll_plot_takes_only_its_marks_in_their_place_as_its_own(plotted, command):
    """A file at an output's name counts as ellroll-plot's by its mark in its
    place alone (a figure's metadata, a page's generator, a table's first
    line): a script or notes that mention ellroll-plot, a user's table that
    begins with `case,`, or its own output with bytes before it are never
    replaced, even with --overwrite."""
    figures = f"own_{'_'.join(command)}"
    code, out, err = plot(plotted, command[0], "out.h5", *command[1:], "--out", figures)
    assert code == 0, err
    targets = [plotted / line for line in out.splitlines() if line]
    if command == ["report"]:
        targets = [plotted / figures / name for name in ("index.html", "summary.csv")]
    rng = np.random.default_rng(1700 + len(figures))
    for target in targets:
        own = target.read_bytes()
        for text in near_misses(rng, own):
            target.write_bytes(text.encode("latin-1"))
            code, _, err = plot(plotted, command[0], "out.h5", *command[1:], "--out", figures, "--overwrite")
            assert code == 2 and "not made by ellroll-plot" in err, (target.name, text[:60], err)
            assert target.read_bytes() == text.encode("latin-1"), target.name
        target.write_bytes(own)
    code, _, err = plot(plotted, command[0], "out.h5", *command[1:], "--out", figures, "--overwrite")
    assert code == 0, err


def test_check_and_run_say_when_the_output_passes_the_free_space(ellroll, tmp_path):
    """An output of about 124 TiB (1e5 cases of 1e7 samples): `check` gives
    its size and the free space of its file system, and warns that a run
    would stop (exit 3) when the disk is full, its journal keeping the cases
    finished. A small output gets no warning."""
    paper = PAPER_INPUT.read_text()
    big = paper.replace("t_end = 30.0", "t_end = 10000.0").replace("interval = 0.01", "interval = 1.0e-3")
    (tmp_path / "big.nml").write_text(big + "&sweep name = 'omega_z', start = 5, stop = 50, count = 100000 /\n")
    result = run(ellroll, "check", "big.nml", cwd=tmp_path)
    assert result.returncode == 0, result.stderr
    assert re.search(r"the output and its journal, uncompressed, about 12\d{4}\.\d GiB; free on its file system "
                     r"[\d.]+ [KMG]iB", result.stdout), result.stdout
    assert re.search(r"ellroll: warning: \S+ and its journal take about 12\d{4}\.\d GiB, more than the [\d.]+ GiB free on "
                     r"its file system: the run stops \(exit 3\) when it is full", result.stderr), result.stderr
    (tmp_path / "small.nml").write_text(paper)
    result = run(ellroll, "check", "small.nml", cwd=tmp_path)
    assert result.returncode == 0 and "warning" not in result.stderr, result.stderr
    assert list(p.name for p in tmp_path.iterdir() if p.suffix != ".nml") == []
