"""A fixed-step case that completes ends at t_end itself: t_end is a whole
number of steps, and the steps' own time, n x dt, can be an ulp off it
(3 x 0.1 = 0.30000000000000004). Seeded (dt, n) pairs whose product is off
t_end, for rk4 and gauss4, a case alone and cases in SIMD lanes, rolling
and sliding (mu low enough to slide): /summary/t_final equals t_end and the
last sample's time, bit for bit."""
import decimal
import random

import h5py
import pytest

from conftest import run

CASE = """&geometry a = 1.0, b = 0.4, c = 0.2 /
&ball radius = 0.2, weight = 2620.0{mu} /
&initial x = 0.05, y = 0.0, omega = -2.0, 2.0, 20.0 /
&integration method = '{method}', dt = {dt}, t_end = {t_end} /
&output file = 'out.h5', interval = {t_end} /
"""


def off_grid_ends(seed, count):
    """(dt, t_end) texts with n x float(dt) != float(t_end), n = t_end / dt."""
    rng = random.Random(seed)
    found = []
    while len(found) < count:
        dt = rng.choice(["0.1", "0.01", "0.001", "0.0003", "0.007", "0.0011", "0.02"])
        n = rng.randint(1, 2000 if float(dt) < 0.01 else 60)
        t_end = str(decimal.Decimal(dt) * n)
        if float(t_end) != n * float(dt):
            found.append((dt, t_end))
    return found


@pytest.mark.parametrize("method, sliding", [("rk4", False), ("gauss4", False), ("rk4", True)],
                         ids=["rk4", "gauss4", "rk4_sliding"])
def test_a_completed_fixed_step_case_ends_at_t_end(ellroll, tmp_path, method, sliding):
    for k, (dt, t_end) in enumerate(off_grid_ends(4400 + 2 * sliding + (method == "gauss4"), 3)):
        text = CASE.format(method=method, dt=dt, t_end=t_end, mu=", mu = 0.05, slip = 'slide'" if sliding else "")
        for lanes in ("", "&sweep name = 'omega_z', values = 20.0, 21.0, 22.0 /\n"):
            folder = tmp_path / f"c{k}_{len(lanes)}"
            folder.mkdir()
            (folder / "case.nml").write_text(text + lanes)
            result = run(ellroll, "run", "case.nml", "-q", cwd=folder)
            assert result.returncode == 0, result.stderr
            with h5py.File(folder / "out.h5", "r") as f:
                status, t_final = f["summary/status"][:], f["summary/t_final"][:]
                times = f["trajectory/time"][:]
                slid = f["summary/sliding_time"][:] if sliding else [1.0]
            label = (method, dt, t_end, lanes, status, t_final)
            assert (status == 1).any() and min(slid) > 0, label
            for s, t in zip(status, t_final):
                if s == 1:
                    assert t == float(t_end) == times[-1], label
