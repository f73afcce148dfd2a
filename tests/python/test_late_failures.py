"""What is left, and what is said, when a command fails late or is stopped:
a read error while `run` prints the summary of its finished output (exit
3, no HDF5 noise at exit), a merge that fails or is stopped (SIGTERM,
SIGINT) after it wrote its work file (the work file and the lock go), and
the messages of a missing shard, a killed run's work file given as a shard,
a thread count beyond any integer and an output folder moved away during a
run. The faults are injected with strace at each call of a kind, or at a
seeded sample of them."""
import os
import pathlib
import platform
import random
import re
import shutil
import signal
import subprocess
import time

import pytest

from conftest import run
from test_campaign import assert_same_datasets
from test_fuzz import CRASH_SIGNS

STRACE = shutil.which("strace")
needs_strace = pytest.mark.skipif(STRACE is None, reason="strace is not installed")
FSYNC = {"x86_64": 74, "aarch64": 82}.get(platform.machine())

# 12 cases of rk4, every field stored
CAMPAIGN = """&geometry a = 1.0, b = 0.4, c = 0.2 /
&ball radius = 0.2, weight = 2620.0 /
&initial x = 0.0, y = 0.0, omega = -2.0, 2.0, 20.0 /
&integration method = 'rk4', dt = 1.0e-3, t_end = 0.3 /
&output file = 'out.h5', interval = 0.01 /
&sweep name = 'omega_z', values = 5, 10, 20, 40, 80, 90, 100, 110, 120, 130, 140, 150 /
"""


def strace(args, cwd, inject=None, trace=None, calls="close"):
    command = [STRACE, "-f", "-o", str(trace or "/dev/null"), "-e", f"trace={calls}"]
    if inject:
        command += ["-e", f"inject={inject}"]
    return subprocess.run(command + [str(a) for a in args], cwd=cwd, capture_output=True, text=True, timeout=120)


def ordinals_after(trace, calls, mark):
    """The ordinals (strace's when=, counted per call name) of the calls
    named in `calls` made after the first line of the trace matching mark."""
    counts = {name: 0 for name in calls}
    found = {name: [] for name in calls}
    started = False
    for line in trace.read_text().splitlines():
        if re.search(mark, line):
            started = True
        match = re.match(r"\d+\s+(\w+)\(", line)
        if match and match.group(1) in counts:
            counts[match.group(1)] += 1
            if started:
                found[match.group(1)].append(counts[match.group(1)])
    return found


def no_noise(result, detail):
    assert result.returncode >= 0, detail
    assert not any(sign in result.stderr for sign in CRASH_SIGNS), detail
    # HDF5's exit handler, when an object was left open
    assert "HDF5:" not in result.stderr and "infinite loop" not in result.stderr, detail


def leftovers(folder, name="out.h5"):
    return sorted(p.name for p in folder.iterdir() if p.name.startswith(name + "."))


@pytest.fixture()
def campaign(ellroll, tmp_path):
    (tmp_path / "camp.nml").write_text(CAMPAIGN)
    result = run(ellroll, "run", "camp.nml", "-o", "whole.h5", "--threads", "1", cwd=tmp_path)
    assert result.returncode == 0, result.stderr
    return tmp_path, result.stdout


@needs_strace
@pytest.mark.parametrize("call", ["close", "flock"])
def test_a_read_error_while_the_summary_is_printed_is_exit_3(ellroll, campaign, call):
    """EIO at each close or flock after the finished file is moved into
    place (the summary and the final line read it back): the output is
    complete and equal to an undisturbed run's; where the summary is not
    on standard output the run exits 3 saying so, and HDF5 prints nothing
    at exit (no object left open)."""
    folder, _ = campaign
    args = [ellroll, "run", "camp.nml", "--threads", "1"]
    trace = folder / "trace.txt"
    undisturbed = strace(args, folder, trace=trace, calls=f"{call},rename,renameat2")
    assert undisturbed.returncode == 0, undisturbed.stderr
    summary = undisturbed.stdout
    points = ordinals_after(trace, [call], r'rename(at2)?\(.*"out\.h5"')[call]
    assert points, trace.read_text()[-2000:]
    (folder / "out.h5").unlink()
    exit_3 = 0
    for n in points:
        result = strace(args, folder, inject=f"{call}:error=EIO:when={n}", calls=call)
        detail = f"EIO at {call} #{n}: rc {result.returncode}\n{result.stdout}\n{result.stderr}"
        no_noise(result, detail)
        assert_same_datasets(folder / "whole.h5", folder / "out.h5")
        assert leftovers(folder) == [], detail
        # (the table's times differ from run to run: its first line and last figure tell it)
        if result.stdout.splitlines()[:1] != summary.splitlines()[:1] or \
                summary.splitlines()[-1].split()[0] not in result.stdout:
            assert result.returncode == 3, detail
            assert "out.h5: complete and in place, but its summary cannot be printed" in result.stderr, detail
            assert "Input/output error" in result.stderr and "'ellroll summary out.h5'" in result.stderr, detail
            exit_3 += 1
        else:
            assert result.returncode in (0, 3), detail
        (folder / "out.h5").unlink()
    assert exit_3 > 0, f"no {call} among {points} kept the summary from standard output"


