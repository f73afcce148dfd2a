"""Steps that leave every scale of the motion (a fixed step far beyond the
method's stability) end the case at a status in every build: the Debug
build traps overflow, so the model is never evaluated at a state no step
can reach (the end of a step that failed at a stage; a sliding piece whose
substeps, shrunk to round-off, cannot finish it)."""
import h5py
import pytest

from conftest import run

# rk4 at dt 0.1 (check: 'dt <= 0.0005 s would do'), sliding, mu 1000, a couple
# of rolling resistance 500 R: the step's substeps and partial steps meet
# states of omega 1e86 rad/s on the way (test_held_stop.py has its rest)
SLIDING = """&geometry a=0.001, b=0.001, c=0.01 /
&ball radius=1e-06, mass=1.0, mu=1000.0, slip='slide', rolling_resistance=0.0005 /
&initial x=-0.0003409340241157387, y=-0.0003349201356646935, omega=0.0,0.0,1.0, velocity=1.0,0.0,-3.881292271606023 /
&integration method='rk4', dt=0.1, t_end=1.0 /
&output interval=1.0 /
"""
# gauss4 at dt 0.1 on a 1e-6 m ball spinning at 1e6 rad/s: the first step has
# no solution; its end's reaction is 1e224 N
ROLLING = """&geometry a=0.001, b=1e-05, c=0.0002 /
&ball radius=1e-06, mass=1.0 /
&initial x=0.00048081070222445277, y=-7.659482764024395e-07, omega=-1000.0,1000000.0,0.0 /
&integration method='gauss4', dt=0.1, t_end=10.0 /
&output interval=10.0 /
"""


def ending(exe, folder, text, name):
    (folder / f"{name}.nml").write_text(text)
    result = run(exe, "run", f"{name}.nml", "-q", "-o", f"{name}.h5", cwd=folder, timeout=300)
    assert result.returncode == 0, result.stderr[-2000:]
    with h5py.File(folder / f"{name}.h5", "r") as f:
        return f["summary/status"][0], f["summary/t_final"][0]


@pytest.mark.parametrize("text, status", [(SLIDING, 1), (ROLLING, 3)], ids=["sliding", "rolling"])
def test_the_debug_build_ends_an_exploding_step_at_the_release_builds_status(ellroll, ellroll_debug, tmp_path,
                                                                              text, status):
    release = ending(ellroll, tmp_path, text, "release")
    debug = ending(ellroll_debug, tmp_path, text, "debug")
    assert release[0] == status and debug[0] == status          # completed (at rest), no_fit
    assert abs(debug[1] - release[1]) <= 1e-9 * release[1]
