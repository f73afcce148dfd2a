"""The adaptive pairs at the ends of their documented ranges, through the
program, on the Release and the Debug build (traps on invalid, zero-divide
and overflow): atol = 0 (pure relative error control, the normal's x and y
exactly zero at the start) runs the paper's case, one case and a batch, to
the accuracy of atol > 0; a spin of 1e6 rad/s about every axis, whose
starting step is far too long for its motion, ends at the fit limit without
a trap. Every run is held to a timeout: an adaptive case must never hang."""
import h5py
import numpy as np
import pytest

from conftest import FULL, run
from test_fuzz import CRASH_SIGNS

CASE = """&geometry a = 1.0, b = 0.4, c = 0.2 /
&ball radius = 0.2, weight = 2620.0 /
&initial x = 0.0, y = 0.0, omega = {omega} /
&integration method = '{method}', rtol = {rtol!r}, atol = {atol!r}, t_end = {t_end!r} /
&output file = 'out.h5', interval = {interval!r}, fields = 'contact' /
"""
SPINS_8 = "&sweep name = 'omega_z', values = 5, 10, 15, 20, 25, 30, 35, 40 /\n"


def run_case(exe, folder, name, sweep="", timeout=60, **values):
    (folder / f"{name}.nml").write_text(CASE.format(**values) + sweep)
    result = run(exe, "run", f"{name}.nml", "-o", f"{name}.h5", "-q", cwd=folder, timeout=timeout)
    assert not any(sign in result.stderr for sign in CRASH_SIGNS), result.stderr
    assert result.returncode == 0, result.stderr
    with h5py.File(folder / f"{name}.h5") as f:
        status = f["summary/status"]
        names = dict(zip(status.attrs["flag_values"], status.attrs["flag_meanings"].split()))
        return [names[s] for s in status[:]], f["summary/t_final"][:], f["trajectory/contact"][:]


@pytest.mark.parametrize("build", ["release", "debug"])
@pytest.mark.parametrize("method", ["dop853", "vern9"])
@pytest.mark.parametrize("sweep", ["", SPINS_8], ids=["one case", "batch"])
def test_pure_relative_control(ellroll, ellroll_debug, tmp_path, build, method, sweep):
    exe = ellroll if build == "release" else ellroll_debug
    rtol, omega = 1.0e-8, "-2.0, 2.0, 20.0"
    common = dict(method=method, omega=omega, rtol=rtol, t_end=3.0, interval=0.5)
    status, t_final, relative = run_case(exe, tmp_path, "relative", sweep, atol=0.0, **common)
    assert status == ["completed"] * len(status) and np.all(t_final == 3.0)
    reference_status, _, reference = run_case(exe, tmp_path, "reference", sweep, atol=1.0e-13,
                                              **dict(common, rtol=1.0e-13, method="vern9"))
    assert reference_status == status
    # the accuracy the pairs reach at atol > 0 (test_integrators): within 100 rtol
    assert np.max(np.linalg.norm(relative - reference, axis=-1)) < 100 * rtol


@pytest.mark.parametrize("method", ["dop853", "vern9"])
@pytest.mark.parametrize("sweep", ["", "&sweep name = 'omega_z', values = " + ", ".join(
    str(1.0e6 - k) for k in range(8)) + " /\n"], ids=["one case", "batch"])
def test_a_starting_step_far_too_long_stays_finite(ellroll_debug, tmp_path, method, sweep):
    status, t_final, _ = run_case(ellroll_debug, tmp_path, "spin", sweep, method=method, omega="1e6, 1e6, 1e6",
                                  rtol=1.0e-6, atol=1.0e-6, t_end=1.0e-4, interval=1.0e-5)
    assert status == ["no_fit"] * len(status)
    assert np.all(np.abs(t_final - 1.0806e-6) < 1.0e-9)


# a ball shaken off its rolling at 0.014 s, inside the pairs' first step or two:
# the piece of the step up to the slip holds a maximum of Theta and the couple's work
SLIP_IN_FIRST_STEP = """&geometry a = 0.5, b = 0.36324918179651394, c = 0.8527649992936689 /
&ball radius = 0.01645012763074531, mass = 100.0, inertia_factor = 0.6666666666666666,
      rolling_resistance = 0.00021127666497455753, mu = 0.35399501318949733 /
&initial x = 0.03216820946231186, y = 0.09128263733986659,
         omega = -1.2948872570006738, 10.916668156017185, 7.369790422472628 /
&integration {integration}, t_end = 4.0 /
&excitation kind = 'harmonic', amplitude = 1.7460471439216079, 2.991353343910225, -0.04861389182843223,
            frequency = 0.9601498620292943, phase = 0.4770214915031632 /
&output file = 'out.h5', interval = 0.001 /
"""


