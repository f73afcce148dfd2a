"""Where the output goes, decided before any case runs: a folder that cannot
take the file is named by run and check alike; a file that is not an
ellroll output (the input itself, say) is never replaced, even with
--overwrite; a resume of a run that is already complete has nothing to do,
one of a run that never began runs it. And what a log file sees: progress
as the run goes."""
import hashlib
import re
import subprocess
import time

import pytest

from conftest import run
from test_campaign import JOURNAL_HEADER, assert_same_datasets, record_bytes, write


def digest(path):
    return hashlib.sha256(path.read_bytes()).hexdigest()


def test_an_output_onto_the_input_is_refused_even_with_overwrite(ellroll, tmp_path):
    name = write(tmp_path, "", t_end=0.1)
    before = digest(tmp_path / name)
    for command in (["run", name, "-o", name, "--overwrite"], ["check", name, "-o", name]):
        result = run(ellroll, *command, cwd=tmp_path)
        assert result.returncode == 3, result.stderr
        assert f"{name}: is the input file; it is never written" in result.stderr
    assert digest(tmp_path / name) == before
    assert sorted(p.name for p in tmp_path.iterdir()) == [name]


def test_an_existing_file_of_another_kind_is_never_replaced(ellroll, tmp_path):
    name = write(tmp_path, "", t_end=0.1)
    (tmp_path / "out.h5").write_bytes(b"results of another program\n")
    result = run(ellroll, "run", name, "--overwrite", cwd=tmp_path)
    assert result.returncode == 3 and "out.h5: exists and is not an ellroll output file" in result.stderr
    assert (tmp_path / "out.h5").read_bytes() == b"results of another program\n"


def test_a_missing_output_folder_is_named_by_check_and_run(ellroll, tmp_path):
    name = write(tmp_path, "", t_end=0.1)
    for command in ("check", "run"):
        result = run(ellroll, command, name, "-o", "no_such_folder/out.h5", cwd=tmp_path)
        assert result.returncode == 3, result.stderr
        assert ("no_such_folder/out.h5: cannot create files in folder no_such_folder: No such file or directory"
                in result.stderr), result.stderr
    assert sorted(p.name for p in tmp_path.iterdir()) == [name]


def test_resuming_a_complete_run_has_nothing_to_do(ellroll, tmp_path):
    name = write(tmp_path, "&sweep name = 'omega_z', values = 5, 10 /\n", t_end=0.1)
    assert run(ellroll, "run", name, "-q", cwd=tmp_path).returncode == 0
    before = digest(tmp_path / "out.h5")
    result = run(ellroll, "run", name, "--resume", cwd=tmp_path)
    assert result.returncode == 0, result.stderr
    assert "out.h5: this run is already complete; nothing to do" in result.stderr
    assert digest(tmp_path / "out.h5") == before
    # the same output name from another input is no run to resume
    other = write(tmp_path, "&sweep name = 'omega_z', values = 5, 11 /\n", t_end=0.1, name="other.nml")
    result = run(ellroll, "run", other, "--resume", cwd=tmp_path)
    assert result.returncode == 3 and "holds the output of another input" in result.stderr
    assert digest(tmp_path / "out.h5") == before


def test_a_resume_with_nothing_begun_is_the_first_run(ellroll, tmp_path):
    """What a requeued batch job meets on its first start: --resume runs the
    whole campaign."""
    name = write(tmp_path, "&sweep name = 'omega_z', values = 5, 10 /\n", t_end=0.1)
    result = run(ellroll, "run", name, "--resume", "-q", cwd=tmp_path)
    assert result.returncode == 0, result.stderr
    run(ellroll, "run", name, "-q", "-o", "alone.h5", cwd=tmp_path)
    assert_same_datasets(tmp_path / "out.h5", tmp_path / "alone.h5")
    assert not (tmp_path / "out.h5.journal").exists()


