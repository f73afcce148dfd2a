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


def test_a_sigterm_stopped_work_file_reads_its_finished_cases(ellroll, whole, tmp_path):
    """Seeded shards I/N stopped by SIGTERM after a seeded number of cases:
    the work file's cases are I, I+N, ... (its pending ones included); each
    finished case's status and trajectories are the whole run's, bit for
    bit; each pending case's trajectories are NaN, never 0; and a per-case
    figure of case I draws it while one of a pending case says never run."""
    rng = random.Random(1212)
    stopped = 0
    with ellroll_post.open(whole / "w.h5") as full:
        fields = full.fields
        for trial in range(4):
            shards = rng.choice([1, 2, 3])
            shard = rng.randrange(shards)
            folder = tmp_path / f"t{trial}"
            folder.mkdir()
            name = write(folder, "w", SWEEP, t_end=3.0, estimate=False)
            code = stop_after_records([str(ellroll), "run", name, "-q", "--threads", "1", "--shard",
                                       f"{shard}/{shards}", "-o", "s.h5"], folder, folder / "s.h5.journal",
                                      rng.randint(1, 4))
            if code == 0:
                continue            # (it finished first)
            assert code == 128 + signal.SIGTERM
            stopped += 1
            partial = folder / "s.h5.partial"
            with ellroll_post.open(partial) as part:
                expected = list(range(shard, CASES, shards))
                assert part.cases.tolist() == expected
                status = part.status_names()
                assert 0 < status.count("completed") and "pending" in status, status
                for case, name_ in zip(expected, status):
                    assert part.case_index(case) == case
                    if name_ == "pending":
                        for field in fields:
                            assert np.all(np.isnan(part.trajectory(field, case))), (case, field)
                        continue
                    assert name_ == full.status_name(case)
                    for field in fields:
                        assert np.array_equal(part.trajectory(field, case), full.trajectory(field, case),
                                              equal_nan=True), (case, field)
                first_pending = expected[status.index("pending")]
            code, _, err = cli("nutation", partial, "--case", first_pending, "--out", folder)
            one_line_error(code, err, "s.h5.partial", f"case {first_pending} was never run")
            code, out, err = cli("nutation", partial, "--case", shard, "--out", folder)
            assert code == 0 and out.strip().endswith(f"case{shard}.png" if shard else ".png"), (code, err)
    assert stopped >= 2


@pytest.mark.parametrize("options", [["--overwrite"], ["-q", "--overwrite"],
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
