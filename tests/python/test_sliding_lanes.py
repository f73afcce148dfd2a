"""Cases that may slide (&ball slip = 'slide') in SIMD lanes: a campaign's
case that never slides gives, bit for bit, what it gives with slip = 'end'
(the lanes' rolling); a case that slides (or meets a limit) gives, bit for
bit, what it gives run alone (the one-case path, from t = 0); whatever its
neighbours. A campaign of 9 cases: a batch of 8 and a lone one."""
import h5py
import numpy as np
import pytest

from conftest import run

# the paper cup shaken at 1.5, 0.5 m/s^2: mu up to 0.06 slide, the others roll;
# the lone case of the second batch slides
MUS = [0.08, 0.2, 2.0, 0.01, 0.02, 10.0, 0.04, 0.05, 0.06]
CASE = """&geometry a = 1.0, b = 0.4, c = 0.2 /
&ball radius = 0.2, mass = 1.0, mu = {mu}, slip = '{slip}' /
&initial x = 0.01, y = 0.0, omega = 0.0, 0.0, 1.0 /
&integration {integration}, t_end = 3.0 /
&excitation kind = 'harmonic', amplitude = 1.5, 0.5, 0.0, frequency = 0.8 /
&output file = 'out.h5', interval = 0.01, fields = 'all' /
"""
METHODS = {"rk4": "method = 'rk4', dt = 1e-3", "dop853": "method = 'dop853', rtol = 1e-8, atol = 1e-11"}


def run_file(ellroll, folder, name, text):
    (folder / f"{name}.nml").write_text(text)
    result = run(ellroll, "run", f"{name}.nml", "-q", "-o", f"{name}.h5", cwd=folder)
    assert result.returncode == 0, result.stderr
    return folder / f"{name}.h5"


def case_data(path, j):
    """Every stored value of case j (wall_time and its index left out): its summary and
    trajectory rows and its switches."""
    found = {}
    with h5py.File(path, "r") as f:
        for name, item in f["summary"].items():
            if name not in ("wall_time", "case"):
                found[f"summary/{name}"] = np.asarray(item[j])
        for name, item in f["trajectory"].items():
            if item.ndim > 1:                                # (case, sample, ...)
                found[f"trajectory/{name}"] = np.asarray(item[j])
        if "switches" in f:
            first, count = f["switches/first"][j], f["switches/count"][j]
            for name in ("switch_time", "switch_kind"):
                found[f"switches/{name}"] = f["switches"][name][first:first + count]
    return found


def assert_same_bits(a, b, names, what):
    for name in names:
        assert a[name].tobytes() == b[name].tobytes(), f"{what}: {name}"


@pytest.mark.parametrize("method", METHODS)
def test_a_case_that_may_slide_gives_the_rolling_lanes_or_its_own_run_alone(ellroll, tmp_path, method):
    sweep = f"&sweep name = 'mu', values = {', '.join(map(str, MUS))} /\n"
    slide = run_file(ellroll, tmp_path, "slide", CASE.format(mu=0.1, slip="slide", integration=METHODS[method]) + sweep)
    end = run_file(ellroll, tmp_path, "end", CASE.format(mu=0.1, slip="end", integration=METHODS[method]) + sweep)
    slid = rolled = 0
    for j, mu in enumerate(MUS):
        ours = case_data(slide, j)
        if ours["summary/slip_episodes"] == 0 and ours["summary/status"] == 1:
            rolled += 1
            theirs = case_data(end, j)
            assert_same_bits(ours, theirs, sorted(set(ours) & set(theirs)), f"mu {mu} against slip = 'end'")
            assert not ours["trajectory/regime"].any() and not ours["trajectory/slip_speed"].any()
            assert ours["summary/sliding_time"] == 0 and ours["summary/friction_energy"] == 0
        else:
            slid += 1
            alone = case_data(run_file(ellroll, tmp_path, f"alone{j}",
                                       CASE.format(mu=mu, slip="slide", integration=METHODS[method])), 0)
            assert set(alone) <= set(ours)                  # (the sweep's file has summary/mu too)
            assert_same_bits(ours, alone, sorted(alone), f"mu {mu} against its run alone")
    assert (slid, rolled) == (5, 4)
