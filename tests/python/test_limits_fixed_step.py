"""Fixed-step methods at the model's limits: every state a step evaluates the
model at is checked, and a step that meets a limit is followed to it on
shorter steps. The truth: DOP853 at rtol 1e-13, and DOP853 continuing the
fixed-step method's own last state inside the model."""
import re

import h5py
import numpy as np
import pytest

from conftest import run

# The paper cup, started at the bottom rolling along y: the ball stops
# fitting the cup (r_min / R - 1 = 1e-6) at these times (DOP853, rtol 1e-13;
# an independent reference agrees to 1e-12 s).
T_NO_FIT = {-4.5: 0.319137870749, -6.0: 0.207031071628}


def case_text(method, dt, omega, t_end=1.0, interval=0.01, start=(0.0, 0.0), extra=""):
    omega = [float(w) for w in omega]
    start = [float(x) for x in start]
    return (f"&geometry a = 1.0, b = 0.4, c = 0.2 /\n&ball radius = 0.2, weight = 2620.0 /\n"
            f"&initial x = {start[0]!r}, y = {start[1]!r}, omega = {', '.join(map(repr, omega))} /\n"
            f"&integration method = '{method}', dt = {dt!r}, t_end = {t_end!r} {extra}/\n"
            f"&output file = 'out.h5', interval = {interval!r} /\n")


def run_case(ellroll, tmp_path, text, name="case.nml"):
    (tmp_path / name).write_text(text)
    result = run(ellroll, "run", name, "-q", "--overwrite", "-o", "out.h5", cwd=tmp_path, timeout=300)
    assert result.returncode == 0, result.stderr
    with h5py.File(tmp_path / "out.h5", "r") as f:
        meanings = f["summary/status"].attrs["flag_meanings"].split()
        out = {"status": [meanings[s] for s in f["summary/status"][:]], "t_final": f["summary/t_final"][:],
               "time": f["time"][:], "energy_drift": f["summary/energy_drift"][:]}
        for field in ("contact", "omega", "nutation"):
            out[field] = f["trajectory/" + field][:]
    return out


@pytest.mark.parametrize("omega_x", sorted(T_NO_FIT))
@pytest.mark.parametrize("method, dt", [("rk4", 1e-3), ("rk4", 5e-4), ("rk4", 1e-4), ("gauss4", 1e-4)])
def test_a_step_over_the_fit_limit_ends_the_case_there(ellroll, tmp_path, method, dt, omega_x):
    out = run_case(ellroll, tmp_path, case_text(method, dt, (omega_x, 0.0, 0.0)))
    assert out["status"] == ["no_fit"]
    # near the limit the solution has a square-root singularity (the contact
    # point's speed diverges): the method's last step before it errs by a
    # part of a step, 1.1e-3 to 5e-3 dt here, gauss4 below 1e-8 s
    assert abs(out["t_final"][0] - T_NO_FIT[omega_x]) < (1e-8 if method == "gauss4" else 1e-2 * dt)
    done = out["time"] <= out["t_final"][0]
    assert np.all(np.isfinite(out["nutation"][0][done])) and np.all(np.isnan(out["nutation"][0][~done]))


@pytest.mark.parametrize("omega_x", sorted(T_NO_FIT))
def test_the_limit_is_where_the_methods_own_trajectory_meets_it(ellroll, tmp_path, omega_x):
    """RK4 at dt = 1e-3 sampled at every step; DOP853 (rtol 1e-13) from its
    last step inside the model meets the limit where RK4's end time says
    (measured: 1.1e-8 and 3.1e-8 s apart)."""
    dt = 1e-3
    rk4 = run_case(ellroll, tmp_path, case_text("rk4", dt, (omega_x, 0.0, 0.0), interval=dt))
    assert rk4["status"] == ["no_fit"]
    last = np.searchsorted(rk4["time"], rk4["t_final"][0], side="right") - 1
    assert rk4["t_final"][0] - rk4["time"][last] < dt
    x, y, _ = rk4["contact"][0, last]
    text = case_text("dop853", 0.01, tuple(rk4["omega"][0, last]), t_end=0.01, interval=0.01, start=(x, y),
                     extra=", rtol = 1e-13, atol = 1e-15")
    dop = run_case(ellroll, tmp_path, text, name="continued.nml")
    assert dop["status"] == ["no_fit"]
    assert abs(rk4["time"][last] + dop["t_final"][0] - rk4["t_final"][0]) < 5e-8