def make_shards(ellroll, folder, n=2):
    for i in range(n):
        result = run(ellroll, "run", "camp.nml", "-q", "--shard", f"{i}/{n}", "-o", f"s{i}.h5", cwd=folder)
        assert result.returncode == 0, result.stderr


@needs_strace
def test_a_merge_that_fails_late_leaves_no_work_file(ellroll, campaign):
    """ENOSPC or EIO (in turn) at each fsync, rename and close after the merge
    made its work file, and at each of a seeded sample of its writes: exit 3
    with the system's reason and nothing left beside the output (no
    out.h5.partial, no lock), or exit 0 with the file a single run writes."""
    folder, _ = campaign
    make_shards(ellroll, folder)
    args = [ellroll, "merge", "out.h5", "s0.h5", "s1.h5"]
    trace = folder / "trace.txt"
    calls = ["fsync", "rename", "renameat2", "close", "pwrite64", "pwritev"]
    undisturbed = strace(args, folder, trace=trace, calls=",".join(calls + ["openat"]))
    assert undisturbed.returncode == 0, undisturbed.stderr
    found = ordinals_after(trace, calls, r'openat\(.*"out\.h5\.partial"')
    rng = random.Random(20261127)
    points = [(name, n) for name in ["fsync", "rename", "renameat2", "close"] for n in found[name]]
    points += [(name, n) for name in ["pwrite64", "pwritev"] for n in rng.sample(found[name], min(4, len(found[name])))]
    assert any(name == "fsync" for name, _ in points), found
    (folder / "out.h5").unlink()
    failed = 0
    for k, (name, n) in enumerate(points):
        fault = ["ENOSPC", "EIO"][k % 2]
        result = strace(args, folder, inject=f"{name}:error={fault}:when={n}", calls=name)
        detail = f"{fault} at {name} #{n}: rc {result.returncode}\n{result.stderr}"
        no_noise(result, detail)
        assert result.returncode in (0, 3), detail
        assert leftovers(folder) == [], detail
        if result.returncode == 3:
            failed += 1
            reason = "No space left on device" if fault == "ENOSPC" else "Input/output error"
            assert reason in result.stderr, detail
        if (folder / "out.h5").exists():
            assert_same_datasets(folder / "whole.h5", folder / "out.h5")
            (folder / "out.h5").unlink()
    assert failed > 0


@needs_strace
@pytest.mark.parametrize("name, number", [("SIGTERM", 15), ("SIGINT", 2)])
def test_a_stopped_merge_says_so_and_leaves_nothing(ellroll, campaign, name, number):
    """The signal delivered at each of a seeded sample of the merge's writes
    (and at its first): exit 128 + signal with `merge interrupted by SIG...;
    run it again` and no work file or lock left, or (the signal after the
    last case) exit 0 with the whole file; the merge run again gives it."""
    folder, _ = campaign
    make_shards(ellroll, folder)
    args = [ellroll, "merge", "out.h5", "s0.h5", "s1.h5"]
    trace = folder / "trace.txt"
    undisturbed = strace(args, folder, trace=trace, calls="pwritev,pwrite64,openat")
    assert undisturbed.returncode == 0, undisturbed.stderr
    (folder / "out.h5").unlink()
    found = ordinals_after(trace, ["pwrite64"], r'openat\(.*"out\.h5\.partial"')["pwrite64"]
    rng = random.Random(20261127 + number)
    stopped = 0
    for n in sorted({found[0], *rng.sample(found, min(5, len(found)))}):
        result = strace(args, folder, inject=f"pwrite64:signal={name}:when={n}", calls="pwrite64")
        detail = f"{name} at pwrite64 #{n}: rc {result.returncode}\n{result.stderr}"
        no_noise(result, detail)
        assert leftovers(folder) == [], detail
        if result.returncode == 128 + number:
            stopped += 1
            assert f"ellroll: merge interrupted by {name}; run it again" in result.stderr, detail
            assert not (folder / "out.h5").exists(), detail
            again = run(ellroll, "merge", "out.h5", "s0.h5", "s1.h5", cwd=folder)
            assert again.returncode == 0, again.stderr
        else:
            assert result.returncode == 0, detail
        assert_same_datasets(folder / "whole.h5", folder / "out.h5")
        (folder / "out.h5").unlink()
    assert stopped > 0


