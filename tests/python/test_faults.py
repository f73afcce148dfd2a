"""Every write the program makes is checked: a failure injected into each
write-type system call of a run, a resume and a merge (strace -e inject=...)
ends in exit 3 with a message naming the file and the system's reason, or in
exit 0 with the file an undisturbed run writes; the command repeated with the
fault gone (a --resume, or merge --overwrite) then writes that file. A kill
(SIGKILL) at each such call: the resume that follows writes it too. Never a
crash, never exit 0 over a wrong file, never a work file left beside a
finished output.

The calls are counted in an undisturbed run (those of the dynamic loader,
before the program opens its input, are left out). CI walks a seeded sample
of the calls of every kind, the first and last of each among them;
ELLROLL_TEST_FULL=1 walks every call with EIO, ENOSPC and SIGKILL."""
import os
import pathlib
import random
import re
import shutil
import subprocess
import sys

import pytest

from conftest import FULL
from test_campaign import assert_same_datasets
from test_fuzz import CRASH_SIGNS
from test_output_safety import printed_folder

SAMPLE_PER_KIND = 3          # in CI: the first, the last and this many more of each kind
WRITE_CALLS = ["pwrite64", "pwritev", "write", "fsync", "ftruncate", "rename", "renameat2", "unlink", "close"]
STRACE = shutil.which("strace")

# 16 cases of rolling resistance (one at a time: blocks of 4 on one thread),
# every field stored
CAMPAIGN = """&geometry a = 1.0, b = 0.4, c = 0.2 /
&ball radius = 0.2, weight = 2620.0, rolling_resistance = 1.0e-4 /
&initial x = 0.1, y = 0.0, omega = -2.0, 2.0, 20.0 /
&integration method = 'rk4', dt = 1.0e-3, t_end = 0.05 /
&output file = 'out.h5', interval = 0.01 /
&sweep name = 'omega_z', values = 5, 10, 20, 40 /
&sweep name = 'x', values = 0.0, 0.05, 0.1, 0.15 /
"""

pytestmark = pytest.mark.skipif(STRACE is None, reason="strace is not installed")


def strace(args, cwd, inject=None, trace_file=None, timeout=120):
    command = [STRACE, "-f", "-o", str(trace_file or os.devnull)]
    if inject:
        command += ["-e", f"inject={inject}"]
    else:
        command += ["-e", "trace=" + ",".join(WRITE_CALLS + ["openat"])]
    return subprocess.run(command + [str(a) for a in args], cwd=cwd, capture_output=True, text=True,
                          timeout=timeout)


def call_ordinals(trace, first_file):
    """For each write-type system call, the ordinals (from 1, as strace's
    when= counts them) of the calls made after the program opened
    first_file."""
    started = False
    counts = {name: 0 for name in WRITE_CALLS}
    ordinals = {name: [] for name in WRITE_CALLS}
    for line in trace.read_text().splitlines():
        match = re.match(r"\d+\s+(\w+)\(", line)
        if not match:
            continue
        name = match.group(1)
        if name == "openat" and f'"{first_file}"' in line:
            started = True
        if name in counts:
            counts[name] += 1
            if started:
                ordinals[name].append(counts[name])
    return ordinals


def chosen(ordinals, seed):
    rng = random.Random(seed)
    points = []
    for name, found in sorted(ordinals.items()):
        if FULL or len(found) <= SAMPLE_PER_KIND + 2:
            picked = found
        else:
            picked = sorted({found[0], found[-1], *rng.sample(found[1:-1], SAMPLE_PER_KIND)})
        points += [(name, n) for n in picked]
    return points


def faults(points, seed):
    """(call, ordinal, fault) to inject: in CI each point gets one of EIO,
    ENOSPC and SIGKILL in turn; with ELLROLL_TEST_FULL all three."""
    kinds = ["error=EIO", "error=ENOSPC", "signal=SIGKILL"]
    if FULL:
        return [(name, n, kind) for name, n in points for kind in kinds]
    offset = random.Random(seed).randrange(3)
    return [(name, n, kinds[(k + offset) % 3]) for k, (name, n) in enumerate(points)]


def no_crash(result, detail):
    assert result.returncode >= 0 or result.returncode == -9, detail
    assert not any(sign in result.stderr for sign in CRASH_SIGNS), detail


def work_files(folder):
    return sorted(p.name for p in folder.iterdir() if re.match(r"out\.h5\.", p.name))


