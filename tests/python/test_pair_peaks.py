"""The embedded pairs' (dop853, vern9) summary maxima of the displacement,
horizontal force, absolute acceleration, normal force and friction needed,
and the times of the displacement's and acceleration's, against the stored
samples and against independent truth.

- The samples come from the pair's dense output between step ends; the
  maxima are located on the same dense output (docs/output.md), so no
  stored sample is above its figure (to round-off).
- The scenes: a spinning ball in the fixed cup, harmonic shaking at several
  frequencies, a ground record, rolling resistance under shaking along three
  axes, and sliding (mu = 0.1) under strong shaking.
- The truth is RK4 at dt 1e-4 with every step end in its summary: its
  step-end maxima are within about 1e-8 of the motion's (relative) at
  these frequencies. The pairs' figures converge to it with rtol.
"""
import pathlib
import random

import h5py
import numpy as np
import pytest

from conftest import run

ROOT = pathlib.Path(__file__).resolve().parents[2]
RECORD = ROOT / "input" / "records" / "synthetic_ground.csv"
CUP = "&geometry a = 1.0, b = 0.4, c = 0.2 /\n"
AT_REST = "&initial x = 0.0, y = 0.0, omega = 0.0, 0.0, 0.0 /\n"
PEAKS = ["displacement_max", "horizontal_force_max", "absolute_acceleration_max", "reaction_normal_max",
         "friction_needed_max"]
INTERVAL = 0.005


def _scene(kind, seed):
    """The &ball, &initial and &excitation groups of a seeded scene, and its t_end."""
    rng = random.Random(seed)
    ball = "&ball radius = 0.2, weight = 2620.0"
    if kind == "fixed_cup":
        start = "&initial x = {:.6g}, y = {:.6g}, omega = {:.6g}, {:.6g}, {:.6g} /\n".format(
            rng.uniform(0.02, 0.1), rng.uniform(0.0, 0.05), rng.uniform(-2, 2), rng.uniform(-2, 2), rng.uniform(5, 25))
        return ball + " /\n" + start, "", 10.0
    if kind == "harmonic":
        amplitude = (rng.uniform(0.02, 0.06), rng.uniform(0.0, 0.04), 0.0)
        frequency = rng.choice([0.15, 0.3, 0.5, 0.9])
        t_end = 20.0
    elif kind == "rolling_resistance":
        ball += ", rolling_resistance = 2e-3"
        amplitude = (rng.uniform(0.3, 0.6), rng.uniform(0.2, 0.4), rng.uniform(0.5, 1.0))
        frequency = rng.uniform(0.4, 0.8)
        t_end = 15.0
    elif kind == "slide":
        ball += ", mu = 0.1, slip = 'slide'"
        amplitude = (rng.uniform(1.3, 1.6), rng.uniform(0.3, 0.6), 0.0)
        frequency = 0.5
        t_end = 10.0
    else:
        return ball + " /\n" + AT_REST, f"&excitation kind = 'record', record_file = '{RECORD}' /\n", 20.0
    excitation = ("&excitation kind = 'harmonic', amplitude = {:.6g}, {:.6g}, {:.6g}, frequency = {:.6g} /\n"
                  .format(*amplitude, frequency))
    return ball + " /\n" + AT_REST, excitation, t_end


def _run(exe, folder, name, scene, integration):
    ball, excitation, t_end = scene
    text = (CUP + ball + excitation + f"&integration {integration}, t_end = {t_end} /\n"
            f"&output file = '{name}.h5', interval = {INTERVAL}, fields = 'reaction', 'center', 'normal' /\n")
    (folder / f"{name}.nml").write_text(text)
    done = run(exe, "run", f"{name}.nml", "-q", "-o", f"{name}.h5", cwd=folder)
    assert done.returncode == 0, done.stderr
    with h5py.File(folder / f"{name}.h5") as f:
        summary = {k: f["summary"][k][0] for k in f["summary"]}
        reaction, normal, center = (f["trajectory"][k][0] for k in ("reaction", "normal", "center"))
        times = f["trajectory/time"][:]
        mass = float(f["case/mass"][0])
    normal_force = np.einsum("ij,ij->i", reaction, normal)
    horizontal = np.hypot(reaction[:, 0], reaction[:, 1])
    samples = {"displacement_max": np.hypot(center[:, 0], center[:, 1]),
               "horizontal_force_max": horizontal,
               "absolute_acceleration_max": horizontal / mass,
               "reaction_normal_max": normal_force,
               "friction_needed_max": np.linalg.norm(reaction - normal_force[:, None] * normal, axis=1) / normal_force}
    return summary, samples, times


@pytest.mark.parametrize("kind,seed", [("fixed_cup", 6), ("fixed_cup", 7), ("harmonic", 1), ("harmonic", 2), ("harmonic", 3), ("record", 0),
                                       ("rolling_resistance", 4), ("slide", 5)])
def test_pair_maxima_are_above_the_samples_and_converge(ellroll, tmp_path, kind, seed):
    scene = _scene(kind, seed)
    truth, _, _ = _run(ellroll, tmp_path, "truth", scene, "method = 'rk4', dt = 1e-4")
    for method in ("dop853", "vern9"):
        for rtol, bound in ((1e-6, 2e-5), (1e-9, 2e-7)):
            s, samples, times = _run(ellroll, tmp_path, f"{method}_{rtol}", scene,
                                     f"method = '{method}', rtol = {rtol}")
            assert s["t_final"] == truth["t_final"]
            for name in PEAKS:
                top = samples[name].max()
                assert s[name] >= top * (1 - 1e-12), (method, rtol, name, s[name], top)
                assert abs(s[name] - truth[name]) <= bound * truth[name], (method, rtol, name, s[name], truth[name])
            # the times follow the maxima: a sample within one interval of
            # the time has nearly the figure's value
            for name, value in (("displacement_max", "displacement_max"),
                                ("absolute_acceleration_max", "absolute_acceleration_max")):
                near = np.abs(times - s[name + "_time"]) <= INTERVAL
                assert near.any() and samples[value][near].max() >= s[value] * (1 - 1e-3), (method, rtol, name)
