"""Races on the names of an output's files, by someone who can write its
folder: no command writes, truncates or replaces a file it did not make.

1. A symbolic link to a victim put at the work file's name (OUT.partial of
   run, run --overwrite and merge; OUT.partial.new of run --resume) while
   the program is stopped at each open of that name by HDF5 (strace delays
   that openat; the link goes in while the program waits there): the victim
   keeps its bytes, whatever the program answers.
2. Output names that end in a suffix of ellroll's own work files are
   refused (exit 2, naming the option or variable and the value); and a
   file made at the output's name while a run finishes (its fsync delayed)
   is never replaced: the run ends with exit 3, the file keeps its bytes,
   and the finished cases stay in the journal.
3. In a folder with the sticky bit, --overwrite (and merge --overwrite) of
   another user's output is refused before any case runs (exit 3, naming
   the file and the sticky bit), leaving no work file (needs root, setpriv)."""
import os
import pathlib
import re
import shutil
import subprocess
import tempfile
import threading
import time

import pytest

from conftest import run

STRACE = shutil.which("strace")
SETPRIV = shutil.which("setpriv")
VICTIM = b"somebody's data, not ellroll's\n"
# 4 cases of a second or so each on one thread: the last one's trajectory
# lies in place, the others' too (pwritev)
CAMPAIGN = """&geometry a = 1.0, b = 0.4, c = 0.2 /
&ball radius = 0.2, weight = 2620.0 /
&initial x = 0.0, y = 0.0, omega = -2.0, 2.0, 20.0 /
&integration method = 'rk4', dt = 1.0e-3, t_end = 0.5 /
&output file = 'out.h5', interval = 0.05 /
&sweep name = 'omega_z', values = 5, 10, 20, 40 /
"""
DELAY_US = 1_500_000

needs_strace = pytest.mark.skipif(STRACE is None, reason="strace is not installed")


def strace(args, cwd, *options):
    return subprocess.Popen([STRACE, "-f", "-o", "trace.txt", *options, *map(str, args)], cwd=cwd,
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)


def prepared(ellroll, tmp_path, entry):
    """A folder for entry point `entry`, the command, and the work file's name."""
    folder = tmp_path / entry
    folder.mkdir()
    (folder / "camp.nml").write_text(CAMPAIGN)
    if entry == "overwrite":
        assert run(ellroll, "run", "camp.nml", "-q", cwd=folder).returncode == 0
        return folder, ["run", "camp.nml", "-q", "--threads", "1", "--overwrite"], "out.h5.partial"
    if entry == "resume":
        killed = subprocess.run([STRACE, "-f", "-o", "/dev/null", "-e", "inject=pwritev:signal=SIGKILL:when=3",
                                 "--", *map(str, [ellroll, "run", "camp.nml", "-q", "--threads", "1"])], cwd=folder,
                                capture_output=True, text=True, timeout=120)
        assert killed.returncode != 0 and (folder / "out.h5.journal").exists(), killed.stderr
        return folder, ["run", "camp.nml", "-q", "--threads", "1", "--resume"], "out.h5.partial.new"
    if entry == "merge":
        for shard in ("0/2", "1/2"):
            made = run(ellroll, "run", "camp.nml", "-q", "--shard", shard, "-o", f"s{shard[0]}.h5", cwd=folder)
            assert made.returncode == 0, made.stderr
        return folder, ["merge", "out.h5", "s0.h5", "s1.h5"], "out.h5.partial"
    return folder, ["run", "camp.nml", "-q", "--threads", "1"], "out.h5.partial"


def opens_by_name(trace, name):
    """Ordinals (strace's when=, from 1) of the openat calls of `name`
    without O_NOFOLLOW: HDF5's opens of it."""
    ordinals, n = [], 0
    for line in trace.read_text().splitlines():
        if not re.match(r"\d+\s+openat\(", line):
            continue
        n += 1
        if f'"{name}"' in line and "O_NOFOLLOW" not in line:
            ordinals.append(n)
    return ordinals


def stopped_at(pid, number):
    """Whether a thread of process pid is stopped (by its tracer) at system
    call `number` (x86-64: 257 openat, 74 fsync)."""
    try:
        tasks = list(pathlib.Path(f"/proc/{pid}/task").iterdir())
    except OSError:                   # it has ended
        return False
    for task in tasks:
        try:
            state = (task / "stat").read_text().rsplit(")", 1)[1].split()[0]
            call = (task / "syscall").read_text().split()[0]
        except (OSError, IndexError):
            continue
        if state in "tT" and call == str(number):
            return True
    return False