def scenario(ellroll, tmp_path, name):
    """A folder with the campaign and what the command to test needs, the
    command, the command that finishes the job once the fault is gone, the
    file both must write, and the file whose opening marks the start."""
    base = tmp_path / "base"
    base.mkdir()
    (base / "camp.nml").write_text(CAMPAIGN)
    whole = subprocess.run([str(ellroll), "run", "camp.nml", "-q", "-o", "whole.h5"], cwd=base, capture_output=True,
                           text=True)
    assert whole.returncode == 0, whole.stderr
    if name == "run":
        return base, ["run", "camp.nml", "-q", "--threads", "1"], ["run", "camp.nml", "-q", "--resume"], \
            "whole.h5", "camp.nml"
    if name == "resume":
        # a run killed after two of its four blocks were journaled: at its
        # fifth positioned write of several pieces (trajectories, journal, twice)
        killed = strace([ellroll, "run", "camp.nml", "-q", "--threads", "1"], base,
                        inject="pwritev:signal=SIGKILL:when=5")
        assert killed.returncode != 0 and (base / "out.h5.journal").exists(), killed.stderr
        return base, ["run", "camp.nml", "-q", "--resume", "--threads", "1"], ["run", "camp.nml", "-q", "--resume"], \
            "whole.h5", "camp.nml"
    for shard in ("0/2", "1/2"):
        made = subprocess.run([str(ellroll), "run", "camp.nml", "-q", "--shard", shard, "-o",
                               f"s{shard[0]}.h5"], cwd=base, capture_output=True, text=True)
        assert made.returncode == 0, made.stderr
    return base, ["merge", "out.h5", "s0.h5", "s1.h5"], ["merge", "out.h5", "s0.h5", "s1.h5", "--overwrite"], \
        "whole.h5", "s0.h5"


@pytest.mark.parametrize("command", ["run", "resume", "merge"])
def test_a_fault_at_each_write_is_an_error_or_the_right_file(ellroll, tmp_path, command):
    base, args, finish, reference, first_file = scenario(ellroll, tmp_path, command)
    counting = tmp_path / "counting"
    shutil.copytree(base, counting)
    trace = tmp_path / "trace.txt"
    undisturbed = strace([ellroll, *args], counting, trace_file=trace)
    assert undisturbed.returncode == 0, undisturbed.stderr
    assert_same_datasets(base / reference, counting / "out.h5")
    ordinals = call_ordinals(trace, first_file)
    assert ordinals["pwrite64"] and ordinals["pwritev"] and (ordinals["rename"] or ordinals["renameat2"]), ordinals
    seed = 20261125 + ["run", "resume", "merge"].index(command)
    outcomes = {}
    for call, n, fault in faults(chosen(ordinals, seed), seed):
        folder = tmp_path / f"{call}{n}{fault.split('=')[1]}"
        shutil.copytree(base, folder)
        result = strace([ellroll, *args], folder, inject=f"{call}:{fault}:when={n}")
        detail = f"{command}: {fault} at {call} #{n}:\n{result.stdout}\n{result.stderr}"
        no_crash(result, detail)
        if fault.startswith("signal"):
            outcome = "killed" if result.returncode == -9 else f"exit {result.returncode}"
        else:
            assert result.returncode in (0, 3), detail
            outcome = f"exit {result.returncode}"
            if result.returncode == 3:
                # (or the standard output: its close, checked at the end, is one of the calls)
                assert re.search(r"ellroll: error: ((out|s0|s1)\.h5[.\w]*|cannot write the standard output): ",
                                 result.stderr), detail
                reason = "Input/output error" if fault == "error=EIO" else "No space left on device"
                assert reason in result.stderr, detail
                if command == "run" and (folder / "out.h5.journal").exists() and not (folder / "out.h5").exists():
                    # every write error that leaves the run's journal says so, also one while closing the file
                    assert "out.h5.journal keeps the cases finished so far; fix the cause and run again with " \
                           "--resume" in result.stderr, detail
            else:
                assert_same_datasets(base / reference, folder / "out.h5")
                assert work_files(folder) == [], detail
        outcomes[outcome] = outcomes.get(outcome, 0) + 1
        finished = subprocess.run([str(ellroll), *finish], cwd=folder, capture_output=True, text=True, timeout=120)
        detail += f"\nthen {' '.join(finish)}:\n{finished.stderr}"
        assert finished.returncode == 0, detail
        assert_same_datasets(base / reference, folder / "out.h5")
        assert work_files(folder) == [], detail
        shutil.rmtree(folder)
    print(f"{command}: {sum(len(v) for v in ordinals.values())} write-type calls "
          f"({', '.join(f'{k} {len(v)}' for k, v in ordinals.items() if v)}); injected: {outcomes}")


