"""The maxima of Theta (nutation_maxima, nutation_period) where the motion
switches regime or starts at a turning point, against the maxima of the
stored Theta itself (1 ms samples, interior maxima counted by three
samples): seeded shaken sliding campaigns with many switches to rolling
(a state tracked again at its switch is no flat top of a rising Theta),
releases from rest (Theta turns at t = 0: no rise before it, no
maximum), and a record shaking a ball that rests on the way, held by
rolling resistance (a rest is a maximum where Theta rises into it and
falls out of it, none where it rises or falls through it; the ball leaves
the bottom), for every method that runs them, at two output intervals."""
import h5py
import numpy as np
import pytest

from conftest import FULL, ROOT, pairs_in_turn, run

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
PAIRS = ("dop853", "vern9")
RESTING = """&geometry a = 1.0, b = 0.4, c = 0.2 /
&ball radius = 0.2, weight = 2620.0, rolling_resistance = 1.0e-3 /
&initial x = 0.0, y = 0.0, omega = 0.0, 0.0, 0.0 /
&integration {integration}, t_end = 10.0 /
&excitation kind = 'record', record_file = '{record}', scale = 2.0 /
&output file = 'out.h5', interval = {interval}, fields = 'nutation' /
&campaign samples = 3, seed = 5 /
&sample name = 'scale', low = 1.0, high = 3.0 /
&sample name = 'rolling_resistance', low = 5e-4, high = 2e-3 /
"""
RESTARTS = """&geometry a = 1.0, b = 0.4, c = 0.2 /
&ball radius = 0.19881653340707292, weight = 100.0, rolling_resistance = 0.005 /
&initial x = 0.05652699231526587, y = 0.007738113410130221, omega = 0.0, 0.0, 0.0 /
&integration {integration}, t_end = 8.0 /
&excitation kind = 'record', record_file = '{record}', scale = 2.2056802713921133 /
&output file = 'out.h5', interval = 1e-4, fields = 'nutation' /
"""
RELEASED = """&geometry a = 1.0, b = 0.4, c = 0.2 /
&ball radius = 0.2, mass = 100.0 /
&initial x = {x!r}, y = {y!r}, omega = 0, 0, 0 /
&integration {integration}, t_end = 5.0 /
&output file = 'out.h5', interval = 0.001, fields = 'nutation' /
"""


def sample_maxima(theta, t):
    """The interior maxima of the samples and their mean spacing (NaN
    below 3): a sample, or the first of a run of equal ones (a rest held by
    rolling resistance), with a lower one on each side."""
    first = np.flatnonzero(np.r_[True, theta[1:] != theta[:-1]])
    runs = theta[first]
    inner = first[np.flatnonzero((runs[1:-1] > runs[:-2]) & (runs[1:-1] > runs[2:])) + 1]
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


@pytest.mark.parametrize("method, interval", pairs_in_turn(METHODS, ["0.001", "0.002"]))
def test_rests_held_by_rolling_resistance_are_maxima_only_between_a_rise_and_a_fall(ellroll, tmp_path, method,
                                                                                     interval):
    """(Each method at one of the intervals in turn; every pair with
    ELLROLL_TEST_FULL.)"""
    record = ROOT / "input" / "records" / "synthetic_ground.csv"
    integration = METHODS[method].replace("rtol = 1e-9", "rtol = 1e-10") + ", dt = 0.01" * (method in PAIRS)
    check_counts(ellroll, tmp_path, RESTING.format(integration=integration, record=record, interval=interval))


@pytest.mark.parametrize("method", ["dop853", "vern9", *(["rk4", "gauss4"] if FULL else [])])
def test_a_ball_that_stops_and_sets_off_again_and_again_counts_each_maximum_once(ellroll, tmp_path, method):
    """A large rolling resistance (5 mm) under a record: the ball stops and
    sets off dozens of times. Setting off moves Theta by round-off (1e-15),
    a pair rises 2e-12 into a rest rk4 falls into, and a crawl of 3e-10 s
    steps meets one flat top twice: none of these is a maximum. The truth
    is rk4's samples at its steps (dop853's own samples, from its dense
    output, wiggle near the rests: 22 maxima where there are 20.) The
    pairs, whose rules these are; rk4 and gauss4 too with ELLROLL_TEST_FULL."""
    record = ROOT / "input" / "records" / "SYN1_H1.AT2"
    counts = {}
    for name in ("rk4", method):
        integration = METHODS[name].replace("rtol = 1e-9", "rtol = 1e-10").replace("dt = 1e-3", "dt = 1e-4")
        folder = tmp_path / name
        folder.mkdir(exist_ok=True)
        (folder / "case.nml").write_text(RESTARTS.format(integration=integration, record=record))
        result = run(ellroll, "run", "case.nml", "-q", "--overwrite", cwd=folder)
        assert result.returncode == 0, result.stderr
        with h5py.File(folder / "out.h5", "r") as f:
            counts[name] = (f["summary/nutation_maxima"][0], f["summary/nutation_period"][0],
                            *sample_maxima(f["trajectory/nutation"][0], f["time"][()]))
    samples, samples_period, summary, summary_period = counts["rk4"][2], counts["rk4"][3], *counts[method][:2]
    assert summary == samples == 20, counts
    assert abs(summary_period - samples_period) <= 2e-4 / (samples - 1), counts
