"""Rolling resistance (&ball rolling_resistance = delta): the planar swing in
the paper's cup is a Coulomb-damped oscillator (decrement 2 rho delta / R
per half cycle, rest where |x| <= rho delta / R, period unchanged); in 3D
the couple's work is the energy lost (rolling_resistance_energy with every
method, energy_drift the balance's residual, on a fixed and a moving cup); the stick is an event (the state is
then exactly constant, no rejected steps); a moving cup starts the ball
only when its pull exceeds delta N / R; delta = 0 is the model without it."""
import h5py
import numpy as np
import pytest

from conftest import run

RHO, RADIUS, DELTA, G, K = 1.0**2 / 0.2, 0.2, 2.0e-4, 9.81, 0.4
HALF_PERIOD = np.pi * np.sqrt((1 + K) * (RHO - RADIUS) / G)      # linearised x-z swing

CUP = """&geometry a = 1.0, b = 0.4, c = 0.2 /
&ball radius = 0.2, weight = 2620.0{resistance} /
&initial x = {x}, y = {y}, omega = 0.0, 0.0, {spin} /
&integration {integration}, t_end = {t_end} /
{excitation}&output file = 'out.h5', interval = 1.0e-3 /
"""
RK4 = "method = 'rk4', dt = 1.0e-3"
DOP853 = "method = 'dop853', rtol = 1.0e-10"
VERN9 = "method = 'vern9', rtol = 1.0e-10"


def run_cup(ellroll, folder, delta=DELTA, x=0.052, y=0.0, spin=0.0, integration=RK4, t_end=30.0, excitation=""):
    resistance = f", rolling_resistance = {delta!r}" if delta is not None else ""
    (folder / "cup.nml").write_text(CUP.format(resistance=resistance, x=x, y=y, spin=spin, integration=integration,
                                               t_end=t_end, excitation=excitation))
    result = run(ellroll, "run", "cup.nml", "-q", "--overwrite", cwd=folder)
    assert result.returncode == 0, result.stderr
    assert "warning" not in result.stderr, result.stderr
    f = h5py.File(folder / "out.h5", "r")
    return f


def turning_points(t, x):
    k = np.nonzero((np.diff(x[:-1]) * np.diff(x[1:]) < 0))[0] + 1
    return t[k], x[k]


@pytest.mark.parametrize("integration", [RK4, DOP853, VERN9], ids=["rk4", "dop853", "vern9"])
def test_planar_swing_is_a_coulomb_damped_oscillator(ellroll, tmp_path, integration):
    with run_cup(ellroll, tmp_path, integration=integration) as f:
        t, x = f["time"][()], f["trajectory/contact"][0][:, 0]
        y = f["trajectory/contact"][0][:, 1]
        rejected = f["summary/n_rejected"][0]
    times, points = turning_points(t, x)
    assert np.allclose(points[:4], [-0.042, 0.032, -0.022, 0.012], atol=3e-4)
    decrements = np.abs(np.r_[0.052, points[:4]])[:-1] - np.abs(points[:4])
    assert np.allclose(decrements, 2 * RHO * DELTA / RADIUS, rtol=0.03)       # 0.010 m each half cycle
    assert np.allclose(np.diff(np.r_[0.0, times[:4]]), HALF_PERIOD, rtol=0.01)  # the period unchanged
    stop = np.nonzero(np.diff(x))[0][-1] + 1
    assert abs(x[-1] - (-0.002)) < 5e-4 and abs(x[-1]) <= RHO * DELTA / RADIUS
    assert t[stop] == pytest.approx(5 * HALF_PERIOD, rel=0.01)                # at rest from the fifth turn on
    assert np.all(x[stop:] == x[-1]) and np.all(y == 0)                         # exactly: no chattering
    assert rejected == 0                                                        # the stops are events


