"""In-range inputs at the far ends of the documented ranges (axes and radius
1e-6..1e6 m, spins to 1e6 rad/s, masses to 1e12 kg) under the Debug build,
which traps invalid, zero-divide and overflow: the build never stops by a
signal; a case is refused with exit 2 or run to a recorded status. A cup
far deeper than wide (c >> a, b) has the bottom radii a^2/c, b^2/c, and a
ball that does not fit them is refused on every build."""
import random
import re

import h5py
import pytest

from conftest import run
from test_fuzz import CRASH_SIGNS

def status_of(path):
    with h5py.File(path) as f:
        status = f["summary/status"]
        names = dict(zip(status.attrs["flag_values"], status.attrs["flag_meanings"].split()))
        return names[status[0]]


def run_case(exe, folder, name, text):
    (folder / f"{name}.nml").write_text(text)
    result = run(exe, "run", f"{name}.nml", "-o", f"{name}.h5", "-q", "--overwrite", cwd=folder, timeout=120)
    detail = f"{name}:\n{text}\n{result.stdout}\n{result.stderr}"
    assert not any(sign in result.stderr for sign in CRASH_SIGNS), detail
    assert result.returncode in (0, 2), detail
    if result.returncode == 0:
        assert status_of(folder / f"{name}.h5") != "pending", detail
    return result


def deep_cups(seed, count):
    rng = random.Random(seed)
    for _ in range(count):
        a = 10 ** rng.uniform(-6, -2)
        b = a * rng.choice([1.0, 1.5, 10 ** rng.uniform(0, 1)])
        c = 10 ** rng.uniform(2, 6)
        radius = 10 ** rng.uniform(-6, -3)
        yield a, b, c, radius


@pytest.mark.parametrize("build", ["ellroll", "ellroll_debug"])
def test_a_ball_wider_than_a_deep_cup_is_refused_with_its_bottom_radii(request, tmp_path, build):
    exe = request.getfixturevalue(build)
    for k, (a, b, c, radius) in enumerate([(1e-6, 1e-6, 1e3, 1e-6), (1e-6, 1e-6, 1e2, 1e-6)]
                                          + list(deep_cups(20, 12))):
        name = f"cup{k}"
        text = (f"&geometry a = {a!r}, b = {b!r}, c = {c!r} /\n&ball radius = {radius!r}, weight = 1.0 /\n"
                "&initial omega = 0, 0, 0 /\n&integration dt = 1.0e-3, t_end = 0.01 /\n"
                f"&output file = '{name}.h5', interval = 1.0e-3 /\n")
        (tmp_path / f"{name}.nml").write_text(text)
        result = run(exe, "check", f"{name}.nml", cwd=tmp_path, timeout=60)
        detail = f"{text}\n{result.stdout}\n{result.stderr}"
        assert not any(sign in result.stderr for sign in CRASH_SIGNS), detail
        # a^2/c <= 1e-4 * 1e-2 < 1e-6 <= radius: no such ball fits
        assert result.returncode == 2, detail
        assert "the ball does not fit the cup at the start" in result.stderr, detail
        radii = [float(v) for v in re.search(r"there are (\S+) m and (\S+) m", result.stderr).groups()]
        assert radii == pytest.approx(sorted([a * a / c, b * b / c]), rel=1e-9), detail
        result = run(exe, "run", f"{name}.nml", "-q", cwd=tmp_path, timeout=60)
        assert result.returncode == 2 and not (tmp_path / f"{name}.h5").exists(), detail


def gauss4_fast_cases(seed, count):
    rng = random.Random(seed)
    for _ in range(count):
        a = rng.uniform(5e4, 2e5)
        radius = a * a / 1e6 * rng.choice([0.5, 0.9, 0.999, 0.999999])     # up to the bottom radius a^2/c
        omega = [1e6] + [rng.uniform(-1e6, 1e6) for _ in range(2)]
        yield (f"&geometry a = {a!r}, b = 1e6, c = 1e6 /\n&ball radius = {radius!r}, weight = 1.0 /\n"
               "&environment g = 9.81 /\n"
               f"&initial omega = {omega[0]!r}, {omega[1]!r}, {omega[2]!r} /\n"
               "&integration method = 'gauss4', dt = 1.0e-3, t_end = 0.01 /\n"
               "&output file = 'e.h5', interval = 1.0e-3 /\n")


def test_gauss4_on_large_fast_balls_ends_each_case_with_a_status(ellroll_debug, tmp_path):
    cases = ["&geometry a = 97166.96, b = 1e6, c = 1e6 /\n&ball radius = 9441.4, weight = 1.0 /\n"
             "&environment g = 9.81 /\n&initial omega = 1e6, -818109, -583183 /\n"
             "&integration method = 'gauss4', dt = 1.0e-3, t_end = 0.01 /\n"
             "&output file = 'e.h5', interval = 1.0e-3 /\n"] + list(gauss4_fast_cases(21, 8))
    for k, text in enumerate(cases):
        assert run_case(ellroll_debug, tmp_path, f"g{k}", text).returncode == 0


def screen_cases(seed, count):
    rng = random.Random(seed)
    for _ in range(count):
        a, b = rng.uniform(1e5, 1e6), rng.uniform(1e5, 1e6)
        y = b * rng.uniform(0.1, 0.5)
        mass = rng.choice([1e6, 1e9, 1e12])
        yield (f"&geometry a = {a!r}, b = {b!r}, c = 1e-06 /\n"
               f"&ball radius = 1e-06, mass = {mass!r}, mu = 1000000.0, slip = 'end', "
               "inertia_factor = 0.6666666666666666, rolling_resistance = 0.1 /\n&environment g = 0 /\n"
               f"&initial x = 0.0, y = {y!r}, omega = 1000000.0, 1000000.0, 1000000.0 /\n"
               "&integration method = 'dop853', dt = 1.0e-3, t_end = 0.01 /\n"
               "&excitation kind = 'harmonic', amplitude = -10000.0, -3333.3333333333335, -1428.5714285714287, "
               "frequency = 990734.1269921708, phase = -1000 /\n&output file = 'e.h5', interval = 1.0e-3 /\n")


def test_the_peak_screen_of_a_ball_whose_normal_force_vanishes_ends_with_a_status(ellroll_debug, tmp_path):
    cases = ["&geometry a = 592272.3041206562, b = 803107.1645036046, c = 1e-06 /\n"
             "&ball radius = 1e-06, mass = 1000000000000.0, mu = 1000000.0, slip = 'end', "
             "inertia_factor = 0.6666666666666666, rolling_resistance = 0.1 /\n&environment g = 0 /\n"
             "&initial x = 0.0, y = 240932.14935108137, omega = 1000000.0, 1000000.0, 1000000.0 /\n"
             "&integration method = 'dop853', dt = 1.0e-3, t_end = 0.01 /\n"
             "&excitation kind = 'harmonic', amplitude = -10000.0, -3333.3333333333335, -1428.5714285714287, "
             "frequency = 990734.1269921708, phase = -1000 /\n&output file = 'e.h5', interval = 1.0e-3 /\n"] \
        + list(screen_cases(22, 6))
    for k, text in enumerate(cases):
        assert run_case(ellroll_debug, tmp_path, f"p{k}", text).returncode == 0
