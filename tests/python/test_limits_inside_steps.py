"""Outcomes that end a case inside a long step of the adaptive pairs, against
closed forms, for every method, on seeded sets of cases around the threshold.

Lift-off. A ball at rest at the bottom of a cup shaken vertically, a(t) =
A sin(2 pi f t + phase), stays at rest and N = m (g + a(t)): it lifts off
at the first root of g + A sin(2 pi f t + phase) (A > g), and never where
A < g. Rolling (the paper's cup), and sliding across a plate (a = b = 1e6,
c = 1e-6 m: curvature 1e-18 / m, so N = m (g + a(t)) to 1e-17 of itself)
launched with mu from 1e-12 to 1e-3, which slides throughout. N < 0 lasts
from 0.007 / f s (A = 1.001 g) to 0.19 / f s, inside one step of a pair at
rest (steps of 0.1 s and more), whose ends have N > 0. Every method holds
the state exactly (at rest, or moving uniformly), so only the location of
the root errs: 16 units in the last place of t (limit_time_ulps, 1e-15 s
here); the bound is 1e-12 s.

Rim. A ball launched from the bottom of a frictionless sphere cup (radius
r, ball R, mu = 1e-12) at s times the speed that reaches the rim, sqrt(2 g
(r - R)), s from 1.001 to 1.3, moves in a vertical plane and reaches n_z =
1e-6 (rim_level) at t = integral of (r - R) dphi / sqrt(v0^2 - 2 g (r - R)
(1 - cos phi)) from 0 to acos(1e-6) (energy). The bounds are each method's accuracy there, measured on these
seeds (worst in parentheses): the pairs 1e-8 s at rtol 1e-8 (3.1e-9 s), 3e-11 s
at rtol 1e-12 (1.0e-11 s, at any tolerance from 1e-10: the floor of these
runs); rk4 at dt = 1e-4 (1.7e-7 s) the rim's resolution in the sliding model,
rim_level times the cup's radius over the speed at the rim (docs/model.md:
2.6e-7 s and more here). The output interval (0.01 s or 0.5 s, where a
pair's sliding steps end) must not matter.
"""
import math

import h5py
import numpy as np
import pytest

from conftest import run

G = 9.81
RIM_LEVEL = 1.0e-6
T_END = 2.0
N_CASES = 12
STATUS = {"completed": 1, "rim": 2, "liftoff": 5}

# (method, its accuracy setting): the pairs at a loose and a tight tolerance
METHODS = [("rk4", "dt = 1e-3"), ("gauss4", "dt = 1e-3"), ("dop853", "rtol = 1e-8"), ("dop853", "rtol = 1e-11"),
           ("vern9", "rtol = 1e-8"), ("vern9", "rtol = 1e-12")]
# (method, its accuracy setting, the bound on the rim's time; None: the rim's resolution)
RIM_METHODS = [("rk4", "dt = 1e-4", None), ("dop853", "rtol = 1e-8", 1.0e-8), ("dop853", "rtol = 1e-12", 3.0e-11),
               ("vern9", "rtol = 1e-8", 1.0e-8), ("vern9", "rtol = 1e-12", 3.0e-11)]
LIFTOFF_TOLERANCE = 1.0e-12
INTERVALS = [0.01, T_END]


def run_campaign(exe, folder, name, text, sweeps):
    """The cases as a campaign of zipped sweeps (eight or more smooth cases
    run in SIMD batches): their statuses and end times."""
    text += "&campaign combine = 'zip' /\n"
    for key, values in sweeps.items():
        text += f"&sweep name = '{key}', values = {', '.join(repr(float(v)) for v in values)} /\n"
    (folder / f"{name}.nml").write_text(text)
    result = run(exe, "run", f"{name}.nml", "-q", "--overwrite", "-o", f"{name}.h5", cwd=folder, timeout=300)
    assert result.returncode == 0, result.stderr
    with h5py.File(folder / f"{name}.h5") as f:
        order = np.argsort(f["summary/case"][:]) if "case" in f["summary"] else slice(None)
        return f["summary/status"][:][order], f["summary/t_final"][:][order]


