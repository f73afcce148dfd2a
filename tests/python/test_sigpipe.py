"""A reader of `run`'s standard output or error that goes away (`| head -1`,
a dead tee): the run is not ended by SIGPIPE; it finishes its file (equal
to an uninterrupted run's), and a summary it cannot write is exit 3."""
import subprocess
import time

import pytest

from conftest import run
from test_campaign import SPIN_RADIUS, assert_same_datasets, write


@pytest.fixture()
def campaign(ellroll, tmp_path):
    name = write(tmp_path, SPIN_RADIUS.replace("count = 4", "count = 40"), t_end=5.0)
    assert run(ellroll, "run", name, "-q", "-o", "whole.h5", cwd=tmp_path).returncode == 0
    return tmp_path, name


def assert_complete(folder):
    assert_same_datasets(folder / "whole.h5", folder / "out.h5")
    assert not any((folder / f"out.h5.{end}").exists() for end in ("journal", "partial", "partial.new", "lock"))


@pytest.mark.parametrize("streams", ["both", "stderr"])
def test_a_reader_gone_after_the_first_progress_line(ellroll, campaign, streams):
    """`ellroll run camp.nml 2>&1 | head -1`, and a reader of stderr alone."""
    folder, name = campaign
    if streams == "both":
        proc = subprocess.Popen([str(ellroll), "run", name, "--threads", "2"], cwd=folder, stdout=subprocess.PIPE,
                                stderr=subprocess.STDOUT)
        out = proc.stdout
    else:
        proc = subprocess.Popen([str(ellroll), "run", name, "--threads", "2"], cwd=folder, stdout=subprocess.DEVNULL,
                                stderr=subprocess.PIPE)
        out = proc.stderr
    first = out.readline()
    out.close()
    assert first and proc.poll() is None, first
    assert proc.wait(timeout=120) == (3 if streams == "both" else 0)      # (not -SIGPIPE)
    assert_complete(folder)


def test_standard_output_closed_from_the_start(ellroll, campaign):
    """`ellroll run camp.nml -q | true`: the summary cannot be written."""
    folder, name = campaign
    proc = subprocess.Popen([str(ellroll), "run", name, "-q", "--threads", "2"], cwd=folder,
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE)
    proc.stdout.close()
    _, stderr = proc.communicate(timeout=120)
    assert proc.returncode == 3 and b"cannot write the standard output" in stderr, stderr
    assert_complete(folder)


def test_a_summary_printed_to_a_pipe_read_late_is_whole(ellroll, campaign):
    """`ellroll summary out.h5 --format csv | less` (csv, json, --suite),
    left 11 s before it is read: past the 10 s that a damaged file's reads
    may take, but the rows wait on the reader, not on HDF5. Every row,
    exit 0, as printed to a file. (The three wait side by side.)"""
    folder, _ = campaign
    formats = [["--format", "csv"], ["--format", "json"], ["--suite", "--format", "csv"]]
    printed = []
    for args in formats:
        whole = run(ellroll, "summary", "whole.h5", *args, cwd=folder)
        assert whole.returncode == 0 and len(whole.stdout) > 65536, (whole.stderr, len(whole.stdout))  # (past a pipe's buffer)
        printed.append(whole.stdout)
    procs = [subprocess.Popen([str(ellroll), "summary", "whole.h5", *args], cwd=folder, stdout=subprocess.PIPE,
                              stderr=subprocess.PIPE, text=True) for args in formats]
    time.sleep(11)
    for args, proc, whole in zip(formats, procs, printed):
        out, err = proc.communicate(timeout=60)
        assert (proc.returncode, err) == (0, "") and out == whole, args