def test_a_missing_shard_is_named_with_its_option(ellroll, campaign):
    folder, _ = campaign
    make_shards(ellroll, folder, 3)
    result = run(ellroll, "merge", "m.h5", "s1.h5", "s2.h5", cwd=folder)
    assert result.returncode == 2
    assert "ellroll: error: missing shard 0/3 (given: 1/3, 2/3): run it with --shard 0/3 -o FILE (a file of its own) and merge again" in result.stderr
    result = run(ellroll, "merge", "m.h5", "s2.h5", cwd=folder)
    assert result.returncode == 2
    assert "missing shards 0/3, 1/3 (given: 2/3): run them with --shard 0/3 -o FILE, --shard 1/3 -o FILE (each a file of its own) and merge again" in result.stderr
    assert leftovers(folder, "m.h5") == [] and not (folder / "m.h5").exists()


@needs_strace
def test_a_killed_runs_work_file_given_as_a_shard_is_bad_input(ellroll, campaign):
    """As a damaged shard: exit 2 (docs/usage.md: bad input), nothing written."""
    folder, _ = campaign
    make_shards(ellroll, folder)
    killed = strace([ellroll, "run", "camp.nml", "-q", "--threads", "1", "--shard", "0/2", "-o", "k.h5"], folder,
                    inject="pwritev:signal=SIGKILL:when=3", calls="pwritev")
    assert killed.returncode != 0 and (folder / "k.h5.partial").exists(), killed.stderr
    result = run(ellroll, "merge", "m.h5", "k.h5.partial", "s1.h5", cwd=folder)
    assert result.returncode == 2, result.stderr
    assert "k.h5.partial: an unfinished run's work file" in result.stderr
    assert not (folder / "m.h5").exists() and leftovers(folder, "m.h5") == []


def test_a_thread_count_beyond_any_integer_is_too_large(ellroll, campaign):
    folder, _ = campaign
    result = run(ellroll, "run", "camp.nml", "--threads", "99999999999", cwd=folder)
    assert result.returncode == 2
    assert "--threads 99999999999: too large (at most 2147483647" in result.stderr
    assert "positive" not in result.stderr
    result = run(ellroll, "run", "camp.nml", "--threads", "0", cwd=folder)
    assert result.returncode == 2 and "--threads needs a positive number, not 0" in result.stderr


