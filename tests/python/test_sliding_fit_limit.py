"""A ball that slides into the fit limit (where the cup's curvature radius
falls to the ball's): near the limit's square-root singularity a fixed
step's own last steps meet it late, far beyond its order (rk4 at dt =
1e-3 s: 3e-5 s), so a fixed-step case ends where the exact flow from a
checkpoint a few steps back meets it (docs/model.md, "Where a case ends").
Seeded sliding starts in the paper's cup, fixed and shaken, with and
without rolling resistance: rk4's end time against vern9 at rtol 1e-12,
the sliding time equal to it, and no sample after it."""
import h5py
import numpy as np
import pytest

from conftest import run

CUP = "&geometry a = 1.0, b = 0.4, c = 0.2 /\n"


def start(rng):
    """A sliding start near the cup's bottom, launched along the short axis
    (towards the sheet's tight curvature), and its scene."""
    x = float(rng.uniform(0.02, 0.08))
    vx, vy = float(rng.uniform(0.1, 0.4)), float(rng.choice([-1, 1]) * rng.uniform(1.4, 1.8))
    mu = float(rng.choice([0.03, 0.05, 0.08]))
    resistance = float(rng.choice([0.0, 1e-3]))
    shaken = bool(rng.random() < 0.5)
    return x, vx, vy, mu, resistance, shaken


def text(x, vx, vy, mu, resistance, shaken, integration):
    # the tangent vz at (x, 0) on the paper cup: v . n = 0 with n along (x / a^2, 0, z / c^2)
    z = -0.2 * np.sqrt(1 - x**2)
    vz = float(-vx * (x / 1.0**2) / (z / 0.2**2))
    lines = [CUP,
             f"&ball radius = 0.2, mass = 1.0, mu = {mu!r}, slip = 'slide', rolling_resistance = {resistance!r} /\n",
             f"&initial x = {x!r}, y = 0.0, omega = 0.0, 0.0, 0.0, velocity = {vx!r}, {vy!r}, {vz!r} /\n",
             f"&integration {integration}, t_end = 1.0 /\n",
             "&output file = 'out.h5', interval = 0.01 /\n"]
    if shaken:
        lines.append("&excitation kind = 'harmonic', amplitude = 2.0, 1.0, 0.0, frequency = 1.5 /\n")
    return "".join(lines)


def summary(ellroll, folder, name, nml):
    (folder / f"{name}.nml").write_text(nml.replace("'out.h5'", f"'{name}.h5'"))
    result = run(ellroll, "run", f"{name}.nml", "-q", cwd=folder)
    assert result.returncode == 0, result.stderr
    with h5py.File(folder / f"{name}.h5", "r") as f:
        figures = {key: f["summary"][key][0] for key in ("status", "t_final", "sliding_time", "slip_episodes")}
        figures["time"] = f["trajectory/time"][:]
        figures["center"] = f["trajectory/center"][0]
    return figures


@pytest.mark.parametrize("seed", range(6))
def test_a_fixed_step_ends_a_slide_into_the_fit_limit_where_the_exact_flow_does(ellroll, tmp_path, seed):
    rng = np.random.default_rng(4500 + seed)
    scene = start(rng)
    reference = summary(ellroll, tmp_path, "vern9", text(*scene, "method = 'vern9', rtol = 1e-12"))
    label = f"seed {seed}: {scene}"
    # every seeded start slides into the fit limit in one episode
    assert reference["status"] == 3 and reference["slip_episodes"] == 1, label
    assert reference["sliding_time"] == pytest.approx(reference["t_final"], abs=1e-12), label
    for dt in (1e-3, 2.5e-4):
        rk4 = summary(ellroll, tmp_path, f"rk4_{dt}", text(*scene, f"method = 'rk4', dt = {dt}"))
        assert rk4["status"] == 3, (label, dt)
        assert abs(rk4["t_final"] - reference["t_final"]) < 2e-9, (label, dt, rk4["t_final"], reference["t_final"])
        assert rk4["sliding_time"] == pytest.approx(rk4["t_final"], abs=1e-12), (label, dt)
        inside = rk4["time"] <= rk4["t_final"]
        assert np.all(np.isfinite(rk4["center"][inside])), (label, dt)
        assert np.all(np.isnan(rk4["center"][~inside])), (label, dt)


def fit_limit_theta(b, c, radius, margin):
    """Theta where a ball sliding up the y-z section of the cup stops
    fitting: the section's curvature (b c)^-2 / (y^2/b^4 + z^2/c^4)^(3/2)
    times radius (1 + margin) reaches 1 (the other principal curvature, along
    x, is smaller there); by bisection on the ellipse's angle."""
    def excess(phi):
        y, z = b * np.sin(phi), -c * np.cos(phi)
        return radius * (1 + margin) / (b * b * c * c * (y * y / b**4 + z * z / c**4) ** 1.5) - 1
    low, high = 0.0, np.pi / 2
    for _ in range(200):
        middle = (low + high) / 2
        low, high = (middle, high) if excess(middle) < 0 else (low, middle)
    y, z = b * np.sin(low), -c * np.cos(low)
    return np.arctan((y / b**2) / (abs(z) / c**2))


