"""A ball without gravity (g = 0, a valid input) set at the bottom of a
fixed cup: nothing presses it on the cup (N = 0), so it lifts off at
t = 0; the friction ratio it would need is undefined (NaN, not the largest
number); of its linear modes about the bottom only the gyroscopic one
oscillates, at 2 pi (1 + k) sqrt(l1 l2) / (k R |sigma|) (l = a^2/c - R,
b^2/c - R), the other has frequency zero (NaN). The same on the Release
and the Debug build. Seeded cups, balls and spins."""
import math

import h5py
import numpy as np
import pytest

from conftest import run


@pytest.mark.parametrize("seed", range(3))
def test_a_ball_without_gravity_lifts_off_with_its_gyroscopic_mode(ellroll, ellroll_debug, tmp_path, seed):
    rng = np.random.default_rng(7700 + seed)
    a, b = float(rng.uniform(0.5, 2.0)), float(rng.uniform(0.3, 0.5))
    c = float(rng.uniform(0.1, 0.2))
    radius = float(0.5 * min(a * a, b * b) / c * rng.uniform(0.1, 0.9))
    k = float(rng.uniform(0.1, 0.6))
    sigma = float(rng.choice([-1, 1]) * rng.uniform(1.0, 50.0))
    method = str(rng.choice(["rk4", "gauss4", "dop853", "vern9"]))
    text = (f"&geometry a = {a!r}, b = {b!r}, c = {c!r} /\n"
            f"&ball radius = {radius!r}, mass = 3.0, inertia_factor = {k!r} /\n"
            "&environment g = 0.0 /\n"
            f"&initial x = 0.0, y = 0.0, omega = 0.0, 0.0, {sigma!r} /\n"
            f"&integration method = '{method}', dt = 1e-3, t_end = 1.0 /\n"
            "&output file = 'out.h5', interval = 0.5 /\n")
    (tmp_path / "case.nml").write_text(text)
    l1, l2 = a * a / c - radius, b * b / c - radius
    gyroscopic = 2 * math.pi * (1 + k) * math.sqrt(l1 * l2) / (k * radius * abs(sigma))
    results = []
    for exe in (ellroll, ellroll_debug):
        result = run(exe, "run", "case.nml", "-q", "--overwrite", cwd=tmp_path)
        assert result.returncode == 0, result.stderr
        with h5py.File(tmp_path / "out.h5", "r") as f:
            s = {key: f["summary"][key][0] for key in ("status", "t_final", "friction_needed_max", "linear_periods")}
        label = (text, str(exe), s)
        assert s["status"] == 5 and s["t_final"] == 0, label
        assert math.isnan(s["friction_needed_max"]), label
        # the slow mode's period is infinite without g: NaN, and the longer, first
        assert math.isnan(s["linear_periods"][0]), label
        assert s["linear_periods"][1] == pytest.approx(gyroscopic, rel=1e-9), label
        results.append(s["linear_periods"][1])
    assert results[0] == pytest.approx(results[1], rel=1e-12)
