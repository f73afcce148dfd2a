"""Summary figures of sliding cases against what the model fixes them to:
the friction's work over a slip shorter than a step (a stiff slip, mu up
to 1e4) equals the energy the motion lost in a fixed cup (every method,
every step size), and the friction ratio |F_t| / N of a sliding ball is mu
up to a lift-off, where N falls to zero, at any tolerance and output
interval."""
import h5py
import numpy as np
import pytest

from conftest import run

CUP = "&geometry a = 1.0, b = 0.4, c = 0.2 /\n"
STIFF = CUP + """&ball radius = 0.2, mass = 100.0, mu = {mu}, slip = 'slide' /
&initial x = 0.1, y = 0.05, omega = 0.5, 0.5, 5.0, velocity = 0.3, -0.4, -0.019248218264302413 /
&integration {integration}, t_end = 0.5 /
&output interval = 0.01, fields = 'energy' /
"""
LIFTING = CUP + """&ball radius = 0.2, mass = 100.0, mu = 0.3, slip = 'slide' /
&initial x = 0.05, y = 0.02, omega = 0.0, 8.0, 0.0, velocity = 0.2, 0.1, 0.004511292364053771 /
&integration {integration}, t_end = 0.32 /
&excitation kind = 'harmonic', amplitude = 0, 0, 14.0, frequency = 2.0 /
&output interval = {interval}, fields = 'reaction', 'normal' /
"""


def run_text(ellroll, folder, text):
    (folder / "case.nml").write_text(text)
    result = run(ellroll, "run", "case.nml", "-q", "--overwrite", "-o", "out.h5", cwd=folder)
    assert result.returncode == 0, result.stderr
    return h5py.File(folder / "out.h5", "r")


@pytest.mark.parametrize("mu", [100.0, 1000.0, 1.0e4])
@pytest.mark.parametrize("integration", ["method = 'rk4', dt = 1e-3", "method = 'rk4', dt = 1.25e-4",
                                         "method = 'dop853', rtol = 1e-10", "method = 'vern9', rtol = 1e-12"])
def test_a_slip_shorter_than_a_step_takes_the_energy_lost(ellroll, tmp_path, mu, integration):
    with run_text(ellroll, tmp_path, STIFF.format(mu=mu, integration=integration)) as f:
        summary = f["summary"]
        energy = f["trajectory/energy"][0]
        assert summary["slip_episodes"][0] == 1 and summary["sliding_time"][0] < 1e-4
        lost = energy[0] - energy[-1]
        assert lost > 1.3
        assert abs(summary["friction_energy"][0] - lost) <= 1e-9 * lost, (summary["friction_energy"][0], lost)
        assert abs(summary["energy_drift"][0]) <= 1e-10


@pytest.mark.parametrize("interval", [0.01, 1e-5])
@pytest.mark.parametrize("integration", ["method = 'rk4', dt = 1e-5", "method = 'dop853', rtol = 1e-6",
                                         "method = 'dop853', rtol = 1e-10", "method = 'vern9', rtol = 1e-12"])
def test_the_friction_ratio_of_a_sliding_ball_is_mu_up_to_a_lift_off(ellroll, tmp_path, integration, interval):
    with run_text(ellroll, tmp_path, LIFTING.format(integration=integration, interval=interval)) as f:
        summary = f["summary"]
        assert summary["status"][0] == 5                               # liftoff
        assert abs(summary["t_final"][0] - 0.3123000761) < 1e-9
        assert summary["friction_needed_max"][0] <= 0.3 * (1 + 1e-12), summary["friction_needed_max"][0]
        sliding = f["trajectory/regime"][0] == 1 if "regime" in f["trajectory"] else None
        reaction, normal = f["trajectory/reaction"][0], f["trajectory/normal"][0]
        big_n = np.einsum("ij,ij->i", reaction, normal)
        tangent = np.linalg.norm(reaction - big_n[:, None] * normal, axis=1)
        kept = np.isfinite(big_n) & (big_n > 0)
        if sliding is not None:
            kept &= sliding
        assert np.all(tangent[kept] <= 0.3 * big_n[kept] * (1 + 1e-9) + 1e-9), np.max(tangent[kept] / big_n[kept])


@pytest.mark.parametrize("seed", [3, 8])
@pytest.mark.parametrize("integration", ["method = 'rk4', dt = 1e-4", "method = 'dop853', rtol = 1e-10",
                                         "method = 'vern9', rtol = 1e-12"])
def test_a_start_that_slides_at_once_takes_its_maxima_from_the_sliding_state(ellroll, tmp_path, seed, integration):
    """A ball at rest in a cup whose acceleration at t = 0 needs more
    friction than mu N slides from t = 0: the rolling state there never
    acts. friction_needed_max is mu (every state slides), and the summary's
    horizontal force is no larger than the stored samples' (1e-4 s apart)
    by more than 1e-6 of them (the rolling state's, m (k / (1 + k)) |a(0)|,
    may lie above)."""
    rng = np.random.default_rng(seed)
    mu = float(rng.uniform(0.02, 0.08))
    amplitude = [float(v) for v in rng.uniform(3.0, 6.0, size=2) * rng.choice([-1.0, 1.0], size=2)]
    text = CUP + (f"&ball radius = 0.2, mass = 1.0, mu = {mu!r}, slip = 'slide' /\n&initial omega = 0, 0, 0 /\n"
                  f"&integration {integration}, t_end = 0.2 /\n"
                  f"&excitation kind = 'harmonic', amplitude = {amplitude[0]!r}, {amplitude[1]!r}, 0, "
                  f"frequency = 0.5, phase = 1.5707963267948966 /\n"
                  "&output file = 'out.h5', interval = 1e-4 /\n")
    with run_text(ellroll, tmp_path, text) as f:
        summary = {key: f[f"summary/{key}"][0] for key in ("status", "friction_needed_max", "horizontal_force_max")}
        kinds, times = f["switches/switch_kind"][:], f["switches/switch_time"][:]
        reaction, normal = f["trajectory/reaction"][0], f["trajectory/normal"][0]
    assert summary["status"] == 1 and kinds[0] == 1 and times[0] == 0
    assert summary["friction_needed_max"] == pytest.approx(mu, rel=1e-12)
    samples = np.max(np.hypot(reaction[:, 0], reaction[:, 1]))
    assert samples <= summary["horizontal_force_max"] <= samples * (1 + 1e-6)