@pytest.mark.parametrize("journal_bytes", [0, 20])
@pytest.mark.parametrize("resume", [True, False])
def test_a_journal_killed_before_its_header_starts_the_run_afresh(ellroll, tmp_path, journal_bytes, resume):
    """A kill before the journal's header reached the disk leaves an empty or
    torn journal: nothing was finished, so a resume (or a plain run) starts
    afresh, says so, and exits 0, instead of asking for a resume forever."""
    name = write(tmp_path, "&sweep name = 'omega_z', values = 5, 10 /\n", t_end=0.1)
    (tmp_path / "out.h5.journal").write_bytes((b"ELLROLL2" + bytes(64))[:journal_bytes])
    (tmp_path / "out.h5.partial").write_bytes(bytes(100))
    result = run(ellroll, "run", name, "-q", *(["--resume"] if resume else []), cwd=tmp_path)
    assert result.returncode == 0, result.stderr
    assert "finished no case (killed before the journal's header was written); starting afresh" in result.stderr
    run(ellroll, "run", name, "-q", "-o", "alone.h5", cwd=tmp_path)
    assert_same_datasets(tmp_path / "out.h5", tmp_path / "alone.h5")
    assert not (tmp_path / "out.h5.journal").exists() and not (tmp_path / "out.h5.partial").exists()


def test_progress_reaches_a_log_file_while_the_run_goes(ellroll, tmp_path):
    """stderr redirected to a file, as in a batch job: full lines, flushed at
    each tenth of the cases, are there before the run ends; the last has the
    totals; -q silences them."""
    name = "log.nml"          # 40 cases of 300,000 steps, little output: a few seconds
    (tmp_path / name).write_text(
        "&geometry a = 1.0, b = 0.4, c = 0.2 /\n&ball radius = 0.2, weight = 2620.0 /\n"
        "&initial x = 0.0, y = 0.0, omega = -2.0, 2.0, 20.0 /\n&integration dt = 1.0e-3, t_end = 300.0 /\n"
        "&output file = 'out.h5', interval = 10.0, fields = 'energy' /\n"
        "&sweep name = 'omega_z', start = 1, stop = 40, count = 40 /\n")
    with open(tmp_path / "log.txt", "w") as log:
        process = subprocess.Popen([str(ellroll), "run", name, "--threads", "1"], cwd=tmp_path, stderr=log)
        seen_while_running = ""
        while process.poll() is None and not seen_while_running:
            time.sleep(0.05)
            seen_while_running = (tmp_path / "log.txt").read_text()
        assert process.wait(timeout=300) == 0
    assert re.match(r"ellroll: \d+/40 cases \(\d+%\)", seen_while_running), seen_while_running
    lines = (tmp_path / "log.txt").read_text().splitlines()
    assert "\r" not in "".join(lines)
    progress = [line for line in lines if re.match(r"ellroll: \d+/40 cases", line)]
    percents = [int(re.search(r"\((\d+)%\)", line).group(1)) for line in progress]
    assert set(range(10, 101, 10)) <= set(percents) and percents == sorted(percents)   # (and one each 10 s)
    assert progress[-1].startswith("ellroll: 40/40 cases (100%), ")
    result = run(ellroll, "run", name, "-q", "-o", "quiet.h5", cwd=tmp_path)
    assert result.returncode == 0 and result.stderr == ""


@pytest.mark.parametrize("where", ["creation", "cases"])
def test_a_file_size_limit_is_a_clean_write_error_and_the_resume_finishes(ellroll, tmp_path, where):
    """A file-size limit (ulimit -f, as batch systems set it) makes the
    writes fail with EFBIG, at the file's creation (64 KiB) or once some
    cases are done (50 kB below the final size: the last cases' trajectories
    lie beyond it): exit 3 naming the file and the system's reason, no
    signal; the file --overwrite was to replace is untouched; a run that
    finished nothing leaves no file behind; a resume without the limit gives
    the uninterrupted run's file."""
    import resource
    name = write(tmp_path, "&sweep name = 'omega_z', values = 5, 10, 20, 40, 80 /\n"
                           "&sweep name = 'radius', start = 0.05, stop = 0.2, count = 4, spacing = 'linear' /\n",
                 t_end=3.0)
    assert run(ellroll, "run", name, "-q", "-o", "whole.h5", cwd=tmp_path).returncode == 0
    assert run(ellroll, "run", name, "-q", "-o", "out.h5", "--threads", "1", cwd=tmp_path).returncode == 0
    before = digest(tmp_path / "out.h5")

    limit = 64 * 1024 if where == "creation" else (tmp_path / "whole.h5").stat().st_size - 50_000

    def limited():
        resource.setrlimit(resource.RLIMIT_FSIZE, (limit, limit))
    result = subprocess.run([str(ellroll), "run", name, "-q", "--overwrite", "--threads", "1"], cwd=tmp_path,
                            capture_output=True, text=True, preexec_fn=limited, timeout=120)
    assert result.returncode == 3, (result.returncode, result.stderr)
    assert "out.h5.partial: cannot write" in result.stderr and "File too large" in result.stderr, result.stderr
    assert "Program received signal" not in result.stderr
    assert digest(tmp_path / "out.h5") == before
    if where == "creation":         # nothing finished: no file left behind
        assert not (tmp_path / "out.h5.journal").exists() and not (tmp_path / "out.h5.partial").exists()
    else:
        assert (tmp_path / "out.h5.journal").stat().st_size > JOURNAL_HEADER
    resumed = run(ellroll, "run", name, "-q", "--resume", cwd=tmp_path)
    assert resumed.returncode == 0, resumed.stderr
    assert_same_datasets(tmp_path / "whole.h5", tmp_path / "out.h5")