def first_liftoff(amplitude, frequency, phase):
    """The first t > 0 where g + A sin(2 pi f t + phase) = 0 (None: never)."""
    if amplitude <= G:
        return None
    s = math.asin(G / amplitude)
    roots = [(theta - phase) / (2 * math.pi * frequency)
             for k in range(3) for theta in (math.pi + s + 2 * math.pi * k, 2 * math.pi - s + 2 * math.pi * k)]
    return min(t for t in roots if t > 0)


def shaking_cases(seed):
    """Amplitudes from 1e-3 to 0.3 above g (9 of 12) and 1e-3 to 0.1 below,
    phases where N > 0.05 m g at the start, frequencies 0.8 to 2 Hz."""
    rng = np.random.default_rng(seed)
    cases = []
    while len(cases) < N_CASES:
        above = len(cases) < 9
        delta = 10 ** rng.uniform(-3, math.log10(0.3) if above else -1)
        amplitude = G * (1 + delta) if above else G * (1 - delta)
        phase = rng.uniform(0, 2 * math.pi)
        frequency = rng.uniform(0.8, 2.0)
        if G + amplitude * math.sin(phase) < 0.05 * G:
            continue
        cases.append(dict(amplitude=amplitude, phase=phase, frequency=frequency,
                          truth=first_liftoff(amplitude, frequency, phase)))
    return cases


def shaking_sweeps(cases):
    return {"excitation_amplitude_z": [c["amplitude"] for c in cases], "excitation_phase": [c["phase"] for c in cases],
            "excitation_frequency": [c["frequency"] for c in cases]}


def assert_liftoffs(cases, status, t_final, label):
    for case, s, t in zip(cases, status, t_final):
        if case["truth"] is None:
            assert s == STATUS["completed"] and t == T_END, (label, case, s, t)
        else:
            assert s == STATUS["liftoff"], (label, case, s, t)
            assert abs(t - case["truth"]) <= LIFTOFF_TOLERANCE, (label, case, t - case["truth"])


@pytest.mark.parametrize("interval", INTERVALS)
@pytest.mark.parametrize("method, accuracy", METHODS)
def test_a_ball_at_rest_in_a_shaken_cup_lifts_off_at_the_root_of_n(ellroll, tmp_path, method, accuracy, interval):
    cases = shaking_cases(seed=11)
    text = (f"&geometry a = 1.0, b = 0.4, c = 0.2 /\n&ball radius = 0.2, weight = 2620.0 /\n"
            f"&initial x = 0.0, y = 0.0, omega = 0.0, 0.0, 0.0 /\n"
            f"&integration method = '{method}', {accuracy}, t_end = {T_END!r} /\n"
            f"&output file = 'out.h5', interval = {interval!r}, fields = 'all' /\n"
            f"&excitation kind = 'harmonic', amplitude = 0.0, 0.0, 10.0, frequency = 1.0 /\n")
    status, t_final = run_campaign(ellroll, tmp_path, "rolling", text, shaking_sweeps(cases))
    assert_liftoffs(cases, status, t_final, (method, accuracy, interval))


