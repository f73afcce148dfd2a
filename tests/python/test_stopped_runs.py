"""The reader and ellroll-plot on the work files of a run that stopped:
a run stopped by SIGTERM closes OUT.h5.partial cleanly, and the reader
reads its finished cases as the whole run holds them, each by its global
index, and NaN for what was not run (seeded shards and stopping points); a
run killed -9 after `run --overwrite` is named with the command that
finishes it, which ellroll takes."""
import random
import signal
import subprocess
import time

import numpy as np
import pytest

import ellroll_post
from conftest import run
from test_campaign import record_bytes
from test_plot_cli_inputs import cli, one_line_error, write

CASES = 24
SWEEP = f"&sweep name = 'omega_z', start = 5, stop = 50, count = {CASES} /\n"


def stop_after_records(args, cwd, journal, records, how=signal.SIGTERM):
    """Start a run and send it `how` once its journal holds `records` cases;
    the run's exit code (0 where it finished first)."""
    proc = subprocess.Popen(args, cwd=cwd, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    deadline = time.monotonic() + 60
    while proc.poll() is None and time.monotonic() < deadline:
        if journal.exists() and journal.stat().st_size >= records * record_bytes():
            break
        time.sleep(0.002)
    if proc.poll() is None:
        proc.send_signal(how)
    return proc.wait(timeout=60)


@pytest.fixture(scope="module")
def whole(ellroll, tmp_path_factory):
    folder = tmp_path_factory.mktemp("stopped")
    name = write(folder, "w", SWEEP, t_end=3.0, estimate=False)
    result = run(ellroll, "run", name, "-q", "--threads", 2, cwd=folder)
    assert result.returncode == 0, result.stderr
    return folder


@pytest.mark.parametrize("options", [["--overwrite"], ["--threads", "1", "--overwrite", "-q"],
                                     ["--overwrite", "--shard", "1/2"]])
def test_the_command_named_for_a_killed_overwrite_run_finishes_it(ellroll, whole, tmp_path, options):
    """A run started with --overwrite (over a finished output) and killed -9:
    the reader and every ellroll-plot subcommand name the command that
    finishes it, its lock's without --overwrite (ellroll refuses --resume
    with it), and that command, run from the folder, finishes the run."""
    name = write(tmp_path, "w", SWEEP, t_end=3.0, estimate=False)
    assert run(ellroll, "run", name, "-q", "-o", "k.h5", cwd=tmp_path).returncode == 0
    command = [str(ellroll), "run", name, "-o", "k.h5", "--threads", "1", *options]
    assert stop_after_records(command, tmp_path, tmp_path / "k.h5.journal", 2, signal.SIGKILL) == -signal.SIGKILL
    with pytest.raises(ellroll_post.NotAnEllrollFile) as raised:
        ellroll_post.open(tmp_path / "k.h5.partial")
    said = str(raised.value)
    advised = said.split("finish it with '", 1)[1].split(" (the command", 1)[0].rstrip("'")
    assert "--overwrite" not in advised and advised.endswith(" --resume"), said
    code, _, err = cli("summary", tmp_path / "k.h5.partial")
    one_line_error(code, err, "k.h5.partial", advised)
    result = subprocess.run(advised.replace("ellroll ", f"{ellroll} ", 1), shell=True, cwd=tmp_path,
                            capture_output=True, text=True, timeout=120)
    assert result.returncode == 0, result.stderr
    with ellroll_post.open(tmp_path / "k.h5") as done, ellroll_post.open(whole / "w.h5") as full:
        assert set(done.status_names()) == {"completed"}
        for case in done.cases:
            assert np.array_equal(done.trajectory("nutation", case), full.trajectory("nutation", case))
