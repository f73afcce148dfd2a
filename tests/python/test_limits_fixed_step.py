"""Fixed-step methods at the model's limits: every state a step evaluates the
model at is checked, and a step that meets a limit is followed to it on
shorter steps. The truth: DOP853 at rtol 1e-13."""
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
               "time": f["time"][:], "energy_drift": f["summary/energy_drift"][:], "n_steps": f["summary/n_steps"][:], "n_rejected": f["summary/n_rejected"][:]}
        for field in ("contact", "omega", "nutation"):
            out[field] = f["trajectory/" + field][:]
    return out


@pytest.mark.parametrize("omega_x", sorted(T_NO_FIT))
@pytest.mark.parametrize("method, dt", [("rk4", 2e-3), ("rk4", 1e-3), ("rk4", 5e-4), ("rk4", 1e-4),
                                        ("gauss4", 1e-3), ("gauss4", 1e-4)])
def test_a_step_over_the_fit_limit_ends_the_case_there(ellroll, tmp_path, method, dt, omega_x):
    """Near the fit limit the solution has a square-root singularity, and the
    method's own last steps err by up to 5e-6 s there; the case ends where the
    exact flow from its state 8 to 15 steps back meets the limit (measured:
    within 2.8e-10 s of the reference for every row, docs/model.md's figure)."""
    out = run_case(ellroll, tmp_path, case_text(method, dt, (omega_x, 0.0, 0.0)))
    assert out["status"] == ["no_fit"]
    assert abs(out["t_final"][0] - T_NO_FIT[omega_x]) < 3e-10
    assert out["n_rejected"][0] == 0      # the step control's count: adaptive methods only
    done = out["time"] <= out["t_final"][0]
    assert np.all(np.isfinite(out["nutation"][0][done])) and np.all(np.isnan(out["nutation"][0][~done]))


@pytest.mark.parametrize("path", ["", ", error_estimate = 'reference'"], ids=["batch", "one case"])
def test_a_limit_met_before_the_methods_last_step_drops_the_samples_after_it(ellroll, tmp_path, path):
    """omega_x chosen so that the limit lies 1.5e-6 s before t = 0.207 (the
    reference below): RK4's own steps at dt = 1e-3 stay inside the model up to
    0.207 and meet the limit only on the step after it. The case ends at the
    reference time, and the sample at 0.207, after the end, is not stored;
    in a batch and alone (a case with error figures runs alone)."""
    omega_x, t_limit = -6.00075720332869, 0.2069985
    reference = run_case(ellroll, tmp_path, case_text("dop853", 1.0, (omega_x, 0.0, 0.0),
                                                       extra=", rtol = 1e-13, atol = 1e-15"))
    assert reference["status"] == ["no_fit"] and abs(reference["t_final"][0] - t_limit) < 1e-12
    out = run_case(ellroll, tmp_path, case_text("rk4", 1e-3, (omega_x, 0.0, 0.0), interval=1e-3, extra=path))
    assert out["status"] == ["no_fit"] and out["n_steps"][0] == 208
    assert abs(out["t_final"][0] - t_limit) < 1e-9
    assert np.isfinite(out["omega"][0, 206]).all() and np.isnan(out["omega"][0, 207]).all()
    assert out["time"][206] < out["t_final"][0] < out["time"][207]


def test_a_step_far_beyond_stability_is_named(ellroll, tmp_path):
    out = run_case(ellroll, tmp_path, case_text("rk4", 1e-3, (-2.0, 2.0, 1e6)))
    assert out["status"] == ["unstable"] and out["t_final"][0] < 0.01


