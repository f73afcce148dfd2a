"""A maximum of Theta and the next minimum inside one long step of dop853
or vern9 (dTheta/dt rising at both ends): a shaken paper-cup case whose
Theta wiggles for 0.05 s between two maxima, and seeded ones like it. The
maxima behind nutation_period are those of vern9 at rtol 1e-12 with steps of
at most 0.01 s (its steps end around every wiggle): their count and the
period to 1e-7 s at rtol 1e-6 and 1e-7."""
import h5py
import numpy as np
import pytest

from conftest import run

SCENE = ("&geometry a = 1.0, b = 0.4, c = 0.2 /\n&ball radius = 0.1, weight = 2620.0 /\n"
         "&initial x = {x!r}, y = {y!r}, omega = 1, -1, 15 /\n"
         "&integration {integration}, t_end = 5.0 /\n"
         "&excitation kind = 'harmonic', amplitude = 2.0, -1.5, 4.0, frequency = 1.7, phase = {phase!r} /\n"
         "&output file = 'out.h5', interval = 0.5 /\n")


def nutation(ellroll, folder, name, **scene):
    (folder / f"{name}.nml").write_text(SCENE.format(**scene))
    result = run(ellroll, "run", f"{name}.nml", "-q", "-o", f"{name}.h5", cwd=folder)
    assert result.returncode == 0, result.stderr
    with h5py.File(folder / f"{name}.h5", "r") as f:
        return f["summary/nutation_maxima"][0], f["summary/nutation_period"][0]


@pytest.mark.parametrize("seed", range(4))
def test_a_step_holding_a_maximum_and_the_next_minimum_finds_the_maximum(ellroll, tmp_path, seed):
    rng = np.random.default_rng(6100 + seed)
    x, y, phase = (0.1, -0.05, 1.1) if seed == 0 else (float(rng.uniform(0.05, 0.12)),
                                                         float(rng.uniform(-0.08, 0.0)), float(rng.uniform(0, 6)))
    reference = nutation(ellroll, tmp_path, "reference", x=x, y=y, phase=phase,
                         integration="method = 'vern9', rtol = 1e-12, dt = 0.01")
    for integration in ("method = 'vern9', rtol = 1e-6", "method = 'vern9', rtol = 1e-7",
                        "method = 'dop853', rtol = 1e-6"):
        name = integration.split("'")[1] + integration.split("= ")[-1]
        count, period = nutation(ellroll, tmp_path, name, x=x, y=y, phase=phase, integration=integration)
        label = (seed, x, y, phase, integration)
        assert count == reference[0], (label, count, reference)
        assert abs(period - reference[1]) < 1e-7, (label, period, reference)