def test_a_case_ending_inside_a_step_counts_the_piece_before_its_end(ellroll, tmp_path):
    """`slip` at 0.0140865 s by every method; theta_max 0.5566137997 rad and
    the couple's work 0.0288438 J (rk4 at dt = 1e-6 s: 0.0288428 J) with
    the pairs, whose one or two steps reach past the slip."""
    found = {}
    for name, integration in (("rk4", "method = 'rk4', dt = 1e-6"),
                              ("dop853", "method = 'dop853', rtol = 1e-12"),
                              ("vern9", "method = 'vern9', rtol = 1e-12")):
        (tmp_path / f"{name}.nml").write_text(SLIP_IN_FIRST_STEP.format(integration=integration))
        result = run(ellroll, "run", f"{name}.nml", "-q", "-o", f"{name}.h5", cwd=tmp_path)
        assert result.returncode == 0, result.stderr
        with h5py.File(tmp_path / f"{name}.h5") as f:
            found[name] = {k: f["summary"][k][0] for k in ("status", "t_final", "theta_max", "rolling_resistance_energy")}
            assert found[name]["theta_max"] >= np.nanmax(f["trajectory/nutation"][0])
    for name in ("dop853", "vern9"):
        assert found[name]["status"] == 4                               # slip
        assert found[name]["t_final"] == pytest.approx(found["rk4"]["t_final"], abs=1e-12)
        assert found[name]["theta_max"] == pytest.approx(found["rk4"]["theta_max"], abs=1e-10)
        assert found[name]["rolling_resistance_energy"] == pytest.approx(found["rk4"]["rolling_resistance_energy"],
                                                                        rel=1e-4)


ROUND_CUP = """&geometry a = 1.0, b = {b!r}, c = 0.2 /
&ball radius = 0.05, weight = 2620.0 /
&initial x = {x!r}, y = {y!r}, omega = 0.0, 0.0, 0.0 /
&integration method = '{method}', rtol = 1e-6, atol = {atol!r}, t_end = {t_end!r} /
&output file = 'out.h5', interval = {t_end!r} /
{sweep}"""


@pytest.mark.parametrize("build", ["release", "debug"])
@pytest.mark.parametrize("method", ["dop853", "vern9"])
def test_pure_relative_control_of_a_round_off_component_ends_and_never_hangs(ellroll, ellroll_debug, tmp_path,
                                                                            build, method):
    """A ball at rest off the axis of a cup of revolution (a = b, or b =
    0.999 a), atol = 0 or 1e-100: a component that symmetry keeps at zero
    holds round-off, which pure relative control can never accept: its
    steps shrink to 1e-101 s and less at t = 0, where 16 ulp of t bound
    none. Each case ends within the timeout, one and in a batch: a case
    that cannot follow ends 'unstable' at its start, t_final below 1e-12
    of t_end; atol = 1e-30 completes. Seeded starts. (The Debug build, 20
    times slower at its 1e5 round-off attempts, takes the first and the
    last; all with ELLROLL_TEST_FULL.)"""
    exe = ellroll if build == "release" else ellroll_debug
    rng = np.random.default_rng(6100 + (method == "vern9"))
    cases = [(1.0, 0.0, 1e-8), (0.999, 0.0, 1.0), (1.0, 1e-100, 0.5), (1.0, 1e-30, 1e-8)]
    for k, (b, atol, t_end) in enumerate(cases if build == "release" or FULL else cases[::3]):
        x, y = (float(v) for v in rng.uniform(0.2, 0.5, 2))
        sweep = "&sweep name = 'x', values = 0.3, 0.4 /\n" if k == 1 else ""
        folder = tmp_path / f"c{k}"
        folder.mkdir()
        (folder / "case.nml").write_text(ROUND_CUP.format(b=b, x=x, y=y, method=method, atol=atol, t_end=t_end,
                                                          sweep=sweep))
        result = run(exe, "run", "case.nml", "-q", cwd=folder, timeout=60)
        assert result.returncode == 0 and not any(sign in result.stderr for sign in CRASH_SIGNS), result.stderr
        with h5py.File(folder / "out.h5") as f:
            status, t_final = f["summary/status"][:], f["summary/t_final"][:]
        label = (b, atol, t_end, x, y, status, t_final)
        if atol > 1e-50:
            assert (status == 1).all(), label
        else:
            assert ((status == 9) & (t_final < 1e-12 * t_end) | (status == 1)).all() and (status == 9).any(), label
