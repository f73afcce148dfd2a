"""time_beyond_capacity of the embedded pairs, whose steps are long (0.05 to
0.2 s on a shaken isolator): taken on the dense output, it agrees with rk4
at dt = 1e-4 s (whose crossings, linear between step ends, are within about
1e-8 s) to 1e-6 s at any tolerance and any output interval, where the step
ends alone cut the dips below the capacity or missed them (1.1e-2 s at
rtol 1e-12, 0.4 s at 1e-6). Seeded shakings, starts and capacities."""
import h5py
import numpy as np
import pytest

from conftest import run

BASE = """&geometry a = 1.0, b = 0.4, c = 0.2 /
&ball radius = 0.2, mass = 267.07 /
&initial x = {x!r}, y = {y!r}, omega = 0.5, -0.3, 3.0 /
&integration {integration}, t_end = 10.0 /
&output file = 'out.h5', interval = {interval!r}{capacity} /
&excitation kind = 'harmonic', amplitude = {ax!r}, {ay!r}, {az!r}, frequency = {frequency!r}, phase = {phase!r} /
"""


def summary(ellroll, folder, text):
    (folder / "case.nml").write_text(text)
    result = run(ellroll, "run", "case.nml", "-q", "--overwrite", cwd=folder)
    assert result.returncode == 0, result.stderr
    with h5py.File(folder / "out.h5", "r") as f:
        return {key: f["summary"][key][0] for key in ("status", "displacement_max", "time_beyond_capacity")}


@pytest.mark.parametrize("seed", range(3))
def test_the_pairs_time_beyond_the_capacity_is_the_dense_output_s(ellroll, tmp_path, seed):
    rng = np.random.default_rng(3300 + seed)
    scene = {"x": float(rng.uniform(-0.05, 0.05)), "y": float(rng.uniform(-0.03, 0.03)),
             "ax": float(rng.uniform(0.3, 1.0)), "ay": float(rng.uniform(-0.6, 0.6)), "az": float(rng.uniform(-3, 3)),
             "frequency": float(rng.uniform(0.4, 0.9)), "phase": float(rng.uniform(-3, 3))}
    rk4 = "method = 'rk4', dt = 1e-4"
    peak = summary(ellroll, tmp_path, BASE.format(integration=rk4, interval=10.0, capacity="", **scene))
    assert peak["status"] == 1, scene
    capacity = f", capacity = {float(peak['displacement_max'] * rng.uniform(0.3, 0.8))!r}"
    truth = summary(ellroll, tmp_path, BASE.format(integration=rk4, interval=10.0, capacity=capacity, **scene))
    assert 0 < truth["time_beyond_capacity"] < 10, (scene, truth)
    # (at rtol 1e-6 the path itself moves the crossings by up to about 1e-5 s)
    for integration, bound in (("method = 'dop853', rtol = 1e-9", 1e-6), ("method = 'vern9', rtol = 1e-12", 1e-6),
                               ("method = 'vern9', rtol = 1e-6", 1e-4)):
        for interval in (0.01, 10.0):
            pair = summary(ellroll, tmp_path, BASE.format(integration=integration, interval=interval,
                                                          capacity=capacity, **scene))
            label = (scene, capacity, integration, interval, pair, truth)
            assert pair["status"] == 1, label
            assert abs(pair["time_beyond_capacity"] - truth["time_beyond_capacity"]) < bound, label
