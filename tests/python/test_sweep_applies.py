"""A &sweep or &sample of an input that does not apply to the case (an
input of another excitation kind, an initial velocity without sliding or
without its other components, a tolerance of the adaptive methods with a
fixed-step one, settle where the ball cannot come to rest for good) is
refused as its single value is: exit 2, a message naming the file, the
group, the input and its values and why, and no output file; `check` and
`run` say the same. The inputs and settings come from the parameter table
(`ellroll inputs`); a varied input of an applicable setting runs and its
cases differ."""
import os
import pathlib
import re

import h5py
import numpy as np
import pytest

from conftest import ROOT, run

BASE = """&geometry a = 1.0, b = 0.4, c = 0.2 /
&ball radius = 0.2, weight = 2620.0{ball} /
&initial omega = -2.0, 2.0, 20.0{initial} /
&integration {integration}, t_end = 0.1 /
{excitation}&output file = 'out.h5', interval = 0.01 /
"""
RECORD = "0, 0, 0\n0.05, 0.5, 0.2\n0.1, -0.3, 0.4\n0.2, 0, 0\n"
RK4 = "method = 'rk4', dt = 1.0e-3"

NO_EXCITATION = dict(excitation="")
KIND_NONE = dict(excitation="&excitation kind = 'none' /\n")
HARMONIC = dict(excitation="&excitation kind = 'harmonic', amplitude = 1.0, 0.5, 0.0, frequency = 2.0 /\n")
RECORD_KIND = dict(excitation="&excitation kind = 'record', record_file = 'rec.csv' /\n")
SUITE = dict(excitation="&record name = 'first', record_file = 'rec.csv' /\n"
                        "&record name = 'second', record_file = 'rec.csv', factor = 2.0 /\n")
SLIDE = ", slip = 'slide', mu = 0.3"

def table(ellroll):
    """The rows of the parameter table: name, group, variable, range, varied, description."""
    result = run(ellroll, "inputs")
    assert result.returncode == 0, result.stderr
    rows = []
    for line in result.stdout.splitlines():
        cells = [cell.strip() for cell in line.strip().strip("|").split("|")]
        if len(cells) != 8 or not cells[0].startswith("`"):
            continue
        rows.append(dict(name=cells[0].strip("`"), group=cells[1].strip("`&"), variable=cells[2].strip("`"),
                         range=cells[4], varied=cells[6] == "yes", description=cells[7]))
    assert len(rows) >= 30
    return rows


def two_values(row):
    """Two values inside the row's valid range, as the message prints them."""
    numbers = [float(x) for x in re.findall(r"-?\d+(?:\.\d+)?(?:e[-+]?\d+)?", row["range"])]
    low, high = (0.0, numbers[-1]) if "> 0" in row["range"] else (numbers[0], numbers[1])
    inside = [v for v in (1.0, 2.0, 0.5, 0.25, 1e-6, 1e-7) if low < v <= high]
    return sorted(inside[:2])


def settings_of(row):
    """(not applying: [(label, setting, words)], applying: setting) of a row, or None where it always applies."""
    description, variable = row["description"], row["variable"]
    if row["group"] == "excitation" and description.startswith("harmonic:"):
        return ([("no &excitation", NO_EXCITATION, "applies to kind = 'harmonic' only; &excitation kind is 'none'"),
                 ("kind none", KIND_NONE, "applies to kind = 'harmonic' only; &excitation kind is 'none'"),
                 ("kind record", RECORD_KIND, "applies to kind = 'harmonic' only; &excitation kind is 'record'"),
                 ("suite", SUITE, "applies to kind = 'harmonic' only; &excitation kind is 'record'")],
                HARMONIC)
    if row["group"] == "excitation" and description.startswith("record:"):
        return ([("no &excitation", NO_EXCITATION, "applies to kind = 'record' only; &excitation kind is 'none'"),
                 ("kind none", KIND_NONE, "applies to kind = 'record' only; &excitation kind is 'none'"),
                 ("kind harmonic", HARMONIC, "applies to kind = 'record' only; &excitation kind is 'harmonic'")],
                RECORD_KIND)
    if variable.startswith("velocity("):
        return ([("slip end", {}, "it needs &ball slip = 'slide'"),
                 ("slide, no velocity", dict(ball=SLIDE), "the initial velocity needs all three components")],
                dict(ball=SLIDE, initial=", velocity = 0.1, 0.05, 0.0"))
    if "(adaptive method)" in description:
        return ([(method, dict(integration=f"method = '{method}', dt = 1.0e-3"),
                  f"applies to the adaptive methods only (dop853, vern9); &integration method is '{method}'")
                 for method in ("rk4", "gauss4")],
                dict(integration="method = 'dop853'"))
    if "until the ball is at rest" in description:
        return ([("no rolling resistance", {}, "applies with rolling resistance only"),
                 ("harmonic", dict(HARMONIC, ball=", rolling_resistance = 1e-3"),
                  "applies where the cup comes to rest only")],
                dict(ball=", rolling_resistance = 1e-3"))
    return None