@pytest.fixture
def small_disk(tmp_path):
    """A 820 kB tmpfs (root, where mount is allowed), or skip."""
    folder = tmp_path / "disk"
    folder.mkdir()
    mounted = subprocess.run(["mount", "-t", "tmpfs", "-o", "size=820k", "tmpfs", str(folder)],
                             capture_output=True, text=True)
    if mounted.returncode != 0:
        pytest.skip("cannot mount a tmpfs here: " + mounted.stderr.strip())
    try:
        yield folder
    finally:
        subprocess.run(["umount", str(folder)], check=True)


def blocks(path, block=4096):
    return -(-path.stat().st_size // block) * block


def test_a_full_disk_is_a_clean_write_error_and_the_resume_finishes_in_the_final_files_room(ellroll, tmp_path,
                                                                                           small_disk):
    """The output's disk fills up once some cases are done: exit 3 with the
    system's reason, no signal. The resume needs room for the final file and
    the journal, and a few blocks: the disk grows 8 KiB at a time from just
    above what the killed run left, and each resume that fills it again
    (while it moves the cases to the new file) loses nothing, the next one
    takes its cases back. The first to finish has at most the final file,
    the final journal, the input and 2 blocks per stored field (64 KiB) of
    room, and gives the uninterrupted run's file, no case run twice."""
    name = write(tmp_path, "&sweep name = 'omega_z', values = 5, 10, 20, 40, 80 /\n"
                           "&sweep name = 'radius', start = 0.05, stop = 0.2, count = 4, spacing = 'linear' /\n",
                 t_end=3.0)
    assert run(ellroll, "run", name, "-q", "-o", "whole.h5", cwd=tmp_path).returncode == 0
    (small_disk / name).write_text((tmp_path / name).read_text())
    result = run(ellroll, "run", name, "-q", "--threads", "1", cwd=small_disk)
    assert result.returncode == 3, (result.returncode, result.stderr)
    assert "out.h5.partial: cannot" in result.stderr and "No space left on device" in result.stderr, result.stderr
    assert "Program received signal" not in result.stderr
    assert (small_disk / "out.h5.journal").stat().st_size > JOURNAL_HEADER

    final_journal = JOURNAL_HEADER + 20 * record_bytes()
    room = blocks(tmp_path / "whole.h5") + blocks(tmp_path / name) + -(-final_journal // 4096) * 4096 + 64 * 1024
    size = sum(blocks(p) for p in small_disk.iterdir()) + 8 * 1024
    attempts = []
    while size <= room:
        subprocess.run(["mount", "-o", f"remount,size={size // 1024}k", str(small_disk)], check=True)
        resumed = run(ellroll, "run", name, "-q", "--resume", cwd=small_disk)
        attempts.append((size // 1024, resumed.returncode))
        assert "cases run again" not in resumed.stderr, (attempts, resumed.stderr)
        if resumed.returncode == 0:
            break
        assert resumed.returncode == 3 and "No space left on device" in resumed.stderr, resumed.stderr
        size += 8 * 1024
    assert attempts[-1][1] == 0, (attempts, room // 1024)
    assert len(attempts) > 1, attempts         # at least one resume filled the disk while moving the cases
    assert_same_datasets(tmp_path / "whole.h5", small_disk / "out.h5")
    assert sorted(p.name for p in small_disk.iterdir()) == [name, "out.h5"]