@pytest.mark.parametrize("integration", ["method = 'rk4', dt = 1e-4", "method = 'dop853', rtol = 1e-10",
                                         "method = 'dop853', rtol = 1e-12", "method = 'vern9', rtol = 1e-10",
                                         "method = 'vern9', rtol = 1e-12", "method = 'vern9', rtol = 1e-14"])
def test_every_method_slides_into_the_fit_limit_where_it_is(ellroll, tmp_path, integration):
    """A ball launched sliding up the cup's y-z section (it stays in it)
    ends where the section's curvature reaches 1 / (R (1 + fit_margin)):
    its largest Theta is the closed form's, and the embedded pairs' steps
    go on to it within their tolerance (a partial step past the tolerance
    is not the limit)."""
    text = ("&geometry a = 1.0, b = 0.4, c = 0.2 /\n"
            "&ball radius = 0.7, weight = 100.0, mu = 0.05, slip = 'slide' /\n"
            "&initial x = 0.0, y = 0.0, omega = 0.0, 0.0, 0.0, velocity = 0.0, 0.7, 0.0 /\n"
            f"&integration {integration}, t_end = 1.0, fit_margin = 1.0e-3 /\n"
            "&output file = 'out.h5', interval = 1.0e-3 /\n")
    figures = summary(ellroll, tmp_path, "case", text)
    with h5py.File(tmp_path / "case.h5", "r") as f:
        theta_max = f["summary/theta_max"][0]
    assert figures["status"] == 3, (integration, figures)
    assert abs(theta_max - fit_limit_theta(0.4, 0.2, 0.7, 1e-3)) < 1e-10, (integration, theta_max)
    # the end time of dop853 and vern9 at rtol 1e-14 (they agree to 2e-14 s)
    assert abs(figures["t_final"] - 0.01668353138409) < 2e-11, (integration, figures["t_final"])


ROLLING_INTO_THE_LIMIT = """&geometry a = 1.3739787267446895, b = 1.0050223695556615, c = 0.08088146783420326 /
&ball radius = 0.7400073816178254, mass = 78.89268133301036, inertia_factor = 0.6186746855486748{ball} /
&initial x = -0.2772070880830273, y = -0.28710143540818256, omega = -1.5691786315189653, -3.2365549718941296, -1.3113007154402954 /
&integration {integration}, t_end = 1.0 /
{scene}&output file = 'out.h5', interval = 0.01, fields = 'none' /
"""


@pytest.mark.parametrize("scene", ["", "&sweep name = 'omega_z', start = -1.4, stop = -1.2, count = 8 /\n",
                                   "&excitation kind = 'harmonic', amplitude = 0.6, 0.3, 0.8, frequency = 0.477 /\n"])
def test_a_ball_that_may_slide_rolls_into_the_fit_limit_where_the_exact_flow_does(ellroll, tmp_path, scene):
    """A ball that rolls into the fit limit with slip = 'slide' (mu too large
    for it ever to slide) ends as the rolling model does (slip = 'end'),
    bitwise, alone, in a batch of lanes and in a shaken cup, and within
    2e-9 s of vern9 at rtol 1e-13 with rk4 at dt = 1e-3. Its peaks, which
    grow without bound towards the limit, are taken on the exact flow up to
    where it leaves the cup's curvature, as slip = 'end' takes them: within
    1e-12 of them (a lane's last bits) and 1e-6 of vern9's (the steps' last
    end, 1e-3 s short of the limit, left them up to 38 % low)."""
    peaks = ("displacement_max", "displacement_max_time", "absolute_acceleration_max",
             "absolute_acceleration_max_time", "reaction_normal_max", "horizontal_force_max")

    def ends(ball, integration):
        (tmp_path / "case.nml").write_text(ROLLING_INTO_THE_LIMIT.format(ball=ball, integration=integration,
                                                                         scene=scene))
        result = run(ellroll, "run", "case.nml", "-q", "--overwrite", "--threads", "2", cwd=tmp_path)
        assert result.returncode == 0, result.stderr
        with h5py.File(tmp_path / "out.h5", "r") as f:
            assert np.all(f["summary/status"][:] == 3)          # no_fit
            return f["summary/t_final"][:], {key: f["summary"][key][:] for key in peaks}
    sliding, sliding_peaks = ends(", mu = 100.0, slip = 'slide'", "method = 'rk4', dt = 1e-3")
    rolling, rolling_peaks = ends(", mu = 100.0, slip = 'end'", "method = 'rk4', dt = 1e-3")
    assert np.array_equal(sliding, rolling)
    reference, reference_peaks = ends("", "method = 'vern9', rtol = 1e-13, atol = 1e-15")
    assert np.abs(sliding - reference).max() < 2e-9, sliding - reference
    for key in peaks:
        assert sliding_peaks[key] == pytest.approx(rolling_peaks[key], rel=1e-12, abs=0), key
        assert sliding_peaks[key] == pytest.approx(reference_peaks[key], rel=1e-6, abs=0), key