@needs_strace
@pytest.mark.parametrize("moment, replaced", [("commit", False), ("commit", True), ("running", False)])
def test_an_output_folder_moved_away_is_named_with_the_resume_hint(ellroll, campaign, replaced, moment):
    """The output's folder moved while the run writes (held at its first
    fsync, of the finished file: it syncs by its descriptor, then the move
    into place fails; or held at a write while it runs, its lock going with
    the folder), and with `replaced` another made at its name: exit 3
    naming the folder as gone (not the lock as removed by hand), or the
    file as no longer in its folder (held at the commit; while it runs, a
    new folder at the name cannot be told from a lock removed by hand), and
    the --resume that finishes the run where the folder went, which gives
    the whole file."""
    folder, _ = campaign
    (folder / "od").mkdir()
    held = "fsync:delay_enter=1500000:when=1" if moment == "commit" else "pwritev:delay_enter=1500000:when=3"
    command = [STRACE, "-f", "-o", "/dev/null", "-e", f"trace={held.split(':')[0]}", "-e", f"inject={held}",
               str(ellroll), "run", "camp.nml", "-q", "--threads", "1", "-o", "od/x.h5"]
    process = subprocess.Popen(command, cwd=folder, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    deadline = time.monotonic() + 30
    while not (folder / "od" / "x.h5.partial").exists() and time.monotonic() < deadline:
        time.sleep(0.01)
    time.sleep(0.2)
    (folder / "od").rename(folder / "od2")
    if replaced:
        (folder / "od").mkdir()
    _, stderr = process.communicate(timeout=120)
    assert process.returncode == 3 and "lock was removed" not in stderr, stderr
    if replaced:
        assert "od/x.h5.partial into place: it is no longer in its folder od (the folder moved and another made " \
            "at its name" in stderr, stderr
        assert "x.h5.journal, in that folder, keeps the cases finished so far" in stderr
        assert not any((folder / "od").iterdir())
    else:
        assert "od/x.h5.partial into place: its folder od is gone (moved or removed while ellroll wrote in it)" \
            in stderr, stderr
    assert "--resume" in stderr and "x.h5.journal" in stderr
    again = run(ellroll, "run", "camp.nml", "-q", "--threads", "1", "-o", "od2/x.h5", "--resume", cwd=folder)
    assert again.returncode == 0, again.stderr
    assert_same_datasets(folder / "whole.h5", folder / "od2" / "x.h5")


def held_in(tracer, call):
    """The traced child of tracer one of whose threads is in system call
    number call, or None."""
    try:
        for pid in open(f"/proc/{tracer}/task/{tracer}/children").read().split():
            for task in pathlib.Path(f"/proc/{pid}/task").iterdir():
                if (task / "syscall").read_text().split()[:1] == [str(call)]:
                    return int(pid)
    except OSError:                 # a thread or the process ended while read
        pass
    return None


@needs_strace
@pytest.mark.skipif(FSYNC is None, reason="fsync's system call number is known for x86_64 and aarch64")
def test_a_signal_while_the_finished_file_moves_into_place_changes_nothing(ellroll, campaign):
    """usage.md: a SIGTERM after the last case, while the finished file is
    synced (held there 1.5 s) and moved into place, changes nothing: exit
    0, the summary printed, the file an undisturbed run's, no work file."""
    folder, summary = campaign
    command = [STRACE, "-f", "-o", "/dev/null", "-e", "trace=fsync", "-e", "inject=fsync:delay_enter=1500000:when=1",
               str(ellroll), "run", "camp.nml", "-q", "--threads", "1", "-o", "x.h5"]
    process = subprocess.Popen(command, cwd=folder, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    deadline = time.monotonic() + 60
    child = None
    while child is None and time.monotonic() < deadline:
        time.sleep(0.01)
        child = held_in(process.pid, FSYNC)
    assert child is not None
    os.kill(child, signal.SIGTERM)
    stdout, stderr = process.communicate(timeout=120)
    assert process.returncode == 0 and "interrupted" not in stderr, stderr
    assert stdout.splitlines()[0] == summary.splitlines()[0].replace("whole.h5", "x.h5")
    assert_same_datasets(folder / "whole.h5", folder / "x.h5")
    assert sorted(p.name for p in folder.glob("x.h5*")) == ["x.h5"]


def test_a_records_errors_name_it_once(tmp_path):
    """A Record of the Python API with a value that is not finite: the
    message names the Record and its row once."""
    import os
    import sys
    from conftest import ROOT
    library = os.environ.get("ELLROLL_LIB", str(ROOT / "build" / "libellroll.so"))
    if not os.path.exists(library):
        pytest.skip(f"{library} not built")
    script = ("import sys, math; sys.path.insert(0, sys.argv[1]); import ellroll\n"
              "r = ellroll.Record([0, 0.01, 0.02], [[math.nan, 0], [0, 0], [0, 0]], name='n')\n"
              "try:\n"
              "    ellroll.run({'geometry': {'a': 1.0, 'b': 0.4, 'c': 0.2}, 'ball': {'radius': 0.2, 'weight': 2620.0},"
              " 'initial': {'x': 0.1, 'omega': [0, 0, 1]}, 'integration': {'method': 'rk4', 'dt': 1e-3, 't_end': 0.01},"
              " 'record': {'name': 'n', 'record_file': r}})\n"
              "except ellroll.InputError as error:\n"
              "    print(error)\n")
    result = subprocess.run([sys.executable, "-c", script, str(ROOT / "post")], capture_output=True, text=True,
                            env=dict(os.environ, ELLROLL_LIB=library), timeout=120)
    assert "record_file = Record 'n' row 0: value 2 is not finite: nan" in result.stdout, result.stdout + result.stderr
    assert result.stdout.count("Record 'n'") == 1, result.stdout
