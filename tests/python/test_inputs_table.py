"""The parameter table drives the docs and the checks: docs/inputs.md holds
`ellroll inputs` verbatim, and every row's range is enforced on input, with
a message that names the file, the group, the variable and the range."""
import pathlib
import re

import pytest

from conftest import run

DOCS = pathlib.Path(__file__).resolve().parents[2] / "docs" / "inputs.md"

BASE = {
    "geometry": ["a = 1.0", "b = 0.4", "c = 0.2"],
    "ball": ["radius = 0.2", "weight = 2620.0"],
    "initial": ["omega = -2.0, 2.0, 20.0"],
    "integration": ["dt = 1.0e-3", "t_end = 1.0"],
    "output": ["file = 'out.h5'", "interval = 0.01"],
}


def table_rows(ellroll):
    result = run(ellroll, "inputs")
    assert result.returncode == 0, result.stderr
    return result.stdout


def test_the_docs_hold_the_table(ellroll):
    text = DOCS.read_text()
    generated = text.split("<!-- ellroll inputs -->\n", 1)[1].split("<!-- end -->", 1)[0]
    assert generated == table_rows(ellroll)


def rows(ellroll):
    for line in table_rows(ellroll).splitlines()[2:]:
        cells = [c.strip().strip("`") for c in line.strip("|").split("|")]
        name, group, variable, unit, valid = cells[:5]
        high = re.search(r"(?:and|<=) ([-+\d.e]+)", valid).group(1)
        yield name, group.lstrip("&"), variable, float(high), valid


def namelist(group, variable, value):
    groups = {g: list(items) for g, items in BASE.items()}
    groups.setdefault(group, [])
    if group == "excitation":         # the kind the input belongs to (its file is read after the checks)
        groups[group].append("kind = 'record', record_file = 'absent.AT2'" if variable == "scale"
                             else "kind = 'harmonic'")
    base = variable.split("(")[0]
    if base == "mass":
        groups["ball"].remove("weight = 2620.0")
    if base in ("omega", "amplitude"):
        component = int(variable[-2]) - 1
        values = [-2.0, 2.0, 20.0] if base == "omega" else [0.0, 0.0, 0.0]
        values[component] = value
        groups[group] = [i for i in groups[group] if not i.startswith(base)]
        groups[group].append(f"{base} = " + ", ".join(repr(v) for v in values))
    else:
        groups[group] = [i for i in groups[group] if not i.startswith(base + " ")]
        groups[group].append(f"{base} = {value!r}")
    return "".join(f"&{g} " + ", ".join(items) + " /\n" for g, items in groups.items())


@pytest.mark.parametrize("beyond", ["above", "zero"])
def test_every_row_s_range_is_enforced(ellroll, tmp_path, beyond):
    checked = 0
    table = list(rows(ellroll))
    for name, group, variable, high, valid in table:
        if beyond == "zero" and "> 0" not in valid:
            continue
        value = 2 * high if beyond == "above" else 0.0
        (tmp_path / "in.nml").write_text(namelist(group, variable, value))
        result = run(ellroll, "check", "in.nml", cwd=tmp_path)
        assert result.returncode == 2, (name, result.stdout, result.stderr)
        assert f"in.nml:" in result.stderr and f"&{group}: {variable.split('(')[0]}" in result.stderr, \
            (name, result.stderr)
        assert valid in result.stderr, (name, valid, result.stderr)
        checked += 1
    # every row (above), every row whose range excludes 0 (weight, mass, inertia_factor, dt, ...)
    assert checked == (len(table) if beyond == "above" else sum("> 0" in row[4] for row in table))
    assert checked >= (25 if beyond == "above" else 4)


def test_the_campaign_docs_list_every_input_that_can_vary(ellroll):
    """docs/campaigns.md's list of the names a sweep or sample can vary is
    the table's varied rows, no more, no fewer."""
    varied = [line.split("|")[1].strip().strip("`") for line in table_rows(ellroll).splitlines()[2:]
              if line.split("|")[7].strip() == "yes"]
    text = (DOCS.parent / "campaigns.md").read_text()
    listed = re.search(r"Names that can vary \(.*?\): `([^`]*)`", text, re.S).group(1).split()
    assert sorted(listed) == sorted(varied)
