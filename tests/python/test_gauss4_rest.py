"""gauss4 at an ordinary stop of rolling resistance (no spin) rests where
dop853 at rtol 1e-12 rests: released at tan(slope) 0.01005 against
delta/R = 0.01, the ball rolls back and stops where the couple barely holds
it; and on a 1e-6 m ball whose couple (delta/R = 500) stops it inside the
first step, the rest is no model limit."""
import h5py
import pytest

from conftest import run

PLANAR = """&geometry a=1.0, b=1.0, c=0.5 /
&ball radius=0.1, mass=1.0, rolling_resistance=1e-3 /
&initial x=0.0201, y=0.0, omega=0,0,0 /
&integration {method}, t_end=1.7 /
&output interval=0.01 /
"""
TINY = """&geometry a=0.001, b=0.001, c=0.01 /
&ball radius=1e-06, mass=1.0, rolling_resistance=0.0005 /
&initial x=-0.0003409340241157387, y=-0.0003349201356646935, omega=100.0,-100.0,1.0 /
&integration {method}, t_end=0.01 /
&output interval=0.01 /
"""


def rest(exe, folder, text, method, name):
    (folder / f"{name}.nml").write_text(text.format(method=method))
    result = run(exe, "run", f"{name}.nml", "-q", "-o", f"{name}.h5", cwd=folder)
    assert result.returncode == 0, result.stderr[-2000:]
    with h5py.File(folder / f"{name}.h5", "r") as f:
        s = f["summary"]
        assert s["status"][0] == 1 and s["at_rest"][0] == 1, (s["status"][0], s["t_final"][0])
        return s["rest_time"][0], s["residual_displacement"][0]


# measured against dop853: rest 5.4e-12 s and 2.5e-10 s apart, residual 5e-19 m and 5.6e-13 m
@pytest.mark.parametrize("dt, time_tolerance, residual_tolerance", [("1e-4", 1e-11, 1e-15), ("1e-3", 1e-11, 1e-15),
                                                                     ("1e-2", 1e-9, 2e-12)])
def test_gauss4_rests_at_an_ordinary_stop_as_dop853_does(ellroll, tmp_path, dt, time_tolerance, residual_tolerance):
    reference = rest(ellroll, tmp_path, PLANAR, "method='dop853', rtol=1e-12", "reference")
    assert abs(reference[0] - 1.6354697) < 1e-7 and abs(reference[1] - 0.018897255) < 1e-9
    gauss4 = rest(ellroll, tmp_path, PLANAR, f"method='gauss4', dt={dt}", "gauss4")
    assert abs(gauss4[0] - reference[0]) < time_tolerance
    assert abs(gauss4[1] - reference[1]) < residual_tolerance


def test_gauss4_rest_inside_the_first_step_is_no_model_limit(ellroll, tmp_path):
    reference = rest(ellroll, tmp_path, TINY, "method='dop853', rtol=1e-12", "reference")
    gauss4 = rest(ellroll, tmp_path, TINY, "method='gauss4', dt=1e-4", "gauss4")   # measured: 7.5e-16 s, 3e-19 m
    assert abs(gauss4[0] - reference[0]) < 1e-14
    assert abs(gauss4[1] - reference[1]) < 1e-15


@pytest.mark.parametrize("method", ["method='gauss4', dt=1e-4", "method='rk4', dt=1e-4"])
def test_the_couple_s_work_stops_with_the_rolling_inside_a_step(ellroll, tmp_path, method):
    """The 1e-6 m ball comes to rest 2.2e-7 s into a step of 1e-4 s: the couple's
    work is over the rolling up to the stop (dop853 at rtol 1e-12: 1.38486e-8
    J), not the step's start power over the whole step (6.27e-6 J, an energy
    balance off by 5.2e-4 of E0)."""
    found = {}
    for name, integration in (("reference", "method='dop853', rtol=1e-12"), ("fixed", method)):
        rest(ellroll, tmp_path, TINY, integration, name)
        with h5py.File(tmp_path / f"{name}.h5", "r") as f:
            found[name] = f["summary/rolling_resistance_energy"][0], f["summary/energy_drift"][0]
    assert found["reference"][0] == pytest.approx(1.38486e-8, rel=1e-5)
    assert found["fixed"][0] == pytest.approx(found["reference"][0], rel=1e-5)
    assert found["fixed"][1] < 1e-10
