"""The maxima of Theta (nutation_maxima, nutation_period) where the motion
switches regime or starts at a turning point, against the maxima of the
stored Theta itself (1 ms samples, interior maxima counted by three
samples): seeded shaken sliding campaigns with many switches to rolling
(a state tracked again at its switch is no flat top of a rising Theta),
and releases from rest (Theta turns at t = 0: no rise before it, no
maximum), for every method that runs them."""
import h5py
import numpy as np
import pytest

from conftest import run

METHODS = {"rk4": "method = 'rk4', dt = 1e-4", "dop853": "method = 'dop853', rtol = 1e-9",
           "vern9": "method = 'vern9', rtol = 1e-10", "gauss4": "method = 'gauss4', dt = 1e-3"}
SHAKEN = """&geometry a = 1.0, b = 0.4, c = 0.2 /
&ball radius = 0.2, mass = 100.0, mu = 0.06, slip = 'slide' /
&initial x = 0.05, y = 0.0, omega = 0.0, 0.0, 0.0 /
&integration {integration}, t_end = 4.0 /
&excitation kind = 'harmonic', amplitude = 1.2, 0.7, 0.5, frequency = 0.9, phase = 0.4 /
&output file = 'out.h5', interval = 0.001, fields = 'nutation' /
&campaign samples = 6, seed = {seed} /
&sample name = 'excitation_amplitude_x', low = 0.5, high = 3.0 /
&sample name = 'excitation_frequency', low = 0.3, high = 1.5 /
&sample name = 'x', low = -0.1, high = 0.1 /
&sample name = 'omega_z', low = -5, high = 5 /
"""
RELEASED = """&geometry a = 1.0, b = 0.4, c = 0.2 /
&ball radius = 0.2, mass = 100.0 /
&initial x = {x!r}, y = {y!r}, omega = 0, 0, 0 /
&integration {integration}, t_end = 5.0 /
&output file = 'out.h5', interval = 0.001, fields = 'nutation' /
"""


def sample_maxima(theta, t):
    """The interior maxima of the samples (v1 < v2 >= v3) and their mean spacing (NaN below 3)."""
    inner = np.flatnonzero((theta[1:-1] > theta[:-2]) & (theta[1:-1] >= theta[2:])) + 1
    period = (t[inner[-1]] - t[inner[0]]) / (len(inner) - 1) if len(inner) >= 3 else np.nan
    return len(inner), period


def check_counts(ellroll, folder, text):
    (folder / "case.nml").write_text(text)
    result = run(ellroll, "run", "case.nml", "-q", "--overwrite", cwd=folder)
    assert result.returncode == 0, result.stderr
    with h5py.File(folder / "out.h5", "r") as f:
        t = f["time"][()]
        for i, theta in enumerate(f["trajectory/nutation"][()]):
            status = f["summary/status"][i]
            end = np.searchsorted(t, f["summary/t_final"][i], side="right")
            count, period = sample_maxima(theta[:end], t[:end])
            switches = f["summary/slip_episodes"][i] if "slip_episodes" in f["summary"] else 0
            detail = (i, status, switches, f["summary/nutation_maxima"][i], count)
            assert f["summary/nutation_maxima"][i] == count, detail
            if np.isnan(period):
                assert np.isnan(f["summary/nutation_period"][i]), detail
            else:
                # the samples' maxima are 1 ms apart at worst
                assert abs(f["summary/nutation_period"][i] - period) <= 2e-3 / (count - 1), detail


@pytest.mark.parametrize("method", ["rk4", "dop853", "vern9"])
@pytest.mark.parametrize("seed", [3, 11])
def test_switches_to_rolling_add_no_maximum(ellroll, tmp_path, method, seed):
    check_counts(ellroll, tmp_path, SHAKEN.format(integration=METHODS[method], seed=seed))


@pytest.mark.parametrize("method", list(METHODS))
def test_a_release_from_rest_is_no_maximum(ellroll, tmp_path, method):
    rng = np.random.default_rng(20261127)
    for k in range(3):
        x, y = (float(v) for v in rng.uniform([-0.2, -0.08], [0.2, 0.08]))
        folder = tmp_path / str(k)
        folder.mkdir()
        check_counts(ellroll, folder, RELEASED.format(x=x, y=y, integration=METHODS[method]))
