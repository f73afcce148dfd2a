"""An embedded pair's case that may slide (&ball slip = 'slide') rolls with
the rolling path's own steps: a case that never slides gives, bit for bit,
what slip = 'end' gives (on every scene, with and without rolling
resistance, whatever the output interval), its rolling stops are the
rolling path's, and the friction's work of a case with rolling resistance
that hovers near mu N agrees across pairs."""
from pathlib import Path

import h5py
import numpy as np
import pytest

from conftest import run

RECORDS = Path(__file__).resolve().parents[2] / "input" / "records"

SCENES = {
    "fixed": "",
    "harmonic": "&excitation kind = 'harmonic', amplitude = 0.3, 0.2, 0.1, frequency = 0.7 /",
    "record": f"&excitation kind = 'record', record_file = '{RECORDS}/SYN1_H1.AT2', '{RECORDS}/SYN1_H2.AT2' /",
}
CASE = """&geometry a = 1.0, b = 0.4, c = 0.2 /
&ball radius = 0.2, weight = 2620.0, mu = 1000.0, slip = '{slip}'{resistance} /
&initial x = 0.01, y = 0.02, omega = -2.0, 2.0, 20.0 /
&integration method = '{method}', rtol = 1e-9, t_end = 10.0 /
{scene}
&output file = 'out.h5', interval = {interval}, fields = 'all' /
"""
SLIDE_ONLY = {"sliding_time", "slip_episodes", "friction_energy", "slip_speed_max", "wall_time"}


def run_text(ellroll, folder, name, text):
    (folder / f"{name}.nml").write_text(text)
    result = run(ellroll, "run", f"{name}.nml", "-q", "-o", f"{name}.h5", cwd=folder)
    assert result.returncode == 0, result.stderr
    with h5py.File(folder / f"{name}.h5", "r") as f:
        summary = {k: np.asarray(v[()]) for k, v in f["summary"].items()}
        trajectory = {k: np.asarray(v[()]) for k, v in f["trajectory"].items()}
    return summary, trajectory


@pytest.mark.parametrize("method", ["dop853", "vern9"])
@pytest.mark.parametrize("scene", SCENES)
@pytest.mark.parametrize("resistance", ["", ", rolling_resistance = 1e-4"])
def test_a_pair_that_never_slides_gives_slip_end_bit_for_bit(ellroll, tmp_path, method, scene, resistance):
    runs = {}
    for slip in ("slide", "end"):
        for interval in (1.0, 0.01):
            text = CASE.format(slip=slip, resistance=resistance, method=method, scene=SCENES[scene],
                               interval=interval)
            runs[slip, interval] = run_text(ellroll, tmp_path, f"{slip}_{interval:g}", text)
    for interval in (1.0, 0.01):
        (slide, slide_samples), (end, end_samples) = runs["slide", interval], runs["end", interval]
        assert set(slide) - SLIDE_ONLY == set(end) - SLIDE_ONLY
        for name in set(end) - SLIDE_ONLY:
            assert slide[name].tobytes() == end[name].tobytes(), (interval, name)
        for name in end_samples:
            assert slide_samples[name].tobytes() == end_samples[name].tobytes(), (interval, name)
        assert not slide_samples["regime"].any()
    # the maxima of Theta are located on the dense output, not on the step ends
    assert runs["slide", 1.0][0]["theta_max"].tobytes() == runs["slide", 0.01][0]["theta_max"].tobytes()


# a spinning ball with rolling resistance that stops where the couple barely
# holds it; mu = 10 is never reached
STOP = """&geometry a = 0.5, b = 0.43043632453998515, c = 0.9020031461644527 /
&ball radius = 0.05440854213006758, mass = 100.0, mu = 10.0, slip = '{slip}', inertia_factor = 0.1,
      rolling_resistance = 0.0011109046182971455 /
&initial x = 0.017112483783385368, y = -0.03235973216375581,
         omega = -3.431969859120537, 1.271572413852124, -5.946281168382165 /
&integration method = '{method}', rtol = 1e-09, t_end = 4.0 /
&output file = 'out.h5', interval = 0.01 /
"""


