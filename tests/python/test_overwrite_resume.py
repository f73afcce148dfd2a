"""An --overwrite run of a complete output of the same campaign, stopped
(SIGTERM, kill -9) half way: --resume finishes it and replaces the old
file, keeping every case the stopped run had finished."""
import os
import random
import shutil
import signal
import subprocess
import time

import h5py
import pytest

from conftest import run
from test_campaign import SPIN_RADIUS, assert_same_datasets, journal_wall_times, record_bytes, write


@pytest.mark.parametrize("compression", [0, 4])
@pytest.mark.parametrize("stop", [signal.SIGTERM, signal.SIGKILL])
def test_a_stopped_overwrite_of_the_same_campaign_resumes(ellroll, tmp_path, stop, compression):
    name = write(tmp_path, SPIN_RADIUS.replace("count = 4", "count = 40"), t_end=5.0)
    text = (tmp_path / name).read_text()
    (tmp_path / name).write_text(text.replace("interval = 0.01 /", f"interval = 0.01, compression = {compression} /"))
    assert run(ellroll, "run", name, "-q", "-o", "whole.h5", cwd=tmp_path).returncode == 0
    assert run(ellroll, "run", name, "-q", cwd=tmp_path).returncode == 0        # the old output: complete
    with h5py.File(tmp_path / "out.h5", "r") as f:
        old_wall = f["summary/wall_time"][:]
    journal = tmp_path / "out.h5.journal"
    in_record = 501 * 17 if compression else 0
    rng = random.Random(12 + stop + compression)
    proc = subprocess.Popen([str(ellroll), "run", name, "-q", "--threads", "2", "--overwrite"], cwd=tmp_path,
                            stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True)
    while proc.poll() is None and not (journal.exists() and journal.stat().st_size >= 3 * record_bytes(in_record)):
        time.sleep(0.002)
    time.sleep(rng.uniform(0.0, 0.02))
    assert proc.poll() is None, "the run finished before the signal"
    proc.send_signal(stop)
    _, stderr = proc.communicate(timeout=30)
    assert proc.returncode == (128 + stop if stop == signal.SIGTERM else -stop), stderr
    if stop == signal.SIGTERM:
        assert f"'ellroll run {name} -q --threads 2 --resume' finishes the rest" in stderr
    kept = journal_wall_times(journal, in_record)
    assert 0 < len(kept) < 200 and (tmp_path / "out.h5.partial").exists()
    result = run(ellroll, "run", name, "-q", "--threads", "2", "--resume", cwd=tmp_path)
    assert result.returncode == 0, result.stderr
    assert "nothing to do" not in result.stderr and "removing the journal" not in result.stderr
    assert not any((tmp_path / f"out.h5.{end}").exists() for end in ("journal", "partial", "partial.new", "lock"))
    assert_same_datasets(tmp_path / "whole.h5", tmp_path / "out.h5")
    with h5py.File(tmp_path / "out.h5", "r") as f:
        wall = f["summary/wall_time"][:]
    assert all(wall[slot] == seconds for slot, seconds in kept.items()), "a finished case was lost"
    assert any(wall[slot] != old_wall[slot] for slot in kept), "the old file was kept"


