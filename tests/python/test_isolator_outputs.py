"""The isolator's engineering figures in /summary against the trajectory: with
a sample at every step end they are the trajectory's own peaks, exactly, on
the batch path (fixed cup) and the single-case path (a record); at coarser
samples they bound the samples' peaks."""
import h5py
import numpy as np
import pytest

from conftest import run
from test_records import DT, ground, write_at2

CUP = """&geometry a = 1.0, b = 0.4, c = 0.2 /
&ball radius = 0.2, weight = 2620.0 /
&initial x = {x}, y = 0.03, omega = 0.0, 0.0, {spin} /
&integration method = '{method}', dt = 1.0e-3, t_end = 12.0 /
{excitation}&output file = 'out.h5', interval = {interval} /
"""
RECORD = "&excitation kind = 'record', record_file = 'H1.AT2', 'H2.AT2', scale = 1.5 /\n"


def run_cup(ellroll, folder, x=0.05, spin=0.5, method="rk4", excitation="", interval=1.0e-3):
    (folder / "cup.nml").write_text(CUP.format(x=x, spin=spin, method=method, excitation=excitation,
                                               interval=interval))
    result = run(ellroll, "run", "cup.nml", "-q", cwd=folder)
    assert result.returncode == 0, result.stderr
    with h5py.File(folder / "out.h5", "r") as f:
        summary = {name: f["summary"][name][0] for name in f["summary"]}
        t = f["time"][()]
        center = f["trajectory/center"][0]
        reaction = f["trajectory/reaction"][0]
        mass = f["case/mass"][0]
    return summary, t, center, reaction, mass


@pytest.mark.parametrize("excitation", ["", RECORD], ids=["fixed cup (batch)", "record (single case)"])
def test_peaks_are_the_trajectorys_at_every_step(ellroll, tmp_path, excitation):
    write_at2(tmp_path / "H1.AT2", ground(11), DT)
    write_at2(tmp_path / "H2.AT2", ground(12), DT)
    s, t, center, reaction, mass = run_cup(ellroll, tmp_path, excitation=excitation)
    assert s["t_final"] == t[-1] == 12.0
    displacement = np.sqrt(center[:, 0]**2 + center[:, 1]**2)
    acceleration = np.sqrt(reaction[:, 0]**2 + reaction[:, 1]**2) / mass
    k = int(np.argmax(displacement))                   # (the start counts)
    assert s["displacement_max"] == pytest.approx(displacement[k], rel=1e-15)
    assert s["displacement_max_time"] == t[k]
    k = int(np.argmax(acceleration))
    assert s["absolute_acceleration_max"] == pytest.approx(acceleration[k], rel=1e-14)
    assert s["absolute_acceleration_max_time"] == t[k]
    assert np.isnan(s["residual_displacement"]) and s["at_rest"] == 0   # no rolling resistance: never at rest
    assert s["absolute_acceleration_max"] * mass == pytest.approx(s["horizontal_force_max"], rel=1e-15)
    if excitation:                                      # the ground shakes it well beyond the start
        assert s["displacement_max"] > 2 * displacement[0]


def test_adaptive_peaks_bound_the_samples(ellroll, tmp_path):
    write_at2(tmp_path / "H1.AT2", ground(13), DT)
    write_at2(tmp_path / "H2.AT2", ground(14), DT)
    s, t, center, reaction, mass = run_cup(ellroll, tmp_path, method="dop853", excitation=RECORD,
                                           interval=0.01)
    displacement = np.sqrt(center[:, 0]**2 + center[:, 1]**2)
    acceleration = np.sqrt(reaction[:, 0]**2 + reaction[:, 1]**2) / mass
    assert displacement.max() <= s["displacement_max"] <= displacement.max() * (1 + 1e-3)
    assert acceleration.max() <= s["absolute_acceleration_max"] * (1 + 1e-12)
    assert 0 <= s["displacement_max_time"] <= 12.0 and 0 <= s["absolute_acceleration_max_time"] <= 12.0
    assert np.isnan(s["residual_displacement"]) and np.isnan(s["rest_time"])