@pytest.mark.parametrize("method", ["dop853", "vern9"])
def test_a_rolling_stop_of_a_case_that_may_slide_is_the_rolling_path_s(ellroll, tmp_path, method):
    slide, _ = run_text(ellroll, tmp_path, "slide", STOP.format(slip="slide", method=method))
    end, _ = run_text(ellroll, tmp_path, "end", STOP.format(slip="end", method=method))
    assert slide["status"][0] == 1 and slide["at_rest"][0] == 1
    assert slide["rest_time"][0] == pytest.approx(2.646162, abs=1e-6)         # dop853 and vern9 at 1e-12
    for name in ("rest_time", "residual_displacement", "rolling_resistance_energy", "theta_max"):
        assert slide[name].tobytes() == end[name].tobytes(), name


# a record case with rolling resistance whose slip hovers at 1e-5 m/s for a
# while (outside probe): the pairs follow it, and agree
HOVER = f"""&geometry a = 2.0, b = 0.6268018543610078, c = 0.9429278613916068 /
&ball radius = 0.12344111441142669, mass = 100.0, mu = 0.008971645118120994, slip = 'slide',
      inertia_factor = 0.1, rolling_resistance = 0.0005041501715511712 /
&initial x = -0.46783861628796863, y = -0.026889982428090892,
         omega = -2.7561255518444545, -6.817350098685071, 1.3701760116266248 /
&integration method = '{{method}}', rtol = 1e-10, t_end = 12.0 /
&excitation kind = 'record', record_file = '{RECORDS}/SYN1_H1.AT2', '{RECORDS}/SYN3_H2.AT2',
            scale = 9.371145027533863 /
&output file = 'out.h5', interval = 0.01, fields = 'none' /
"""


def test_pairs_follow_a_hovering_slip_with_rolling_resistance(ellroll, tmp_path):
    """dop853 and vern9 at rtol 1e-10: sliding time 11.3630975 s and the
    friction's work 31.3834785 J both, to 1e-7."""
    runs = {m: run_text(ellroll, tmp_path, m, HOVER.format(method=m))[0] for m in ("dop853", "vern9")}
    for out in runs.values():
        assert out["status"][0] == 1 and out["slip_episodes"][0] == 5
    a, b = runs["dop853"], runs["vern9"]
    for name in ("sliding_time", "friction_energy", "rolling_resistance_energy"):
        assert a[name][0] == pytest.approx(b[name][0], rel=1e-7), name


SLOW_START = """&geometry a = 1.2563732254749764, b = 0.8322510605048443, c = 0.36056575958671633 /
&ball radius = 0.3219360359473515, mass = 10.0, mu = 0.051184432455100015, slip = 'slide',
      rolling_resistance = 0.0017122281832639879 /
&initial x = 0.10714847829077473, y = -0.039583794071531224, omega = -1.3340175200883788, 1.8423182236600724,
         22.92417261393757 /
&integration {integration}, t_end = 4.0 /
&output file = 'out.h5', interval = 0.01 /
"""


@pytest.mark.parametrize("integration", ["method = 'vern9', rtol = 1e-12", "method = 'vern9', rtol = 1e-13",
                                         "method = 'dop853', rtol = 1e-12"])
def test_a_slip_starting_slowly_with_rolling_resistance_is_followed_on_its_slow_manifold(ellroll, tmp_path,
                                                                                         integration):
    """A slip that starts where rolling's friction just passes mu N grows
    from 0 as t^2; against u / |u| its direction's time scale |u| / (c
    |F_req|) holds an explicit pair's steps near 1e-11 s (vern9 at rtol
    1e-12: 100,000 of them in the first 2.3 ms). With rolling resistance too the slip
    follows -F_req (the aligned law) where the couple keeps its direction
    over the step. Against rk4 at dt 2e-5 s (into sliding at 3.5301827922 s,
    rolling at 3.9984881785 s): the same switches, the start within 1e-9
    s, the stop (where rolling needs nearly mu N: a slow approach) within
    5e-7 s, the energy balance closed, and in few steps."""
    summary, _ = run_text(ellroll, tmp_path, "case", SLOW_START.format(integration=integration))
    with h5py.File(tmp_path / "case.h5", "r") as f:
        times, kinds = f["switches/switch_time"][()], f["switches/switch_kind"][()]
    assert summary["status"][0] == 1
    assert list(kinds) == [1, 2]
    assert times[0] == pytest.approx(3.5301827922, abs=1e-9)
    assert times[1] == pytest.approx(3.9984881785, abs=5e-7)
    assert summary["energy_drift"][0] < 1e-12
    assert summary["n_steps"][0] < 5000