def when_stopped(process, number, action):
    """Once the traced program has been stopped at system call `number`
    for 0.2 s (a delayed call: others take microseconds), do action."""
    pid = tracee(process.pid)
    since = None
    while pid and process.poll() is None:
        if stopped_at(pid, number):
            since = since or time.monotonic()
            if time.monotonic() - since > 0.2:
                action()
                return True
        else:
            since = None
        time.sleep(0.01)
    return False


def tracee(strace_pid):
    """The traced program's pid: strace's child that runs ellroll (strace
    forks short-lived children of its own first, to probe ptrace)."""
    children = pathlib.Path(f"/proc/{strace_pid}/task/{strace_pid}/children")
    for _ in range(2000):
        try:
            for child in children.read_text().split():
                if "ellroll" in pathlib.Path(f"/proc/{child}/cmdline").read_text() and \
                        pathlib.Path(f"/proc/{child}/exe").resolve().name == "ellroll":
                    return int(child)
        except OSError:
            pass
        time.sleep(0.002)
    return None


def plant_link(folder, name):
    """A link to victim.txt at name, over whatever is there."""
    (folder / "link.tmp").symlink_to("victim.txt")
    os.replace(folder / "link.tmp", folder / name)


x86_64 = pytest.mark.skipif(os.uname().machine != "x86_64", reason="system call numbers of x86-64")


@needs_strace
@x86_64
@pytest.mark.parametrize("entry", ["run", "overwrite", "resume", "merge"])
def test_a_link_put_at_the_work_file_during_its_open_is_never_written_through(ellroll, tmp_path, entry):
    base, args, name = prepared(ellroll, tmp_path, entry)
    counting = tmp_path / "counting"
    shutil.copytree(base, counting)
    undisturbed = strace([ellroll, *args], counting, "-e", "trace=openat")
    undisturbed.communicate(timeout=120)
    assert undisturbed.returncode == 0
    ordinals = opens_by_name(counting / "trace.txt", name)
    assert ordinals, f"no open of {name} found"
    for n in ordinals:
        folder = tmp_path / f"race{n}"
        shutil.copytree(base, folder)
        (folder / "victim.txt").write_bytes(VICTIM)
        process = strace([ellroll, *args], folder, "-e", "trace=openat",
                         "-e", f"inject=openat:delay_enter={DELAY_US}:when={n}")
        planted = []
        watcher = threading.Thread(target=lambda: planted.append(
            when_stopped(process, 257, lambda: plant_link(folder, name))))
        watcher.start()
        _, stderr = process.communicate(timeout=120)
        watcher.join()
        detail = f"{entry}: link at {name} during openat #{n}: rc {process.returncode}\n{stderr}"
        assert planted == [True], detail
        assert (folder / "victim.txt").read_bytes() == VICTIM, detail
        assert process.returncode == 3, detail
        assert "Traceback" not in stderr and "HDF5-DIAG" not in stderr, detail
        shutil.rmtree(folder)


@pytest.mark.parametrize("suffix", [".partial", ".partial.new", ".journal", ".lock"])
@pytest.mark.parametrize("how", ["option", "namelist", "merge"])
def test_an_output_named_like_a_work_file_is_refused(ellroll, tmp_path, suffix, how):
    (tmp_path / "camp.nml").write_text(CAMPAIGN)
    name = "x.h5" + suffix
    if how == "option":
        result = run(ellroll, "run", "camp.nml", "-q", "-o", name, cwd=tmp_path)
        expected = f"-o {name}: ends in {suffix}"
    elif how == "namelist":
        (tmp_path / "named.nml").write_text(CAMPAIGN.replace("'out.h5'", f"'{name}'"))
        result = run(ellroll, "run", "named.nml", "-q", cwd=tmp_path)
        expected = f"&output: file = '{name}': ends in {suffix}"
    else:
        for shard in ("0/2", "1/2"):
            assert run(ellroll, "run", "camp.nml", "-q", "--shard", shard, "-o", f"s{shard[0]}.h5",
                       cwd=tmp_path).returncode == 0
        result = run(ellroll, "merge", name, "s0.h5", "s1.h5", cwd=tmp_path)
        expected = f"{name}: ends in {suffix}"
    assert result.returncode == 2, result.stderr
    assert expected in result.stderr, result.stderr
    assert not any(p.name.startswith("x.h5") for p in tmp_path.iterdir())