def test_the_couples_work_is_the_energy_lost(ellroll, tmp_path):
    """A 3D motion with spin: E(t) - E(0) equals the work of -delta N
    omega_t / |omega_t| (trapezoid rule on the samples of every step)."""
    with run_cup(ellroll, tmp_path, delta=1.0e-4, x=0.05, y=0.03, spin=0.5, t_end=20.0) as f:
        t = f["time"][()]
        force, normal = f["trajectory/reaction"][0], f["trajectory/normal"][0]
        omega, energy = f["trajectory/omega"][0], f["trajectory/energy"][0]
    normal_force = np.sum(force * normal, axis=1)
    rolling = omega - np.sum(omega * normal, axis=1)[:, None] * normal
    power = -1.0e-4 * normal_force * np.linalg.norm(rolling, axis=1)
    work = np.r_[0.0, np.cumsum((power[1:] + power[:-1]) / 2 * np.diff(t))]
    loss = energy - energy[0]
    assert loss[-1] < -1.0                                                    # it does lose energy
    assert np.abs(loss - work).max() < 1e-6 * abs(loss[-1])


@pytest.mark.parametrize("amplitude,moves", [(0.0095, False), (0.0105, True)])
def test_a_moving_cup_starts_the_ball_beyond_delta_g_over_r(ellroll, tmp_path, amplitude, moves):
    """At rest at the bottom the couple holds the ball while m R |a_base| <=
    delta m g: a base acceleration up to delta g / R = 0.00981 m/s^2."""
    excitation = f"&excitation kind = 'harmonic', amplitude = {amplitude}, 0.0, 0.0, frequency = 0.5 /\n"
    with run_cup(ellroll, tmp_path, x=0.0, integration=DOP853, t_end=10.0, excitation=excitation) as f:
        x = f["trajectory/contact"][0][:, 0]
    assert (np.ptp(x) > 1e-6) == moves and (moves or np.all(x == 0))


def test_delta_zero_is_the_model_without_it(ellroll, tmp_path):
    with run_cup(ellroll, tmp_path, delta=0.0, x=0.05, y=0.03, spin=0.5, t_end=5.0) as f:
        zero = {name: f["trajectory"][name][()] for name in f["trajectory"]}
        assert f["case/rolling_resistance"][0] == 0
    with run_cup(ellroll, tmp_path, delta=None, x=0.05, y=0.03, spin=0.5, t_end=5.0) as f:
        for name in f["trajectory"]:
            assert f["trajectory"][name][()].tobytes() == zero[name].tobytes(), name


# The 3D motion with spin above, on the fixed cup: the couple is the only
# loss, E(0) - E(t_end) is the couple's work.
THREE_D = dict(delta=1.0e-4, x=0.05, y=0.03, spin=0.5, t_end=20.0)


def couples_work(ellroll, folder, integration, excitation=""):
    """rolling_resistance_energy, energy_drift and E(0) - E(t_end) of the 3D motion."""
    with run_cup(ellroll, folder, integration=integration, excitation=excitation, **THREE_D) as f:
        s = {k: f["summary"][k][0] for k in ("status", "t_final", "rolling_resistance_energy", "energy_drift")}
        energy = f["trajectory/energy"][0]
    assert s["status"] == 1 and s["t_final"] == THREE_D["t_end"]
    s["lost"] = energy[0] - energy[-1]
    s["e0"] = energy[0]
    return s


@pytest.mark.parametrize("method", ["dop853", "vern9"])
def test_the_couples_work_closes_the_energy_balance_with_the_embedded_pairs(ellroll, tmp_path, method):
    """At rtol 1e-10 the couple's work (the 4-point Gauss-Legendre rule on
    the pair's dense output over each step) equals the energy lost, 1.29 J,
    to 1.9e-11 (dop853) and 8e-12 (vern9) of it (a trapezoidal sum over the
    long steps counts 0.14 % and 0.16 % too little), and energy_drift, the
    residual of E + W = E0 over E0 = 526 J, is 5e-14 and 4e-14."""
    s = couples_work(ellroll, tmp_path, f"method = '{method}', rtol = 1.0e-10")
    assert s["lost"] > 1.0
    assert abs(s["rolling_resistance_energy"] - s["lost"]) < 1e-9 * s["lost"]
    assert s["energy_drift"] < 1e-12


