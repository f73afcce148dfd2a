"""The rolling-resistance inputs of tests/inputs/rolling_resistance (fixed-step
and adaptive methods, fixed and moving cups, a stop that happens and motions
that go on), each checked against what the model says of it: the planar
swing of the paper's cup stops at its fifth turn within rho delta / R of the
bottom, and from there the state is exactly constant; the energy of a motion
on a fixed cup only falls, by the couple's work; a cup shaken below
delta g / R leaves a ball at rest where it stopped, one shaken beyond starts
it. These inputs are also the ones the bitwise comparisons of the run
loops' event handling use."""
import h5py
import numpy as np
import pytest

from conftest import ROOT, run

INPUTS = ROOT / "tests" / "inputs" / "rolling_resistance"
RHO, RADIUS, G, K = 1.0**2 / 0.2, 0.2, 9.81, 0.4
HALF_PERIOD = np.pi * np.sqrt((1 + K) * (RHO - RADIUS) / G)      # linearised x-z swing


def run_input(ellroll, folder, name):
    (folder / name).write_text((INPUTS / name).read_text())
    result = run(ellroll, "run", name, "-q", "--overwrite", cwd=folder)
    assert result.returncode == 0, result.stderr
    assert "warning" not in result.stderr, result.stderr
    f = h5py.File(folder / "out.h5", "r")
    assert f["summary/status"][0] == 1                                   # completed
    return f


def last_move(x):
    """Index of the first sample from which the contact point stays exactly put."""
    moved = np.nonzero(np.any(np.diff(x, axis=0) != 0, axis=1))[0]
    return moved[-1] + 1 if len(moved) else 0


@pytest.mark.parametrize("name", ["rk4_fixed_stop.nml", "vern9_fixed_stop.nml"])
def test_the_planar_swing_stops_at_its_fifth_turn(ellroll, tmp_path, name):
    with run_input(ellroll, tmp_path, name) as f:
        t, x = f["time"][()], f["trajectory/contact"][0]
        omega, energy = f["trajectory/omega"][0], f["trajectory/energy"][0]
        delta = f["case/rolling_resistance"][0]
    stop = last_move(x)
    assert t[stop] == pytest.approx(5 * HALF_PERIOD, rel=0.01)
    assert abs(x[-1, 0]) <= RHO * delta / RADIUS and np.all(x[:, 1] == 0)
    assert np.all(omega[stop:] == 0) and np.all(energy[stop:] == energy[-1])
    if name.startswith("rk4"):         # the couple only takes energy (on RK4's steps; vern9's samples
        assert np.all(np.diff(energy) <= 1e-9 * energy[0])   # come from dense output over 0.2 s steps)


def test_a_motion_that_rolls_on_loses_the_couples_work(ellroll, tmp_path):
    with run_input(ellroll, tmp_path, "dop853_fixed_rolls.nml") as f:
        t, x = f["time"][()], f["trajectory/contact"][0]
        force, normal = f["trajectory/reaction"][0], f["trajectory/normal"][0]
        omega, energy = f["trajectory/omega"][0], f["trajectory/energy"][0]
        delta = f["case/rolling_resistance"][0]
    assert last_move(x) == len(t) - 1                                    # no stop
    normal_force = np.sum(force * normal, axis=1)
    rolling = np.linalg.norm(omega - np.sum(omega * normal, axis=1)[:, None] * normal, axis=1)
    assert rolling.min() > 0.01
    power = -delta * normal_force * rolling
    work = np.r_[0.0, np.cumsum((power[1:] + power[:-1]) / 2 * np.diff(t))]
    loss = energy - energy[0]
    assert loss[-1] < -0.1
    assert np.abs(loss - work).max() < 1e-4 * abs(loss[-1])               # trapezoid rule on 10 ms samples


def test_a_cup_shaken_below_delta_g_over_r_leaves_the_ball_at_rest(ellroll, tmp_path):
    with run_input(ellroll, tmp_path, "rk4_moving_stops.nml") as f:
        t, x = f["time"][()], f["trajectory/contact"][0]
        base = f["trajectory/base_acceleration"][0]
        delta = f["case/rolling_resistance"][0]
    assert np.abs(base[:, 0]).max() < delta * G / RADIUS                   # the cup's pull cannot start it
    stop = last_move(x)
    assert 0 < t[stop] < t[-1] - 5                                        # it stopped, and stays
    assert np.hypot(x[-1, 0], x[-1, 1]) > 1e-3                              # away from the bottom


def test_a_cup_shaken_beyond_delta_g_over_r_starts_the_ball(ellroll, tmp_path):
    with run_input(ellroll, tmp_path, "vern9_moving_rolls.nml") as f:
        x = f["trajectory/contact"][0]
    assert np.all(x[0] == x[0]) and np.ptp(x[:, 0]) > 1e-6 and np.all(x[:, 1] == 0)


@pytest.mark.parametrize("name", sorted(p.name for p in INPUTS.glob("*.nml")))
def test_the_debug_build_checks_each_input(ellroll_debug, tmp_path, name):
    """The Debug build (floating-point traps) reads and checks each input, mu
    unset (NaN) included: the check against mu R compares with mu only
    where slip = 'slide' gives one."""
    (tmp_path / name).write_text((INPUTS / name).read_text())
    result = run(ellroll_debug, "check", name, cwd=tmp_path)
    assert result.returncode == 0 and f"{name}: ok" in result.stdout + result.stderr, result.stderr