def test_starts_near_the_limits_end_as_the_reference_does(ellroll, tmp_path):
    """Seeded random starts of the paper cup: RK4 at dt = 1e-4 meets the same
    limit as DOP853 at rtol 1e-12 within 1e-6 s, and is never 'completed'
    where the reference met a limit; vern9 at rtol 1e-12 meets it within 1e-9 s
    of DOP853."""
    rng = np.random.default_rng(24)
    starts = [(rng.uniform(-0.3, 0.3), rng.uniform(-0.1, 0.1), rng.uniform(-6, 6), rng.uniform(-6, 6),
               rng.uniform(-30, 30)) for _ in range(40)]
    outcomes = {}
    for method, dt, extra in [("rk4", 1e-4, ""), ("dop853", 1.0, ", rtol = 1e-12, atol = 1e-14"),
                              ("vern9", 1.0, ", rtol = 1e-12, atol = 1e-14")]:
        rows = [run_case(ellroll, tmp_path, case_text(method, dt, s[2:], start=s[:2], extra=extra))
                for s in starts]
        outcomes[method] = [(r["status"][0], r["t_final"][0]) for r in rows]
    limited = [i for i, (status, _) in enumerate(outcomes["dop853"]) if status != "completed"]
    assert len(limited) >= 10
    for i in range(len(starts)):
        assert outcomes["rk4"][i][0] == outcomes["dop853"][i][0], (starts[i], outcomes["rk4"][i], outcomes["dop853"][i])
        assert abs(outcomes["rk4"][i][1] - outcomes["dop853"][i][1]) < 1e-6, (starts[i], outcomes["rk4"][i])
        assert outcomes["vern9"][i][0] == outcomes["dop853"][i][0], (starts[i], outcomes["vern9"][i])
        assert abs(outcomes["vern9"][i][1] - outcomes["dop853"][i][1]) < 1e-9, (starts[i], outcomes["vern9"][i])


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


def small_ball_text(method, dt, omega, cup=(1.0, 0.4, 0.2), start=(0.0, 0.0), t_end=2.0, interval=0.01, extra="",
                    sweep=""):
    a, b, c = cup
    return (f"&geometry a = {a!r}, b = {b!r}, c = {c!r} /\n&ball radius = 0.05, weight = 100.0 /\n"
            f"&initial x = {start[0]!r}, y = {start[1]!r}, omega = {', '.join(repr(float(w)) for w in omega)} /\n"
            f"&integration method = '{method}', dt = {dt!r}, t_end = {t_end!r} {extra}/\n"
            f"&output file = 'out.h5', interval = {interval!r} /\n" + sweep)


# The spin about x at which the small ball on the paper cup just reaches the
# rim (input/hard/rim_above.nml holds 1.001 times it).
OMEGA_RIM = -29.02653437804796 / 1.001


def test_a_stage_past_the_rim_where_the_path_stays_inside_is_taken_in_pieces(ellroll, ellroll_debug, tmp_path):
    """1e-6 below the spin that reaches the rim the path comes within 6.0e-6
    rad of it (vern9 and dop853 at rtol 1e-12: pi/2 - Theta_max = 5.99999e-6)
    and completes. RK4's last stage, y + h k3, lies on a straight line off
    that curved path and passes the rim; the step is taken again in pieces
    (at dt = 1e-3 and, 1e-8 below, at dt = 1e-4), and the case completes as
    the reference does: alone, in a batch (equal to the one-case run
    bitwise but for Theta's vector atan2), and on the Debug build."""
    omega = (OMEGA_RIM * (1 - 1e-6), 0.0, 0.0)
    reference = run_case(ellroll, tmp_path, small_ball_text("vern9", 2.0, omega, extra=", rtol = 1e-12, atol = 1e-14"))
    assert reference["status"] == ["completed"]
    with h5py.File(tmp_path / "out.h5", "r") as f:
        reference_gap = np.pi / 2 - f["summary/theta_max"][0]
    assert reference_gap == pytest.approx(6.0e-6, rel=1e-3)
    for exe in (ellroll_debug, ellroll):
        alone = run_case(exe, tmp_path, small_ball_text("rk4", 1e-3, omega))
        assert alone["status"] == ["completed"] and alone["t_final"][0] == 2.0
    with h5py.File(tmp_path / "out.h5", "r") as f:
        gap = np.pi / 2 - f["summary/theta_max"][0]
    assert reference_gap < gap < reference_gap + 1e-6      # step ends on the path, below its maximum
    # eight copies in one campaign run as a SIMD batch; the first is the case above
    batch = run_case(ellroll, tmp_path, small_ball_text(
        "rk4", 1e-3, omega, sweep=f"&sweep name = 'omega_x', values = {', '.join([repr(omega[0])] * 8)} /\n"))
    assert batch["status"] == ["completed"] * 8
    for field in ("contact", "omega"):
        assert np.array_equal(batch[field][0], alone[field][0])
    # Theta from the vector atan2 of a batch: a few units of round-off
    assert np.allclose(batch["nutation"][0], alone["nutation"][0], rtol=1e-15, atol=0)
    fine = run_case(ellroll, tmp_path, small_ball_text("rk4", 1e-4, (OMEGA_RIM * (1 - 1e-8), 0.0, 0.0)))
    assert fine["status"] == ["completed"]