def finishing_sync(trace):
    """The ordinal (strace's when=) of the fsync of the finished file, the
    last fsync before the output's name is given to it."""
    n, last = 0, None
    for line in trace.read_text().splitlines():
        if re.match(r"\d+\s+fsync\(", line):
            n += 1
            last = n
        if re.match(r'\d+\s+rename(at2)?\(.*"out\.h5"', line):
            return last
    return None


@needs_strace
@x86_64
@pytest.mark.parametrize("entry", ["run", "resume", "merge"])
def test_a_file_made_at_the_output_name_as_the_run_finishes_is_never_replaced(ellroll, tmp_path, entry):
    """The fsync of the finished file delayed 1.5 s (a large file on a
    cluster file system); another process makes a file at the output's name
    meanwhile (as another run whose work file it is would)."""
    base, args, _ = prepared(ellroll, tmp_path, entry)
    counting = tmp_path / "counting"
    shutil.copytree(base, counting)
    undisturbed = strace([ellroll, *args], counting, "-e", "trace=fsync,rename,renameat2,link")
    undisturbed.communicate(timeout=120)
    assert undisturbed.returncode == 0
    n = finishing_sync(counting / "trace.txt")
    assert n, (counting / "trace.txt").read_text()
    folder = tmp_path / "race"
    shutil.copytree(base, folder)
    process = strace([ellroll, *args], folder, "-e", "trace=fsync", "-e",
                     f"inject=fsync:delay_enter={DELAY_US}:when={n}")
    made = []
    watcher = threading.Thread(target=lambda: made.append(
        when_stopped(process, 74, lambda: (folder / "out.h5").write_bytes(VICTIM))))
    watcher.start()
    _, stderr = process.communicate(timeout=120)
    watcher.join()
    assert made == [True], stderr
    assert (folder / "out.h5").read_bytes() == VICTIM, stderr
    assert process.returncode == 3, stderr
    assert "out.h5: a file was made at its name while this run wrote it; it stays, and out.h5.partial is not " \
           "moved into place" in stderr, stderr
    if entry != "merge":          # the finished cases stay in the journal, for a resume
        assert (folder / "out.h5.journal").exists() and (folder / "out.h5.partial").exists()


@pytest.mark.skipif(os.geteuid() != 0 or SETPRIV is None, reason="needs root and setpriv")
@pytest.mark.parametrize("entry", ["overwrite", "merge"])
def test_overwrite_of_another_users_output_in_a_sticky_folder_is_refused_before_running(ellroll, tmp_path, entry):
    # (a folder every user reaches: pytest's own are root's alone)
    folder = pathlib.Path(tempfile.mkdtemp(prefix="ellroll-sticky-"))
    folder.chmod(0o1777)
    try:
        sticky_overwrite(ellroll, folder, entry)
    finally:
        shutil.rmtree(folder)


def sticky_overwrite(ellroll, folder, entry):
    (folder / "camp.nml").write_text(CAMPAIGN)
    (folder / "camp.nml").chmod(0o644)
    for shard in ("0/2", "1/2"):
        assert run(ellroll, "run", "camp.nml", "-q", "--shard", shard, "-o", f"s{shard[0]}.h5", cwd=folder).returncode == 0
    assert run(ellroll, "run", "camp.nml", "-q", cwd=folder).returncode == 0       # root's output
    before = (folder / "out.h5").read_bytes()
    command = ["run", "camp.nml", "-q", "--overwrite"] if entry == "overwrite" else \
        ["merge", "out.h5", "s0.h5", "s1.h5", "--overwrite"]
    result = subprocess.run([SETPRIV, "--reuid=65534", "--regid=65534", "--clear-groups", str(ellroll), *command],
                            cwd=folder, capture_output=True, text=True, timeout=120)
    assert result.returncode == 3, result.stderr
    assert "out.h5: cannot be replaced by this user: it belongs to user id 0" in result.stderr, result.stderr
    assert "sticky bit" in result.stderr, result.stderr
    assert (folder / "out.h5").read_bytes() == before
    assert sorted(p.name for p in folder.iterdir() if p.name.startswith("out.h5")) == ["out.h5"]
