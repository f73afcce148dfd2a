"""A thread stack of 256 KiB (OMP_STACKSIZE=256K for the threads beyond the
first, threading.stack_size in Python): a campaign in SIMD batches of 8 rk4
cases runs to the same results as with the usual stacks (a batch's block of
output samples, 139 kB, is on the heap)."""
import os
import subprocess
import sys

from conftest import ROOT, run
from test_campaign import SPIN_RADIUS, assert_same_datasets, write

KIB_256 = 256 * 1024


def test_a_campaign_in_batches_runs_on_256_kib_stacks(ellroll, tmp_path):
    name = write(tmp_path, SPIN_RADIUS, t_end=0.5)
    assert run(ellroll, "run", name, "-q", "-o", "usual.h5", "--threads", "2", cwd=tmp_path).returncode == 0
    small = subprocess.run([str(ellroll), "run", name, "-q", "-o", "omp.h5", "--threads", "2"], cwd=tmp_path,
                           capture_output=True, text=True, timeout=120, env={**os.environ, "OMP_STACKSIZE": "256K"})
    assert small.returncode == 0, (small.returncode, small.stderr)
    assert_same_datasets(tmp_path / "usual.h5", tmp_path / "omp.h5")


def test_the_python_api_runs_a_batch_in_a_thread_of_256_kib(tmp_path):
    name = write(tmp_path, SPIN_RADIUS, t_end=0.5)
    script = tmp_path / "small.py"
    script.write_text(f"""
import sys, threading
sys.path.insert(0, {str(ROOT / 'post')!r})
import ellroll, numpy as np
text = open({str(tmp_path / name)!r}).read()
usual = ellroll.run(text, threads=1)["summary"]["theta_max"]
threading.stack_size({KIB_256})
box = []
worker = threading.Thread(target=lambda: box.append(ellroll.run(text, threads=1)["summary"]["theta_max"]))
worker.start()
worker.join()
print(np.asarray(usual).tobytes() == np.asarray(box[0]).tobytes())
""")
    result = subprocess.run([sys.executable, str(script)], cwd=tmp_path, capture_output=True, text=True, timeout=120)
    assert result.returncode == 0 and result.stdout.strip() == "True", (result.returncode, result.stderr)