# A flat cup: the ball stops fitting near its rim, where the radius of
# curvature shrinks so fast that the margin 1e-6 is crossed within about
# 1e-15 s of the singular point. vern9 and dop853 at rtol 1e-12 end at
# 0.57502262712993 s and 0.57502262712992 s; SciPy's DOP853 (rtol 1e-13) and
# Radau on bench/ball_numpy.py stop at the singular point, 0.57502262712988 s.
FLAT_CUP = (1.0, 0.8, 0.01)
T_FLAT_NO_FIT = 0.5750226271299


@pytest.mark.parametrize("method, dt", [("rk4", 1e-3), ("rk4", 5e-4), ("gauss4", 1e-3), ("gauss4", 2e-4)])
def test_a_fit_limit_sharper_than_the_resolution_of_t_ends_the_case_there(ellroll, ellroll_debug, tmp_path, method, dt):
    """The exact flow from the method's checkpoint reaches the singular point
    with steps at the resolution of t (1.4e-15 s near 0.575 s); the case ends
    there with 'no_fit', within 2e-10 s of the reference (measured 3e-11 s
    for RK4, 1.6e-10 s for gauss4 at dt = 1e-3, whose Newton iteration has no
    solution on the step before)."""
    text = small_ball_text(method, dt, (30.0, -20.0, 5.0), cup=FLAT_CUP, start=(0.3, 0.1), t_end=1.0)
    for exe in (ellroll, ellroll_debug):
        out = run_case(exe, tmp_path, text)
        assert out["status"] == ["no_fit"]
        assert abs(out["t_final"][0] - T_FLAT_NO_FIT) < 2e-10
        done = out["time"] <= out["t_final"][0]
        assert np.all(np.isfinite(out["nutation"][0][done])) and np.all(np.isnan(out["nutation"][0][~done]))
        if method == "rk4":
            break                                   # the Debug build once per method


def test_samples_between_the_methods_last_state_and_the_flows_end_are_the_flows(ellroll, ellroll_debug, tmp_path):
    """gauss4's step to t = 0.170 has no solution (its stages lie past the fit
    limit), but the exact flow from its checkpoint meets the limit only at
    0.17020492198 s (vern9 at rtol 1e-12; SciPy's DOP853 at rtol 1e-13 to
    1e-14 s): the sample at 0.17 is the flow's, every sample up to the end
    is a number, and none after it."""
    text = case_text("gauss4", 1e-3, (4.864045026055468, -5.7241987982193425, -16.752830749254468),
                     start=(-0.24432499708664288, -0.016657976762415472))
    for exe in (ellroll, ellroll_debug):
        out = run_case(exe, tmp_path, text)
        assert out["status"] == ["no_fit"] and abs(out["t_final"][0] - 0.17020492198) < 1e-10
        done = out["time"] <= out["t_final"][0]
        assert out["time"][done][-1] == pytest.approx(0.17)
        for field in ("contact", "omega", "nutation"):
            assert np.all(np.isfinite(out[field][0][done])) and np.all(np.isnan(out[field][0][~done]))


@pytest.mark.parametrize("pair", ["vern9", "dop853"])
def test_a_singular_point_within_round_off_of_t_end_ends_the_run(ellroll, ellroll_debug, tmp_path, pair):
    """The flat cup's fit limit 5e-13 s after t_end = 1 s (vern9 with
    t_end = 1.01 s: 'no_fit' at 1.000000000000512 s): a step that would end
    within 1e-12 t_end of t_end is stretched to end there, and after it is
    rejected it must not be stretched again. The case completes."""
    text = small_ball_text(pair, 1.0, (-15.664441476396997, -3.465108540098682, -10.254719053652519), cup=FLAT_CUP,
                           start=(0.21295101128683752, 0.025632306483354964), t_end=1.0,
                           extra=", rtol = 1.0e-12, atol = 1.0e-14")
    for exe in (ellroll, ellroll_debug):
        (tmp_path / "edge.nml").write_text(text)
        result = run(exe, "run", "edge.nml", "-q", "--overwrite", "-o", "out.h5", cwd=tmp_path, timeout=60)
        assert result.returncode == 0, result.stderr
        with h5py.File(tmp_path / "out.h5", "r") as f:
            assert f["summary/status"].attrs["flag_meanings"].split()[f["summary/status"][0]] == "completed"
            assert f["summary/t_final"][0] == 1.0