@pytest.mark.parametrize("interval", INTERVALS)
@pytest.mark.parametrize("method, accuracy", [m for m in METHODS if m[0] != "gauss4"])     # (gauss4 does not slide)
def test_a_ball_sliding_across_a_shaken_plate_lifts_off_at_the_root_of_n(ellroll, tmp_path, method, accuracy,
                                                                          interval):
    cases = shaking_cases(seed=12)
    rng = np.random.default_rng(13)
    speed = rng.uniform(0.2, 2.0, N_CASES)
    direction = rng.uniform(0, 2 * math.pi, N_CASES)
    sweeps = dict(shaking_sweeps(cases), mu=10 ** rng.uniform(-12, -3, N_CASES),
                  velocity_x=speed * np.cos(direction), velocity_y=speed * np.sin(direction))
    text = (f"&geometry a = 1e6, b = 1e6, c = 1e-6 /\n"
            f"&ball radius = 0.1, mass = 1.0, mu = 0.001, slip = 'slide' /\n"
            f"&initial x = 0.0, y = 0.0, omega = 0.0, 0.0, 0.0, velocity = 1.0, 0.0, 0.0 /\n"
            f"&integration method = '{method}', {accuracy}, t_end = {T_END!r} /\n"
            f"&output file = 'out.h5', interval = {interval!r}, fields = 'all' /\n"
            f"&excitation kind = 'harmonic', amplitude = 0.0, 0.0, 10.0, frequency = 1.0 /\n")
    status, t_final = run_campaign(ellroll, tmp_path, "sliding", text, sweeps)
    assert_liftoffs(cases, status, t_final, (method, accuracy, interval))


def rim_time(cup, radius, v0):
    """When n_z falls to RIM_LEVEL (energy; Gauss-Legendre in phi: the
    integrand is smooth, the speed at the rim nonzero)."""
    rho = cup - radius
    phi_end = math.acos(RIM_LEVEL)
    x, w = np.polynomial.legendre.leggauss(200)
    phi = 0.5 * phi_end * (x + 1)
    return float(np.sum(0.5 * phi_end * w * rho / np.sqrt(v0**2 - 2 * G * rho * (1 - np.cos(phi)))))


def rim_cases(seed):
    rng = np.random.default_rng(seed)
    cases = []
    for _ in range(N_CASES):
        cup = rng.uniform(0.5, 2.0)
        radius = cup * rng.uniform(0.05, 0.3)
        factor = 1 + 10 ** rng.uniform(-3, math.log10(0.3))
        direction = rng.uniform(0, 2 * math.pi)
        v0 = factor * math.sqrt(2 * G * (cup - radius))
        rim_speed = math.sqrt(v0**2 - 2 * G * (cup - radius))
        cases.append(dict(cup=cup, radius=radius, vx=v0 * math.cos(direction), vy=v0 * math.sin(direction),
                          truth=rim_time(cup, radius, v0), resolution=RIM_LEVEL * cup / rim_speed))
    return cases


@pytest.mark.parametrize("interval", [0.01, 0.5])
@pytest.mark.parametrize("method, accuracy, tolerance", RIM_METHODS)
def test_a_ball_sliding_up_a_sphere_cup_reaches_the_rim_on_time(ellroll, tmp_path, method, accuracy, tolerance,
                                                               interval):
    cases = rim_cases(seed=21)
    assert max(c["truth"] for c in cases) < T_END
    sweeps = {key: [c[name] for c in cases]
              for key, name in (("a", "cup"), ("b", "cup"), ("c", "cup"), ("radius", "radius"),
                                ("velocity_x", "vx"), ("velocity_y", "vy"))}
    text = (f"&geometry a = 1.0, b = 1.0, c = 1.0 /\n"
            f"&ball radius = 0.1, weight = 10.0, mu = 1e-12, slip = 'slide' /\n"
            f"&initial x = 0.0, y = 0.0, omega = 0.0, 0.0, 0.0, velocity = 4.0, 0.0, 0.0 /\n"
            f"&integration method = '{method}', {accuracy}, t_end = {T_END!r} /\n"
            f"&output file = 'out.h5', interval = {interval!r}, fields = 'contact' /\n")
    status, t_final = run_campaign(ellroll, tmp_path, "rim", text, sweeps)
    for case, s, t in zip(cases, status, t_final):
        assert s == STATUS["rim"], (case, s, t)
        assert abs(t - case["truth"]) <= (case["resolution"] if tolerance is None else tolerance), \
            (case, t - case["truth"])
