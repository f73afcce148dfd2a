"""A ball with rolling resistance swinging in a plane of a cup stops at
each turn: a pair's step cut there has its last stages at the stop, where
omega_t is zero to within the stages' error. Its dense output must still be
the flow up to the stop.
- Seeded swings in a fixed cup (cup, ball, start, delta), dop853 and vern9
  with long steps: the couple's work equals the energy lost, E(0) -
  E(t_end) from the stored energies (the cup is fixed: nothing else takes
  energy), the balance's residual stays at round-off, and the samples agree
  with the method's own at a short largest step (its steps end near every
  sample) to 1e-9 m.
- Seeded swings in a shaken cup (vertical or horizontal harmonic shaking):
  every sample of dop853 and vern9 agrees with rk4 at dt = 1e-4 s (whose
  error there is below 1e-13 m) to 1e-11 m and 1e-10 rad/s."""
import h5py
import numpy as np
import pytest

from conftest import run


def swing(rng):
    a, b = rng.uniform(0.6, 1.0), rng.uniform(0.3, 0.9)
    c = rng.uniform(0.2, 0.35)
    radius = rng.uniform(0.04, 0.1)
    along_x = bool(rng.random() < 0.5)
    start = rng.uniform(0.05, 0.1) * (a if along_x else b)
    delta = rng.uniform(2e-4, 6e-4)
    x, y = (start, 0.0) if along_x else (0.0, start)
    return (f"&geometry a = {a!r}, b = {b!r}, c = {c!r} /\n"
            f"&ball radius = {radius!r}, weight = 100.0, rolling_resistance = {delta!r} /\n"
            f"&initial x = {x!r}, y = {y!r}, omega = 0.0, 0.0, 0.0 /\n")


def figures(ellroll, folder, name, text):
    (folder / f"{name}.nml").write_text(text)
    result = run(ellroll, "run", f"{name}.nml", "-q", "-o", f"{name}.h5", cwd=folder)
    assert result.returncode == 0, result.stderr
    with h5py.File(folder / f"{name}.h5", "r") as f:
        s = {key: f["summary"][key][0] for key in ("status", "rolling_resistance_energy", "energy_drift")}
        s["energy"] = f["trajectory/energy"][0]
        s["contact"] = f["trajectory/contact"][0]
        s["omega"] = f["trajectory/omega"][0]
    return s


@pytest.mark.parametrize("seed", range(4))
@pytest.mark.parametrize("method", ["method = 'vern9', rtol = 1e-12", "method = 'dop853', rtol = 1e-11"])
def test_a_pairs_step_cut_at_a_stop_keeps_the_flow_in_its_dense_output(ellroll, tmp_path, seed, method):
    scene = swing(np.random.default_rng(9300 + seed))
    tail = "t_end = 4.0 /\n&output interval = 0.02 /\n"
    long_steps = figures(ellroll, tmp_path, "long", scene + f"&integration {method}, dt = 0.1, {tail}")
    short_steps = figures(ellroll, tmp_path, "short", scene + f"&integration {method}, dt = 0.004, {tail}")
    label = (seed, method, scene)
    assert long_steps["status"] == 1, label
    lost = long_steps["energy"][0] - long_steps["energy"][-1]
    assert long_steps["rolling_resistance_energy"] == pytest.approx(lost, rel=1e-11, abs=1e-13), label
    assert long_steps["energy_drift"] < 1e-12, label
    assert np.abs(long_steps["contact"] - short_steps["contact"]).max() < 1e-9, label
    assert np.abs(long_steps["omega"] - short_steps["omega"]).max() < 1e-8, label


SHAKEN_SWING = """&geometry a = 1.0, b = 0.4, c = 0.2 /
&ball radius = 0.2, mass = 5.0, rolling_resistance = {delta!r} /
&initial x = 0.0, y = {y0!r}, omega = 0.0, 0.0, 0.0 /
&integration {method}, t_end = 4.0 /
&excitation kind = 'harmonic', amplitude = {amplitude}, frequency = {frequency!r} /
&output interval = 0.001 /
"""


@pytest.mark.parametrize("seed", range(4))
def test_a_pairs_samples_before_a_stop_in_a_shaken_cup_are_the_flows(ellroll, tmp_path, seed):
    rng = np.random.default_rng(9100 + seed)
    vertical = seed % 2 == 0
    shake = float(rng.uniform(1.0, 6.0) if vertical else rng.uniform(0.3, 1.0))
    scene = dict(delta=float(rng.uniform(1e-4, 2e-3)), y0=float(rng.uniform(0.02, 0.05)),
                 amplitude=f"0.0, 0.0, {shake!r}" if vertical else f"0.0, {shake!r}, 0.0",
                 frequency=float(rng.uniform(0.5, 2.0)))
    paths = {}
    for label, method in (("reference", "method = 'rk4', dt = 1e-4"),
                          ("vern9", "method = 'vern9', rtol = 1e-12, atol = 1e-14"),
                          ("dop853", "method = 'dop853', rtol = 1e-12, atol = 1e-14")):
        s = figures(ellroll, tmp_path, label, SHAKEN_SWING.format(method=method, **scene))
        assert s["status"] == 1, (label, scene)
        with h5py.File(tmp_path / f"{label}.h5", "r") as f:
            paths[label] = f["trajectory/center"][0], s["omega"]
    reference = paths.pop("reference")
    for label, (center, omega) in paths.items():
        assert np.abs(center - reference[0]).max() < 1e-11, (label, scene)
        assert np.abs(omega - reference[1]).max() < 1e-10, (label, scene)