@pytest.mark.parametrize("integration", [RK4, "method = 'gauss4', dt = 1.0e-3"], ids=["rk4", "gauss4"])
def test_energy_drift_is_the_residual_of_the_balance_with_the_couple(ellroll, tmp_path, integration):
    """The fixed steps (rk4 in SIMD lanes, gauss4 one case at a time) at
    dt = 1e-3 s: energy_drift is max |E - E0 + W| / |E0|, W the couple's
    work (the trapezoidal rule over the short steps), 5.4e-11 with either,
    not the size of the couple's loss (2.5e-3 of E0 = 526 J); the work
    equals the energy lost to 5e-9 and 6e-9 of it."""
    s = couples_work(ellroll, tmp_path, integration)
    assert abs(s["rolling_resistance_energy"] - s["lost"]) < 1e-6 * s["lost"]
    assert s["energy_drift"] < 1e-8
    assert s["energy_drift"] * s["e0"] >= abs(s["rolling_resistance_energy"] - s["lost"]) * (1 - 1e-9)


def test_the_couples_work_converges_with_the_tolerance(ellroll, tmp_path):
    """dop853 at rtol 1e-8, 1e-10, 1e-12 against rk4 at dt = 1e-4 s, whose
    own work is 7e-11 short of the energy lost: 4.7e-10, 7e-11, 8e-11 of
    the work apart (3.3e-3, 1.4e-3, 7.2e-4 with a trapezoidal sum over the
    steps), the error falling with rtol to the reference's own."""
    reference = couples_work(ellroll, tmp_path, "method = 'rk4', dt = 1.0e-4")["rolling_resistance_energy"]
    errors = []
    for rtol in (1e-8, 1e-10, 1e-12):
        work = couples_work(ellroll, tmp_path, f"method = 'dop853', rtol = {rtol}")["rolling_resistance_energy"]
        errors.append(abs(work - reference) / reference)
    assert errors[0] < 2e-9 and errors[1] < 3e-10 and errors[2] < 3e-10
    assert errors[1] < errors[0]


@pytest.mark.parametrize("method", ["dop853", "vern9"])
def test_the_couples_work_closes_the_balance_on_a_moving_cup(ellroll, tmp_path, method):
    """The paper's cup shaken harmonically (1.5, 0.5 m/s^2 at 0.5 Hz), the
    ball from rest at the bottom, delta = 1e-3 m, mu = 10 (never reached), rtol 1e-10,
    samples 1e-3 s apart: E(t) - E(0) - W_cup + rolling_resistance_energy,
    W_cup = -m int a_base . dC from the stored centre (test_sliding_truth),
    is 5.5e-11 (dop853) and -7e-12 (vern9) of the couple's work (0.426 J);
    with a trapezoidal sum over the steps, -1.0e-3 and -1.5e-3."""
    from test_sliding_truth import HARMONIC, harmonic_work, run_case
    amplitude, frequency = HARMONIC
    excitation = (f"&excitation kind = 'harmonic', amplitude = 1.5, 0.5, 0.0, frequency = {frequency}, "
                  "phase = 0.0 /")
    out = run_case(ellroll, tmp_path, "moving", slip="end", mu=10.0, ball=", rolling_resistance = 1e-3",
                   integration=f"method = '{method}', rtol = 1e-10", t_end=20.0, excitation=excitation, interval=1e-3)
    assert out["status"] == 1 and out["t_final"] == 20.0
    resistance = out["rolling_resistance_energy"]
    assert resistance > 0.4
    residual = out["energy"][-1] - out["energy"][0] - harmonic_work(out, amplitude, frequency) + resistance
    assert abs(residual) < 1e-9 * resistance