def test_a_step_far_beyond_stability_is_named(ellroll, tmp_path):
    out = run_case(ellroll, tmp_path, case_text("rk4", 1e-3, (-2.0, 2.0, 1e6)))
    assert out["status"] == ["unstable"] and out["t_final"][0] < 0.01


def test_starts_near_the_limits_end_as_the_reference_does(ellroll, tmp_path):
    """Seeded random starts of the paper cup: RK4 at dt = 1e-4 meets the same
    limit as DOP853 at rtol 1e-12 within 1e-6 s, and is never 'completed'
    where the reference met a limit."""
    rng = np.random.default_rng(24)
    starts = [(rng.uniform(-0.3, 0.3), rng.uniform(-0.1, 0.1), rng.uniform(-6, 6), rng.uniform(-6, 6),
               rng.uniform(-30, 30)) for _ in range(40)]
    outcomes = {}
    for method, dt, extra in [("rk4", 1e-4, ""), ("dop853", 1.0, ", rtol = 1e-12, atol = 1e-14")]:
        rows = [run_case(ellroll, tmp_path, case_text(method, dt, s[2:], start=s[:2], extra=extra))
                for s in starts]
        outcomes[method] = [(r["status"][0], r["t_final"][0]) for r in rows]
    limited = [i for i, (status, _) in enumerate(outcomes["dop853"]) if status != "completed"]
    assert len(limited) >= 10
    for i in range(len(starts)):
        assert outcomes["rk4"][i][0] == outcomes["dop853"][i][0], (starts[i], outcomes["rk4"][i], outcomes["dop853"][i])
        assert abs(outcomes["rk4"][i][1] - outcomes["dop853"][i][1]) < 1e-6, (starts[i], outcomes["rk4"][i])


def test_a_sweep_over_dt_equals_each_case_run_alone(ellroll, tmp_path):
    base = case_text("rk4", 1e-3, (-2.0, 2.0, 20.0))
    swept = run_case(ellroll, tmp_path, base + "&sweep name = 'dt', values = 1e-3, 5e-4, 2e-3 /\n")
    for i, dt in enumerate([1e-3, 5e-4, 2e-3]):
        alone = run_case(ellroll, tmp_path, case_text("rk4", dt, (-2.0, 2.0, 20.0)), name="alone.nml")
        for field in ("contact", "omega", "nutation"):
            assert np.array_equal(swept[field][i], alone[field][0])
        assert swept["t_final"][i] == alone["t_final"][0] == 1.0


def test_a_swept_dt_that_does_not_divide_the_interval_is_rejected(ellroll, tmp_path):
    text = case_text("rk4", 1e-3, (-2.0, 2.0, 20.0)) + "&sweep name = 'dt', values = 1e-3, 3e-3 /\n"
    (tmp_path / "bad.nml").write_text(text)
    for command in ("check", "run"):
        result = run(ellroll, command, "bad.nml", "-o", "bad.h5", cwd=tmp_path)
        assert result.returncode == 2
        assert "case 1 (dt = 0.003)" in result.stderr and "whole number of steps" in result.stderr
        assert not (tmp_path / "bad.h5").exists()


def test_check_names_each_case_beyond_stability_and_those_end_unstable(ellroll, tmp_path):
    """A spin sweep at RK4's dt = 1e-3: the fastest rate at the start grows in
    proportion to the spin (3.4e3 1/s at omega_z = 1e5 rad/s), so dt x rate
    passes 2 sqrt 2 from omega_z = 1e5 on; check lists exactly
    those cases, with a dt that would do, and each of them ends 'unstable'
    while the others do not."""
    spins = [20.0, 150.0, 3000.0, 1e4, 1e5, 2e5, 5e5, 1e6]
    text = case_text("rk4", 1e-3, (-2.0, 2.0, 20.0), t_end=0.5) + \
        f"&sweep name = 'omega_z', values = {', '.join(map(repr, spins))} /\n"
    (tmp_path / "sweep.nml").write_text(text)
    result = run(ellroll, "check", "sweep.nml", cwd=tmp_path)
    assert result.returncode == 0, result.stderr
    listed = [int(i) for i in re.findall(r"^  case (\d+): dt = 0.001 s, dt \* rate = [0-9.]+; dt <= [0-9.e-]+ s would do$",
                                          result.stderr, re.M)]
    assert "4 of 8 cases: dt is beyond rk4's stability" in result.stderr, result.stderr
    assert listed == [4, 5, 6, 7], result.stderr
    out = run_case(ellroll, tmp_path, text, name="sweep.nml")
    assert [i for i, s in enumerate(out["status"]) if s == "unstable"] == listed