def test_a_journal_left_after_the_move_into_place_still_goes(ellroll, tmp_path):
    """The run that wrote the output killed after moving its file into place
    (no work file left): its journal goes and a resume has nothing to do."""
    name = write(tmp_path, SPIN_RADIUS, t_end=1.0)
    assert run(ellroll, "run", name, "-q", cwd=tmp_path).returncode == 0
    journal = tmp_path / "out.h5.journal"
    # a journal of this campaign beside the complete output, and no work file
    proc = subprocess.Popen([str(ellroll), "run", name, "-q", "--overwrite", "--threads", "1"], cwd=tmp_path,
                            stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    while proc.poll() is None and not (journal.exists() and journal.stat().st_size >= 2 * record_bytes()):
        time.sleep(0.002)
    proc.send_signal(signal.SIGKILL)
    proc.wait()
    (tmp_path / "out.h5.partial").unlink()
    result = run(ellroll, "run", name, "-q", "--resume", cwd=tmp_path)
    assert result.returncode == 0, result.stderr
    assert "removing the journal of the run that wrote it" in result.stderr and "nothing to do" in result.stderr
    assert not journal.exists()


@pytest.mark.parametrize("left", ["nothing", "work file"])
def test_a_resume_with_no_journal_says_so_and_runs_every_case(ellroll, tmp_path, left):
    """--resume where the output has no journal (a mistyped -o, a journal
    lost; a killed run's work file left without it): one line saying so,
    then every case run, the output the plain run's."""
    name = write(tmp_path, SPIN_RADIUS, t_end=0.05)
    assert run(ellroll, "run", name, "-q", "-o", "whole.h5", cwd=tmp_path).returncode == 0
    if left == "work file":
        killed = subprocess.run(["strace", "-f", "-o", "/dev/null", "-e", "inject=pwritev:signal=SIGKILL:when=3",
                                 str(ellroll), "run", name, "-q", "--threads", "1"], cwd=tmp_path,
                                capture_output=True)
        assert killed.returncode != 0 and (tmp_path / "out.h5.partial").exists()
        (tmp_path / "out.h5.journal").unlink()
        (tmp_path / "out.h5.lock").unlink(missing_ok=True)
    result = run(ellroll, "run", name, "--resume", cwd=tmp_path)
    assert result.returncode == 0, result.stderr
    first = result.stderr.splitlines()[0]
    if left == "work file":
        assert first == ("ellroll: resuming out.h5: no journal out.h5.journal (the work file out.h5.partial without "
                         "it holds no case a resume can trust); running all cases"), result.stderr
    else:
        assert first == "ellroll: resuming out.h5: no journal out.h5.journal, so no case is kept; running all cases"
    assert_same_datasets(tmp_path / "whole.h5", tmp_path / "out.h5")


def killed_run(ellroll, tmp_path):
    """A 200-case campaign (its whole run in whole.h5) killed once its
    journal holds 8 cases: the input's name and the journal."""
    name = write(tmp_path, SPIN_RADIUS.replace("count = 4", "count = 40"), t_end=5.0)
    assert run(ellroll, "run", name, "-q", "-o", "whole.h5", cwd=tmp_path).returncode == 0
    journal = tmp_path / "out.h5.journal"
    proc = subprocess.Popen([str(ellroll), "run", name, "-q", "--threads", "2"], cwd=tmp_path,
                            stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    while proc.poll() is None and not (journal.exists() and journal.stat().st_size >= 8 * record_bytes(0)):
        time.sleep(0.002)
    assert proc.poll() is None, "the run finished before the signal"
    proc.kill()
    proc.wait(timeout=30)
    return name, journal


def test_a_resume_leaves_a_hard_link_of_the_stopped_run_s_work_file_as_it_was(ellroll, tmp_path):
    """A backup of the killed run's work file and journal made with hard
    links (ln, cp -al, rsnapshot) before --resume: the resume frees no room
    in a file that another name holds and writes its journal records to a
    copy of one name, so the backup keeps its bytes and its blocks, and a
    resume from the backup keeps every case the killed run finished."""
    name, journal = killed_run(ellroll, tmp_path)
    kept = journal_wall_times(journal, 0)
    backup = tmp_path / "backup"
    backup.mkdir()
    (backup / "out.h5.partial").hardlink_to(tmp_path / "out.h5.partial")
    (backup / "out.h5.journal").hardlink_to(journal)
    (backup / name).write_bytes((tmp_path / name).read_bytes())
    before = (backup / "out.h5.partial").read_bytes(), (backup / "out.h5.partial").stat().st_blocks
    journal_before = journal.read_bytes()
    result = run(ellroll, "run", name, "-q", "--threads", "2", "--resume", cwd=tmp_path)
    assert result.returncode == 0, result.stderr
    assert_same_datasets(tmp_path / "whole.h5", tmp_path / "out.h5")
    assert ((backup / "out.h5.partial").read_bytes(), (backup / "out.h5.partial").stat().st_blocks) == before
    assert (backup / "out.h5.journal").read_bytes() == journal_before
    assert sorted(p.name for p in tmp_path.glob("out.h5*")) == ["out.h5"]
    result = run(ellroll, "run", name, "-q", "--threads", "2", "--resume", cwd=backup)
    assert result.returncode == 0 and "damaged" not in result.stderr, result.stderr
    with h5py.File(backup / "out.h5", "r") as f:
        wall = f["summary/wall_time"][:]
    assert len(kept) >= 8 and all(wall[slot] == seconds for slot, seconds in kept.items()), "a finished case was lost"


@pytest.mark.skipif(shutil.which("strace") is None, reason="strace is not installed")
@pytest.mark.parametrize("error, when", [("EIO", 4), ("ENOSPC", 6), ("EFBIG", 12)])
def test_a_resume_that_fails_laying_out_its_file_leaves_none(ellroll, tmp_path, error, when):
    """A resume whose disk fails at one of the first writes of its own file
    (OUT.h5.partial.new, which HDF5 lays out): exit 3, that file gone (it
    holds no case), and the next --resume, as the message says, gives the
    uninterrupted run's file."""
    name, journal = killed_run(ellroll, tmp_path)
    failed = subprocess.run(["strace", "-f", "-qq", "-o", os.devnull, "-e", "trace=pwrite64", "-e",
                             f"inject=pwrite64:error={error}:when={when}", str(ellroll), "run", name, "-q", "--resume",
                             "--threads", "1"], cwd=tmp_path, capture_output=True, text=True, timeout=300)
    assert failed.returncode == 3 and "run again with --resume" in failed.stderr, failed.stderr
    assert not (tmp_path / "out.h5.partial.new").exists()
    result = run(ellroll, "run", name, "-q", "--resume", cwd=tmp_path)
    assert result.returncode == 0, result.stderr
    assert_same_datasets(tmp_path / "whole.h5", tmp_path / "out.h5")


@pytest.mark.parametrize("left", ["a copy cut short", "another file"])
def test_a_resume_meets_a_file_at_its_journal_copy_s_name(ellroll, tmp_path, left):
    """A journal with another name (a cp -al backup) and a file at
    OUT.h5.journal.new, where the resume makes its copy: the first bytes of
    the journal (a resume killed while it copied) go, and the resume gives
    the uninterrupted run's file; any other file stays, and the resume is
    refused naming it (exit 3)."""
    name, journal = killed_run(ellroll, tmp_path)
    (tmp_path / "backup").mkdir()
    (tmp_path / "backup" / "out.h5.journal").hardlink_to(journal)
    copy = tmp_path / "out.h5.journal.new"
    content = journal.read_bytes()[:3000] if left == "a copy cut short" else b"notes of mine\n"
    copy.write_bytes(content)
    result = run(ellroll, "run", name, "-q", "--resume", cwd=tmp_path)
    if left == "a copy cut short":
        assert result.returncode == 0, result.stderr
        assert not copy.exists()
        assert_same_datasets(tmp_path / "whole.h5", tmp_path / "out.h5")
    else:
        assert result.returncode == 3 and "out.h5.journal.new is there and is not a copy of it" in result.stderr, \
            result.stderr
        assert copy.read_bytes() == content
