"""A stop asked while a case runs: SIGTERM and SIGINT end the run within
milliseconds, the signal polled inside the case (a sliding ball with rolling
resistance under a scaled record, rk4 at dt 1e-5 for 60 s: steps at the
switches taken in substeps and pieces, seconds for the one case). The cases
under way are dropped and the journal says how to resume; the library
raises KeyboardInterrupt as promptly. (A fixed step's flow to a model limit
polls it too: tests/python/test_near_fit_equal_radii.py.)"""
import os
import signal
import subprocess
import sys
import threading
import time

import pytest

from conftest import ROOT

# rk4 at dt 1e-5, sliding with rolling resistance under a scaled record: 7 slip
# episodes in its first 4 s, 6 million steps (the case takes seconds).
CHATTER = """&geometry a=0.5, b=0.20899343026301553, c=0.1570934425906232 /
&ball radius=0.01415928391749069, mass=100.0, mu=0.030694063357477794, slip='slide', inertia_factor=0.4,
      rolling_resistance=0.00032386670001004805 /
&initial x=0.008960627061902149, y=-0.0549060776223767, omega=-2.1840402475424456,5.303981287547228,0.7344022305237464 /
&integration method='rk4', dt=1e-5, t_end=60.0 /
&excitation kind='record', record_file='{records}/SYN2_H1.AT2','{records}/SYN1_H2.AT2', scale=5.8585979750433985 /
&output interval=0.01 /
"""


def chatter_text():
    return CHATTER.format(records=ROOT / "input" / "records")


@pytest.mark.parametrize("stop", [signal.SIGTERM, signal.SIGINT])
def test_a_stop_signal_ends_a_run_inside_its_case_within_milliseconds(ellroll, tmp_path, stop):
    (tmp_path / "chatter.nml").write_text(chatter_text())
    proc = subprocess.Popen([str(ellroll), "run", "chatter.nml", "-q", "-o", "out.h5"], cwd=tmp_path,
                            stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True)
    try:
        time.sleep(1.5)
        assert proc.poll() is None, "the case ended before the signal"
        proc.send_signal(stop)
        sent = time.monotonic()
        try:
            _, stderr = proc.communicate(timeout=20)
        except subprocess.TimeoutExpired:
            pytest.fail(f"no exit 20 s after {stop.name}")
        delay = time.monotonic() - sent
    finally:
        proc.kill()
        proc.wait()
    assert delay < 1.0, delay
    assert proc.returncode == 128 + stop, stderr
    assert (f"ellroll: interrupted by {stop.name} after 0 of 1 cases; "
            f"'ellroll run chatter.nml -q -o out.h5 --resume' finishes the rest") in stderr, stderr
    assert (tmp_path / "out.h5.journal").exists() and (tmp_path / "out.h5.partial").exists()
    assert not (tmp_path / "out.h5").exists()


INTERRUPTED = """
import sys, time
sys.path.insert(0, sys.argv[1])
import ellroll
print("started", flush=True)
try:
    ellroll.run_arrays(sys.argv[2], threads=1)
    print("finished", flush=True)
except KeyboardInterrupt:
    print(f"interrupted {time.monotonic():.6f}", flush=True)
"""


def test_ctrl_c_ends_run_arrays_inside_its_case_within_milliseconds(tmp_path):
    (tmp_path / "interrupted.py").write_text(INTERRUPTED)
    env = dict(os.environ, ELLROLL_LIB=os.environ.get("ELLROLL_LIB", str(ROOT / "build" / "libellroll.so")))
    child = subprocess.Popen([sys.executable, "interrupted.py", str(ROOT / "post"), chatter_text()], cwd=tmp_path,
                             stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, env=env)
    deadline = threading.Timer(20, child.kill)       # (a late stop: the reads below see the end)
    deadline.start()
    try:
        assert child.stdout.readline().strip() == "started"
        time.sleep(1.5)
        sent = time.monotonic()
        child.send_signal(signal.SIGINT)
        line = child.stdout.readline().split()
        assert line and line[0] == "interrupted", (line, child.stderr.read() if not line else "")
        delay = float(line[1]) - sent
        assert delay < 1.0, delay
        assert child.wait(timeout=20) == 0
    finally:
        deadline.cancel()
        child.kill()
        child.wait()
