"""The summary's figures at the edges of the number range, against scale
invariance: the rolling motion does not depend on the ball's mass, so
friction_needed_max and absolute_acceleration_max are the same for every
weight and horizontal_force_max / weight too; and a small motion is linear in
its size, so theta_max, displacement_max and the force figures divided by the
size are the same from 1e-300 to 1e-8 (the second-order terms are below 1e-16
of them), and nutation_period and the count of maxima do not change at all.
Seeded draws across the scales, with rk4 and gauss4 (fixed steps: the same
step ends at every scale), each as one campaign (8 cases or more: the batch's
lanes) and case by case in campaigns of 4 (the one-case path); and dop853,
whose steps follow its error estimate, with the figures it locates on its
dense output (theta_max, the nutation period)."""
import math
import random

import h5py
import numpy as np
import pytest

from conftest import run

PAPER_CUP = "&geometry a = 1.0, b = 0.4, c = 0.2 /\n"
FIXED = [("method = 'rk4', dt = 1e-3", False), ("method = 'rk4', dt = 1e-3", True),
         ("method = 'gauss4', dt = 1e-3", True)]
ADAPTIVE = "method = 'dop853', dt = 0.01, rtol = 1e-10, atol = 0.0"
METHODS = FIXED + [(ADAPTIVE, False)]
STEP_END_FIGURES = ("displacement_max", "friction_needed_max", "horizontal_force_max", "absolute_acceleration_max")


def summary(exe, folder, name, text, sweep, values, alone=False):
    """/summary of a campaign sweeping `sweep` over values: in one run, or
    (alone) in runs of 4 cases, below a batch, concatenated."""
    groups = [values[k:k + 4] for k in range(0, len(values), 4)] if alone else [values]
    parts = []
    for k, group in enumerate(groups):
        (folder / f"{name}{k}.nml").write_text(
            text + f"&sweep name = '{sweep}', values = {', '.join(repr(v) for v in group)} /\n")
        result = run(exe, "run", f"{name}{k}.nml", "-q", "-o", f"{name}{k}.h5", cwd=folder)
        assert result.returncode == 0, result.stderr
        with h5py.File(folder / f"{name}{k}.h5") as f:
            parts.append({key: f["summary"][key][:] for key in f["summary"]})
    return {key: np.concatenate([p[key] for p in parts]) for key in parts[0]}


def close(got, want, rtol, what):
    got, want = np.asarray(got, float), np.asarray(want, float)
    assert np.all(np.isnan(got) == np.isnan(want)), (what, got, want)
    both = ~np.isnan(want)
    error = np.abs(got[both] - want[both]) / np.abs(want[both])
    assert np.all(error <= rtol), (what, got[both], want[both], error.max())


def log_uniform(rng, low, high, n):
    return [10.0 ** rng.uniform(low, high) for _ in range(n)]


@pytest.mark.parametrize("method,alone", METHODS)
def test_friction_and_force_figures_do_not_depend_on_the_weight(ellroll, tmp_path, method, alone):
    """Paper's cup, rolling (no slip limit), the weight swept from 1e-300 N to
    1e6 N: the mass-free figures equal those at 2620 N, the horizontal force
    scales with the weight."""
    rng = random.Random(5)
    weights = [2620.0, 1.0e-300, 2.2250738585072014e-308 * 4, 1.0e-200, 1.0e-160, 1.0e6] + \
        log_uniform(rng, -300, 6, 6)
    text = (PAPER_CUP + "&ball radius = 0.2, weight = 2620.0 /\n"
            "&initial x = 0.0, y = 0.0, omega = -2.0, 2.0, 20.0 /\n"
            f"&integration {method}, t_end = 1.0 /\n"
            "&output file = 'w.h5', interval = 0.5, fields = 'none' /\n")
    s = summary(ellroll, tmp_path, "w", text, "weight", weights, alone)
    assert np.all(s["status"] == 1), s["status"]
    n = len(weights)
    for key in ("friction_needed_max", "absolute_acceleration_max", "theta_max", "displacement_max"):
        assert s[key][0] > 0, key
        close(s[key], np.full(n, s[key][0]), 1e-13, key)
    close(s["horizontal_force_max"] / np.array(weights), np.full(n, s["horizontal_force_max"][0] / 2620.0), 1e-13,
          "horizontal_force_max / weight")
    close(s["reaction_normal_max"] / np.array(weights), np.full(n, s["reaction_normal_max"][0] / 2620.0), 1e-13,
          "reaction_normal_max / weight")