# Every input that applies whatever the rest of the input says: a row of the
# table outside this list and outside settings_of is a row whose
# applicability nobody has looked at.
ALWAYS_APPLIES = {"a", "b", "c", "radius", "weight", "mass", "mu", "inertia_factor", "g", "x", "y", "omega_x",
                  "omega_y", "omega_z", "dt", "fit_margin", "rolling_resistance", "capacity"}


def write(folder, setting, varied):
    values = dict(ball="", initial="", integration=RK4, excitation="")
    values.update(setting)
    (folder / "cup.nml").write_text(BASE.format(**values) + varied)
    (folder / "rec.csv").write_text(RECORD)
    return "cup.nml"


def varied_group(group, row, values):
    if group == "sweep":
        text = ", ".join(f"{v:g}" for v in values)
        return f"&sweep name = '{row['name']}', values = {text} /\n", f"(values = {text})"
    return (f"&sample name = '{row['name']}', low = {values[0]:g}, high = {values[1]:g} /\n&campaign samples = 2 /\n",
            f"(low = {values[0]:g}, high = {values[1]:g})")


def refusals():
    """Every (row, setting) where the row does not apply, from the parameter table of the build under test."""
    exe = pathlib.Path(os.environ.get("ELLROLL_EXE", ROOT / "build" / "ellroll"))
    if not exe.exists():
        return []
    cases = []
    for row in table(exe):
        settings = settings_of(row)
        if settings is None:
            continue
        for label, setting, words in settings[0]:
            for group in ("sweep", "sample"):
                cases.append(pytest.param(row, setting, words, group, id=f"{group}-{row['name']}-{label}"))
    return cases


def test_every_varied_input_is_classified(ellroll):
    rows = table(ellroll)
    assert all(row["varied"] for row in rows)
    unclassified = [row["name"] for row in rows if settings_of(row) is None and row["name"] not in ALWAYS_APPLIES]
    assert unclassified == []
    # the rows that apply in some settings only
    assert {row["name"] for row in rows if settings_of(row) is not None} == {
        "excitation_frequency", "excitation_phase", "excitation_amplitude_x", "excitation_amplitude_y",
        "excitation_amplitude_z", "scale", "velocity_x", "velocity_y", "velocity_z", "rtol", "atol", "settle"}


@pytest.mark.parametrize("row,setting,words,group", refusals())
def test_varied_input_that_does_not_apply_is_refused(ellroll, tmp_path, row, setting, words, group):
    values = two_values(row)
    text, shown = varied_group(group, row, values)
    name = write(tmp_path, setting, text)
    line = len((tmp_path / name).read_text().splitlines()) - (1 if group == "sample" else 0)
    messages = []
    for command in ("check", "run"):
        result = run(ellroll, command, name, cwd=tmp_path)
        assert result.returncode == 2, (command, result.stdout, result.stderr)
        expected = f"cup.nml:{line}: &{group}: name = '{row['name']}': "
        assert expected in result.stderr and words in result.stderr and shown in result.stderr, (command, result.stderr)
        messages.append(result.stderr.strip())
        assert sorted(p.name for p in tmp_path.iterdir()) == ["cup.nml", "rec.csv"]
    assert messages[0] == messages[1]


def test_single_value_of_another_kind_is_refused_alike(ellroll, tmp_path):
    """The single value's message: the variable, its value, the same reason."""
    name = write(tmp_path, dict(excitation="&excitation kind = 'none', scale = 2 /\n"), "")
    result = run(ellroll, "run", name, cwd=tmp_path)
    assert result.returncode == 2
    assert "cup.nml:5: &excitation: scale = 2: applies to kind = 'record' only" in result.stderr, result.stderr
    assert sorted(p.name for p in tmp_path.iterdir()) == ["cup.nml", "rec.csv"]


def case_figures(path):
    """Per case, every stored number of its trajectory and summary but the wall time and the checksum."""
    with h5py.File(path, "r") as f:
        n = f["trajectory/contact"].shape[0]
        figures = []
        for i in range(n):
            parts = [f[f"trajectory/{k}"][i].ravel() for k in f["trajectory"]]
            parts += [np.atleast_1d(f[f"summary/{k}"][i]).ravel().astype(float) for k in f["summary"]
                      if k not in ("wall_time", "checksum") and f[f"summary/{k}"].dtype.kind in "fiu"]
            figures.append(np.concatenate(parts))
    return figures


@pytest.mark.parametrize("name", ["excitation_frequency", "excitation_phase", "excitation_amplitude_x", "scale",
                                  "velocity_x", "rtol", "atol", "settle"])
def test_varied_input_that_applies_runs_and_changes_the_cases(ellroll, tmp_path, name):
    row = next(row for row in table(ellroll) if row["name"] == name)
    values = {"rtol": [1e-3, 1e-10], "atol": [1e-2, 1e-12], "settle": [0.5, 1.0],
              "velocity_x": [0.1, 0.2]}.get(name, two_values(row))
    text, _ = varied_group("sweep", row, values)
    write(tmp_path, settings_of(row)[1], text)
    result = run(ellroll, "run", "cup.nml", "-q", cwd=tmp_path)
    assert result.returncode == 0, result.stderr
    first, second = case_figures(tmp_path / "out.h5")
    assert first.shape == second.shape
    assert not np.array_equal(first, second, equal_nan=True)
