"""The adaptive pairs see a limit that the path passes and leaves again
inside one of their steps."""
import h5py
import numpy as np
import pytest

from conftest import run

T_RUN = 1.5
TIGHT = ", rtol = 1.0e-12, atol = 1.0e-14"


def campaign(cases, method, dt, extra="", t_end=T_RUN):
    """The cases as one campaign (zipped sweeps); eight or more rk4, dop853 or
    vern9 cases run in SIMD batches."""
    text = (f"&geometry a = 1.0, b = 0.5, c = 0.2 /\n&ball radius = 0.05, weight = 100.0 /\n"
            f"&initial x = 0.0, y = 0.0, omega = 0.0, 0.0, 1.0 /\n"
            f"&integration method = '{method}', dt = {dt!r}, t_end = {t_end!r} {extra}/\n"
            f"&output file = 'out.h5', interval = 0.01, fields = 'nutation' /\n&campaign combine = 'zip' /\n")
    for key in ("a", "b", "c", "radius", "x", "y", "omega_x", "omega_y", "omega_z", "mu"):
        text += f"&sweep name = '{key}', values = {', '.join(repr(float(c[key])) for c in cases)} /\n"
    return text


def run_campaign(exe, folder, text):
    (folder / "search.nml").write_text(text)
    result = run(exe, "run", "search.nml", "-q", "--overwrite", "-o", "out.h5", cwd=folder, timeout=600)
    assert result.returncode == 0, result.stderr
    with h5py.File(folder / "out.h5", "r") as f:
        meanings = f["summary/status"].attrs["flag_meanings"].split()
        return {"status": [meanings[s] for s in f["summary/status"][:]], "t_final": f["summary/t_final"][:],
                "friction": f["summary/friction_needed_max"][:], "nutation": f["trajectory/nutation"][:],
                "time": f["time"][:]}


# Starts at which the path passes a limit and leaves it again within one
# step of vern9 or dop853 at rtol 1e-12 (found by seeded random starts near
# the limits): the rim,
# 6.6e-7 and 2.6e-8 beyond a graze, and the friction limit, 8.4e-8 and
# 1.6e-7 below the largest friction needed. RK4 at dt = 1e-4, which checks
# every stage, ends them at these times.
PASSED_INSIDE_A_STEP = [
    ({"a": 0.6, "b": 0.5, "c": 0.4, "radius": 0.1, "x": -0.2320451901612417, "y": 0.012007490569209084, "mu": 0.0,
      "omega_x": -21.51192858452452, "omega_y": 2.1858770047939746, "omega_z": 1.4229346533427094}, "rim", 0.4049494344),
    ({"a": 1.0, "b": 0.4, "c": 0.2, "radius": 0.2, "x": 0.20850308562435418, "y": -0.01922293293631365,
      "mu": 0.28002787523045763, "omega_x": 3.996160350664205, "omega_y": 1.4956203185424435,
      "omega_z": 0.4888831287917997}, "slip", 0.3656693042),
    ({"a": 0.6, "b": 0.5, "c": 0.4, "radius": 0.1, "x": 0.06712493723415468, "y": 0.19632310004734413, "mu": 0.0,
      "omega_x": -18.43954773176877, "omega_y": 3.8516192674416625, "omega_z": -27.097360522731897}, "rim", 0.3282963123),
    ({"a": 1.0, "b": 0.4, "c": 0.2, "radius": 0.05, "x": 0.1720863862743837, "y": 0.14878203618740019,
      "mu": 1.759632953367718, "omega_x": 24.51605706586233, "omega_y": -7.0970085913563485,
      "omega_z": 95.6018991027124}, "slip", 0.4595777274)]


@pytest.mark.parametrize("pair", ["vern9", "dop853"])
def test_a_limit_passed_and_left_inside_one_step_of_a_pair_ends_the_case(ellroll, ellroll_debug, tmp_path, pair):
    """A pair checks its step ends, and inside a step the maxima of Theta
    (past the rim) and, with a friction limit, of the friction needed: alone
    (fewer than 8 cases run one by one) and in a batch of 8, on the Debug
    build too."""
    cases = [case for case, _, _ in PASSED_INSIDE_A_STEP]
    expected_status = [status for _, status, _ in PASSED_INSIDE_A_STEP]
    expected_t = [t for _, _, t in PASSED_INSIDE_A_STEP]
    fixed = run_campaign(ellroll, tmp_path, campaign(cases, "rk4", 1e-4))
    assert fixed["status"] == expected_status and np.allclose(fixed["t_final"], expected_t, rtol=0, atol=1e-9)
    for exe, copies in [(ellroll, 1), (ellroll, 2), (ellroll_debug, 1)]:
        out = run_campaign(exe, tmp_path, campaign(cases * copies, pair, T_RUN, TIGHT))
        assert out["status"] == expected_status * copies, (exe, copies)
        assert np.allclose(out["t_final"], expected_t * copies, rtol=0, atol=1e-9), (exe, copies)