@pytest.mark.parametrize("method,alone", METHODS)
def test_a_light_ball_slips_where_a_heavy_one_does(ellroll, tmp_path, method, alone):
    """mu = 0.05 below the 0.0759 the start needs: every weight ends 'slip' at
    t = 0 with the same friction_needed_max."""
    rng = random.Random(6)
    weights = [2620.0, 1.0e-300, 1.0e-200, 1.0e-160] + log_uniform(rng, -300, 6, 5)
    text = (PAPER_CUP + "&ball radius = 0.2, weight = 2620.0, mu = 0.05 /\n"
            "&initial x = 0.0, y = 0.0, omega = -2.0, 2.0, 20.0 /\n"
            f"&integration {method}, t_end = 0.5 /\n"
            "&output file = 'w.h5', interval = 0.5, fields = 'none' /\n")
    s = summary(ellroll, tmp_path, "slip", text, "weight", weights, alone)
    assert np.all(s["status"] == 4), s["status"]
    assert np.all(s["t_final"] == 0), s["t_final"]
    assert 0.0759 < s["friction_needed_max"][0] < 0.0760
    close(s["friction_needed_max"], np.full(len(weights), s["friction_needed_max"][0]), 1e-13, "friction_needed_max")


def scaled_figures(s, sizes, keys):
    return {key: s[key] / np.array(sizes) for key in keys}


@pytest.mark.parametrize("method,alone", METHODS)
def test_a_tiny_start_off_the_bottom_scales_down_to_1e_300(ellroll, tmp_path, method, alone):
    """The ball released at x from 1e-12 down to 1e-300, at rest and spinning
    about the vertical (12 s: Theta's maxima at every half period of x):
    theta_max / x, displacement_max / x and the force figures / x as at
    x = 1e-12, the nutation period and maxima the same."""
    rng = random.Random(7)
    sizes = [1.0e-12, 1.0e-150, 1.0e-160, 1.0e-170, 1.0e-300] + log_uniform(rng, -300, -8, 6)
    keys = ("theta_max",) + (() if method == ADAPTIVE else STEP_END_FIGURES)
    for spin in (0.0, 3.0):
        text = (PAPER_CUP + "&ball radius = 0.2, weight = 2620.0 /\n"
                f"&initial x = 1e-9, y = 0.0, omega = 0.0, 0.0, {spin} /\n"
                f"&integration {method}, t_end = 12.0 /\n"
                "&output file = 'x.h5', interval = 0.5, fields = 'none' /\n")
        s = summary(ellroll, tmp_path, f"x{spin}", text, "x", sizes, alone)
        assert np.all(s["status"] == 1), s["status"]
        for key, values in scaled_figures(s, sizes, keys).items():
            assert values[0] > 0, key
            close(values, np.full(len(sizes), values[0]), 1e-9, f"{key} / x, spin {spin}")
        assert np.all(s["nutation_maxima"] == s["nutation_maxima"][0]), s["nutation_maxima"]
        close(s["nutation_period"], np.full(len(sizes), s["nutation_period"][0]), 1e-9, "nutation_period")
    assert s["nutation_maxima"][0] >= 3 and s["nutation_period"][0] > 0


@pytest.mark.parametrize("method,alone", METHODS)
def test_a_tiny_harmonic_and_record_scale_down_to_1e_300(ellroll, tmp_path, method, alone):
    """The ball at rest at the bottom under a horizontal harmonic (amplitude
    from 1e-12 down to 1e-300 m/s^2) and a record (scale likewise): every
    motion figure / size as at 1e-12."""
    rng = random.Random(8)
    sizes = [1.0e-12, 1.0e-170, 1.0e-300] + log_uniform(rng, -300, -8, 5)
    keys = ("theta_max",) + (() if method == ADAPTIVE else STEP_END_FIGURES)
    times = np.arange(0.0, 1.5, 0.01)
    (tmp_path / "ground.csv").write_text(
        "".join(f"{t!r}, {math.sin(5 * t) * math.exp(-t)!r}, {0.5 * math.sin(9 * t)!r}\n" for t in times.tolist()))
    base = (PAPER_CUP + "&ball radius = 0.2, weight = 2620.0 /\n"
            "&initial x = 0.0, y = 0.0, omega = 0.0, 0.0, 0.0 /\n"
            f"&integration {method}, t_end = 2.0 /\n"
            "&output file = 'h.h5', interval = 0.5, fields = 'none' /\n")
    harmonic = base + "&excitation kind = 'harmonic', amplitude = 1.0, 0.0, 0.0, frequency = 1.3 /\n"
    record = base + "&excitation kind = 'record', record_file = 'ground.csv' /\n"
    for name, text, sweep in (("harmonic", harmonic, "excitation_amplitude_x"), ("record", record, "scale")):
        s = summary(ellroll, tmp_path, name, text, sweep, sizes, alone)
        assert np.all(s["status"] == 1), (name, s["status"])
        for key, values in scaled_figures(s, sizes, keys).items():
            assert values[0] > 0, (name, key)
            close(values, np.full(len(sizes), values[0]), 1e-9, f"{name}: {key} / size")