@pytest.fixture(scope="module")
def printed(ellroll, tmp_path_factory):
    return printed_folder(ellroll, tmp_path_factory)


@pytest.mark.parametrize("command", [["inputs"], ["summary", "w.h5", "--format", "csv"]], ids=" ".join)
def test_an_io_error_on_standard_output_is_exit_3(ellroll, printed, command):
    """write(2) on descriptor 1 failing with EIO (the first such write after
    the program starts: the dynamic loader writes nothing) is exit 3 too."""
    result = subprocess.run([STRACE, "-f", "-o", "/dev/null", "-e", "trace=write", "-e", "inject=write:error=EIO:when=1",
                             str(ellroll), *command], cwd=printed, capture_output=True, text=True, timeout=120)
    no_crash(result, command)
    assert result.returncode == 3, result.stderr
    assert "cannot write the standard output: Input/output error" in result.stderr


def read_ordinals(ellroll, folder, args, path):
    """The pread64 calls (ordinals, strace's when=) on `path` in an
    undisturbed run; of the output, those before the work file is made
    (those after read the file the command writes)."""
    trace = folder / "reads.txt"
    result = subprocess.run([STRACE, "-f", "-P", path, "-P", "out.h5.partial", "-P", "out.h5.partial.new", "-e",
                             "trace=pread64,openat", "-o",
                             str(trace), str(ellroll), *args], cwd=folder, capture_output=True, text=True, timeout=120)
    assert result.returncode == 0, result.stderr
    n, ordinals, mine = 0, [], set()
    for line in trace.read_text().splitlines():
        opened = re.search(r'openat\(AT_FDCWD, "([^"]+)", (\S+).*= (-?\d+)', line)
        if opened:
            name, flags, fd = opened.groups()
            if name in ("out.h5.partial", "out.h5.partial.new") and "O_CREAT" in flags and path == "out.h5":
                break
            (mine.add if name == path else mine.discard)(fd)
        read = re.search(r"pread64\((\d+),", line)
        if read and read.group(1) in mine:      # (strace -P counts these alone)
            n += 1
            ordinals.append(n)
    return ordinals


@pytest.mark.parametrize("command", ["overwrite", "merge", "resume", "journal", "summary"])
def test_a_read_error_is_said_as_such_not_as_a_verdict_on_the_file(ellroll, tmp_path, command):
    """EIO on a read of the existing output (--overwrite), of a shard
    (merge; seeded sample of its reads), of a killed run's lock or of its
    journal's header (--resume): exit 3, 'cannot read it:
    Input/output error', never advice to remove a file that could not be
    read or to start over, every file left as it was."""
    base = tmp_path / "base"
    base.mkdir()
    (base / "camp.nml").write_text(CAMPAIGN)
    if command in ("overwrite", "summary"):
        assert subprocess.run([str(ellroll), "run", "camp.nml", "-q"], cwd=base).returncode == 0
        args, path = ["run", "camp.nml", "-q", "--overwrite"], "out.h5"
        if command == "summary":
            args = ["summary", "out.h5"]
    elif command == "merge":
        for shard in ("0/2", "1/2"):
            assert subprocess.run([str(ellroll), "run", "camp.nml", "-q", "--shard", shard, "-o", f"s{shard[0]}.h5"],
                                  cwd=base).returncode == 0
        args, path = ["merge", "out.h5", "s0.h5", "s1.h5"], "s1.h5"
    else:
        killed = strace([ellroll, "run", "camp.nml", "-q", "--threads", "1"], base,
                         inject="pwritev:signal=SIGKILL:when=5")
        assert killed.returncode != 0 and (base / "out.h5.journal").exists(), killed.stderr
        args, path = ["run", "camp.nml", "-q", "--resume"], "out.h5.journal"
        (base / "out.h5.lock").unlink()         # (the killed run's: the resume takes it over, then leaves none)
        if command == "resume":
            # a lock file left as a killed run on another machine's file system may leave it
            (base / "out.h5.lock").write_text("ellroll lock\nhost h, pid 1, started t: ellroll run camp.nml\n")
            path = "out.h5.lock"
    counting = tmp_path / "counting"
    shutil.copytree(base, counting)
    ordinals = read_ordinals(ellroll, counting, args, path)
    assert ordinals
    rng = random.Random(20261127)
    picked = ordinals if len(ordinals) <= 6 else sorted({ordinals[0], ordinals[-1], *rng.sample(ordinals, 4)})
    if command == "journal":
        # the resume's own reads of its magic, header and note (the 3 before only look
        # at the file: a failed one judges nothing; a record not read reruns its case)
        picked = ordinals[3:6]
    before = {p.name: p.read_bytes() for p in base.iterdir()}
    for n in picked:
        folder = tmp_path / f"eio{n}"
        shutil.copytree(base, folder)
        result = subprocess.run([STRACE, "-f", "-o", "/dev/null", "-P", path, "-e", "trace=pread64", "-e",
                                 f"inject=pread64:error=EIO:when={n}", str(ellroll), *args], cwd=folder,
                                capture_output=True, text=True, timeout=120)
        detail = f"{command}: EIO at read #{n} of {path}:\n{result.stderr}"
        no_crash(result, detail)
        assert result.returncode == 3, detail
        assert re.search(f"ellroll: error: {re.escape(path)}: (cannot read it|cannot open the HDF5 file|cannot take the "
                         "output's lock): "
                         "Input/output error", result.stderr), detail
        assert "remove it" not in result.stderr and "not an ellroll" not in result.stderr, detail
        assert "--overwrite" not in result.stderr, detail
        assert {p.name: p.read_bytes() for p in folder.iterdir()} == before, detail
        shutil.rmtree(folder)


