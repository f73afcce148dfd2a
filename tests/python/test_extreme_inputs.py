"""Every numeric input at the extremes of double precision, under the Debug
build (runtime checks, traps on invalid, zero-divide and overflow): each is
validated before arithmetic uses it, so the build never stops by a signal; a
value is rejected with exit 2 naming the file, group, variable and value, or
accepted and run to a recorded status."""
import re

import h5py
import pytest

from conftest import run
from test_fuzz import CRASH_SIGNS

EXTREMES = ["NaN", "Inf", "-Inf", "1e309", "-1e309", "1e300", "-1e300", "1e-300", "-1e-300", "0", "4.9e-324"]

# group: {variable: value in the base case}; the vectors' components one at a time
BASE = {
    "geometry": {"a": "1.0", "b": "0.4", "c": "0.2"},
    "ball": {"radius": "0.2", "weight": "2620.0", "inertia_factor": "0.4", "mu": None, "mass": None},
    "environment": {"g": "9.81"},
    "initial": {"x": "0.0", "y": "0.0", "omega(1)": "-2.0", "omega(2)": "2.0", "omega(3)": "20.0"},
    "integration": {"method": "'rk4'", "dt": "1.0e-3", "t_end": "0.05", "fit_margin": "1e-6",
                    "rtol": "1e-9", "atol": "1e-12"},
    "output": {"file": "'out.h5'", "interval": "0.01"},
    "excitation": {"kind": "'harmonic'", "amplitude(1)": "0.5", "amplitude(2)": "0.0", "amplitude(3)": "0.0",
                   "frequency": "2.0", "phase": "0.0"},
}
VARIABLES = [(group, name) for group, names in BASE.items() for name in names
             if name not in ("method", "file", "kind")]

BASE_GROUP = {"omega": "initial", "amplitude": "excitation"}


def namelist(group, name, value):
    groups = {g: dict(v) for g, v in BASE.items()}
    if name == "mass":                               # mass given instead of the weight
        del groups["ball"]["weight"]
    groups[group][name] = value
    for vector in ("omega", "amplitude"):            # written as a user would: all three in one
        if f"{vector}(1)" in groups[BASE_GROUP[vector]]:
            items = groups[BASE_GROUP[vector]]
            items[vector] = ", ".join(items.pop(f"{vector}({k})") for k in (1, 2, 3))
    return "".join(f"&{g} " + ", ".join(f"{k} = {v}" for k, v in items.items() if v is not None) + " /\n"
                   for g, items in groups.items())


def end_of_case(path):
    with h5py.File(path) as f:
        status = f["summary/status"]
        names = dict(zip(status.attrs["flag_values"], status.attrs["flag_meanings"].split()))
        return names[status[0]], f["summary/t_final"][0]


def assert_no_crash(result, detail):
    assert not any(sign in result.stderr for sign in CRASH_SIGNS), detail
    assert result.returncode in (0, 2), detail


@pytest.mark.parametrize("group,name", VARIABLES, ids=[n for _, n in VARIABLES])
def test_extreme_values_are_rejected_or_run_to_a_status(ellroll_debug, tmp_path, group, name):
    variable = re.sub(r"\(\d\)", "", name)
    outcomes = {}
    for k, value in enumerate(EXTREMES):
        path = tmp_path / f"case{k}.nml"
        path.write_text(namelist(group, name, value))
        result = run(ellroll_debug, "check", path.name, cwd=tmp_path, timeout=60)
        detail = f"{group}/{name} = {value}:\n{result.stdout}\n{result.stderr}"
        assert_no_crash(result, detail)
        if result.returncode == 2:
            message = result.stderr
            assert message.startswith(f"ellroll: error: {path.name}:"), detail
            # named in its group, or with its value in the message on the input it
            # invalidates (g: the mass from the weight; t_end: the interval)
            assert f"&{group}: {variable} = {value}" in message or f" {variable} = " in message, detail
            outcomes[value] = "rejected"
            continue
        if int(re.search(r"steps per case = (\d+)", result.stdout).group(1)) > 100_000:
            continue
        result = run(ellroll_debug, "run", path.name, "-o", f"case{k}.h5", "-q", cwd=tmp_path, timeout=120)
        assert_no_crash(result, detail + result.stderr)
        assert result.returncode == 0, detail + result.stderr
        status, t_final = end_of_case(tmp_path / f"case{k}.h5")
        assert status not in ("pending", "invalid") and 0 <= t_final <= 0.05, detail + status
        outcomes[value] = status
    assert all(outcomes.get(v) == "rejected" for v in ("NaN", "Inf", "-Inf", "1e309", "-1e309")), outcomes


@pytest.mark.parametrize("group,name,value,words", [
    ("environment", "g", "NaN", ["g = NaN", "must be a finite number"]),
    ("geometry", "a", "1e309", ["a = 1e309", "must be a finite number"]),
    ("environment", "g", "1e-300", ["weight = 2620.0", "gives a mass weight / g above", "g = 1e-300"]),
])
def test_reported_traps_are_clean_rejections(ellroll_debug, tmp_path, group, name, value, words):
    (tmp_path / "case.nml").write_text(namelist(group, name, value))
    for command in ("check", "run"):
        result = run(ellroll_debug, command, "case.nml", cwd=tmp_path)
        assert result.returncode == 2 and all(w in result.stderr for w in words), result.stderr
    assert not (tmp_path / "case.h5").exists()


def test_a_spin_far_beyond_the_step_is_warned_and_ends_unstable(ellroll_debug, tmp_path):
    (tmp_path / "case.nml").write_text(namelist("initial", "omega(3)", "1e6"))
    result = run(ellroll_debug, "check", "case.nml", cwd=tmp_path)
    assert result.returncode == 0
    assert "beyond rk4's stability" in result.stderr and "case 0: dt = 0.001 s" in result.stderr, result.stderr
    result = run(ellroll_debug, "run", "case.nml", "-o", "case.h5", "-q", cwd=tmp_path)
    assert result.returncode == 0, result.stderr
    status, t_final = end_of_case(tmp_path / "case.h5")
    assert status == "unstable" and t_final < 0.01
