"""A sliding start (&initial velocity) whose slip is tiny: round-off of
R omega x n up to 1e-8 m/s, where rolling needs friction well within mu N.
The exact motion stops the slip within |u0| / (kappa (mu N - |F_req|)) (far
below a step), taking about |u0|^2 / (2 kappa) of energy, and rolls on as
the rolling start (no velocity) does. Against that truth, for every method
and the Debug build: the slip never grows, the sliding time and the
friction's work stay within their bounds (the work is never negative), and
the path is the rolling start's (docs/model.md, "Sliding to rolling")."""
import h5py
import numpy as np
import pytest

from conftest import run

A, B, C, R, MU = 1.0, 0.4, 0.2, 0.2, 0.5
K, G = 0.4, 9.81                                   # J = K m R^2, the model's default gravity
METHODS = {"rk4": "method = 'rk4', dt = 1e-3",
           "dop853": "method = 'dop853', rtol = 1e-10", "vern9": "method = 'vern9', rtol = 1e-12"}
CASE = """&geometry a = {a}, b = {b}, c = {c} /
&ball radius = {r}, mass = 1.0, mu = {mu}, slip = 'slide' /
&initial x = {x!r}, y = {y!r}, omega = {omega}{velocity} /
&integration {integration}, t_end = 0.5 /
&output interval = 0.01, fields = 'center', 'normal', 'omega' /
"""


def starts(seed=20261127, count=3):
    """Seeded starts inside the paper's cup whose rolling needs at most mu / 2."""
    rng = np.random.default_rng(seed)
    for _ in range(count):
        yield (float(rng.uniform(-0.25, 0.25)), float(rng.uniform(-0.08, 0.08)),
               [float(v) for v in rng.uniform(-3, 3, 2)] + [float(rng.uniform(-25, 25))],
               float(rng.uniform(0, 2 * np.pi)))


def run_case(exe, folder, name, x, y, omega, integration, velocity=None):
    text = CASE.format(a=A, b=B, c=C, r=R, mu=MU, x=x, y=y, omega=", ".join(repr(w) for w in omega),
                       integration=integration,
                       velocity="" if velocity is None else ", velocity = " + ", ".join(repr(float(v))
                                                                                         for v in velocity))
    (folder / f"{name}.nml").write_text(text)
    result = run(exe, "run", f"{name}.nml", "-q", "--overwrite", "-o", f"{name}.h5", cwd=folder)
    assert result.returncode == 0, result.stderr
    with h5py.File(folder / f"{name}.h5", "r") as f:
        out = {k: f["summary"][k][0] for k in f["summary"]}
        for k in f["trajectory"]:
            out[k] = f["trajectory"][k][0]
    return out


@pytest.fixture(scope="module")
def rolling_starts(ellroll, tmp_path_factory):
    """Each start rolling (no velocity), per method: the truth's path."""
    folder = tmp_path_factory.mktemp("rolling")
    found = {}
    for i, (x, y, omega, _) in enumerate(starts()):
        for method, integration in METHODS.items():
            found[i, method] = run_case(ellroll, folder, f"roll_{i}_{method}", x, y, omega, integration)
    return found


@pytest.mark.parametrize("build", ["release", "debug"])
@pytest.mark.parametrize("method", list(METHODS))
@pytest.mark.parametrize("slip", [0.0, 1e-17, 1e-15, 1e-13, 1e-11, 1e-9])
def test_tiny_slip_stops_at_once(ellroll, ellroll_debug, rolling_starts, tmp_path, build, method, slip):
    exe = ellroll if build == "release" else ellroll_debug
    for i, (x, y, omega, angle) in enumerate(starts()):
        rolling = rolling_starts[i, method]
        assert rolling["status"] == 1
        assert rolling["friction_needed_max"] < MU / 2
        n = rolling["normal"][0]
        tangent = np.cross(n, [0.0, 0.0, 1.0])
        tangent /= np.linalg.norm(tangent)
        across = np.cross(n, tangent)
        u0 = slip * (np.cos(angle) * tangent + np.sin(angle) * across)
        velocity = R * np.cross(rolling["omega"][0], n) + u0
        out = run_case(exe, tmp_path, f"slide_{i}", x, y, omega, METHODS[method], velocity)
        size = np.linalg.norm(u0)
        kappa = 1 + 1 / K                                  # 1/m + R^2/J, per unit mass
        normal_force = G                                  # at most about g near the bottom of this cup
        stop_bound = 2 * size / (kappa * MU * normal_force / 2)   # |F_req| < mu N / 2 there
        assert out["slip_speed_max"] <= size * (1 + 1e-6) + 1e-14, (i, out["slip_speed_max"])
        assert out["sliding_time"] <= stop_bound + 1e-14, (i, out["sliding_time"], stop_bound)
        assert out["slip_episodes"] <= 1
        assert 0 <= out["friction_energy"] <= 4 * size**2 / kappa + 1e-30, (i, out["friction_energy"])
        # the path is the rolling start's: the stop moves it by about |u0| times the stop's time
        np.testing.assert_allclose(out["center"], rolling["center"], rtol=0, atol=1e-9)