def test_ellroll_plot_says_a_read_error_as_such(ellroll, tmp_path):
    """EIO at a seeded sample of ellroll-plot's reads of a good output
    (its root attributes, tables and data, in the parent and in the child
    that times the tables): 'cannot read it: Input/output error', exit 2,
    as `ellroll summary` says it: never 'not an ellroll file' nor
    'damaged' for a good file on a failing disk."""
    (tmp_path / "camp.nml").write_text(CAMPAIGN)
    assert subprocess.run([str(ellroll), "run", "camp.nml", "-q"], cwd=tmp_path).returncode == 0
    args = ["-m", "ellroll_post.cli", "summary", "out.h5"]
    trace = tmp_path / "reads.txt"
    assert subprocess.run([STRACE, "-f", "-P", "out.h5", "-e", "trace=pread64", "-o", str(trace), sys.executable,
                           *args], cwd=tmp_path, capture_output=True, timeout=120).returncode == 0
    # strace counts when= in each process (the parent and its child that times the tables): n hits the
    # n-th read of each that reads as many
    pids = [line.split()[0] for line in trace.read_text().splitlines() if "pread64(" in line]
    reads = max(pids.count(pid) for pid in set(pids))
    assert reads > 10
    rng = random.Random(20261127)
    for n in sorted({1, reads, *rng.sample(range(1, reads + 1), 6)}):
        result = subprocess.run([STRACE, "-f", "-o", "/dev/null", "-P", "out.h5", "-e", "trace=pread64", "-e",
                                 f"inject=pread64:error=EIO:when={n}", sys.executable, *args], cwd=tmp_path,
                                capture_output=True, text=True, timeout=120)
        detail = f"EIO at read #{n} of out.h5:\n{result.stderr}"
        no_crash(result, detail)
        assert result.returncode == 2, detail
        assert result.stderr.endswith("ellroll-plot: error: out.h5: cannot read it: Input/output error\n"), detail


def test_a_write_error_on_a_worker_thread_prints_no_hdf5_error_stack(ellroll, tmp_path):
    """ENOSPC at pwrite64 calls of a run on 2 threads (windows are written by
    whichever thread completes them): ellroll's own message, and none of
    HDF5's (HDF5-DIAG) on any thread."""
    (tmp_path / "camp.nml").write_text(CAMPAIGN)
    seen = set()
    for n in range(6, 60, 3):
        for p in tmp_path.glob("out.h5*"):
            p.unlink()
        result = strace([ellroll, "run", "camp.nml", "-q", "--threads", "2"], tmp_path,
                        inject=f"pwrite64:error=ENOSPC:when={n}")
        no_crash(result, result.stderr)
        assert "HDF5-DIAG" not in result.stderr, f"pwrite64 #{n}:\n{result.stderr}"
        if result.returncode == 3:
            assert "No space left on device" in result.stderr
            assert len(result.stderr.splitlines()) <= 3, result.stderr
        seen.add(result.returncode)
    assert 3 in seen
