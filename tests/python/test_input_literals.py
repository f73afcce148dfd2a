"""Literals a namelist variable of the other kind does not hold, for every
integer and every text variable of the groups (docs/inputs.md): an integer
given a real beyond the doubles (1d400, 1e999: its conversion overflows, which
the Debug and sanitizer builds trap), its underflow, a whole number beyond the
variable's integers, and odd forms; a text given an unquoted number, word or
logical. Each is refused with exit 2, a message naming the file, line, group,
variable and value, and no output file, in the Release and the Debug build
(tests/run_all.sh runs it on the sanitizer build too)."""
import pytest

from conftest import PAPER_INPUT, run
from test_fuzz import CRASH_SIGNS

# (group, variable, the largest magnitude it holds)
INTEGERS = [("output", "compression", 2**31 - 1), ("campaign", "samples", 2**63 - 1),
            ("campaign", "seed", 2**63 - 1), ("sweep", "count", 2**31 - 1)]
# (group, variable): the character variables
TEXTS = [("integration", "method"), ("integration", "error_estimate"), ("ball", "slip"), ("output", "file"),
         ("output", "fields"), ("output", "fields(2)"), ("excitation", "kind"), ("excitation", "record_file"),
         ("campaign", "combine"), ("campaign", "invalid"), ("sweep", "name"), ("sweep", "spacing"),
         ("sample", "name"), ("sample", "spacing"), ("record", "name"), ("record", "record_file"),
         ("limit_state", "name"), ("limit_state", "figure")]
# (value, words of the reason)
REALS_FOR_INTEGERS = [("1d400", "is not a whole number"), ("-1d400", "is not a whole number"),
                      ("1e999", "is not a whole number"), ("1e309", "is not a whole number"),
                      ("-1E+999", "is not a whole number"), ("1d-400", "is not a whole number"),
                      ("4.9e-324", "is not a whole number"), ("1.5", "is not a whole number"),
                      ("NaN", "is not a whole number"), ("Inf", "is not a whole number"), ("-Inf", "is not a whole number"),
                      ("0x10", "is not a number"), ("Z'10'", "is not a number"), ("1d400d3", "is not a number"),
                      ("99999999999999999999999", ": out of range"),
                      ("-99999999999999999999999", ": out of range"),
                      ("9223372036854775808", ": out of range")]
UNQUOTED = ["0.5", "1e308", "99999999999999999999", "1d400", "-7", "NaN", "Inf", "word", ".true."]


def refused(exe, folder, group, assignment):
    """The paper's input with `&group assignment /` added (a group given
    twice replaced): the run's result, and the files it left."""
    text = PAPER_INPUT.read_text()
    lines = [line for line in text.splitlines() if not line.startswith(f"&{group} ")]
    extra = f"&{group} {assignment} /"
    if group == "sweep":                       # (count needs a name; a text of it is the tested one)
        extra = f"&sweep name = 'omega_z', {assignment} /" if "name" not in assignment else extra
    (folder / "case.nml").write_text("\n".join(lines + [extra]) + "\n")
    result = run(exe, "run", "case.nml", "-q", cwd=folder)
    left = sorted(p.name for p in folder.iterdir() if p.name != "case.nml")
    return result, left, len(lines) + 1


def assert_refused(result, left, line, group, name, value, words):
    detail = f"&{group} {name} = {value}: exit {result.returncode}: {result.stderr[-1500:]}"
    assert not any(sign in result.stderr for sign in CRASH_SIGNS), detail
    assert result.returncode == 2, detail
    assert f"case.nml:{line}: &{group}: {name} = {value}" in result.stderr and words in result.stderr, detail
    assert left == [], (detail, left)


@pytest.mark.parametrize("build", ["release", "debug"])
@pytest.mark.parametrize("group,name,largest", INTEGERS, ids=[v[1] for v in INTEGERS])
def test_an_integer_variable_refuses_reals_and_whole_numbers_beyond_it(ellroll, ellroll_debug, tmp_path, build,
                                                                      group, name, largest):
    exe = ellroll if build == "release" else ellroll_debug
    cases = REALS_FOR_INTEGERS + [(str(largest + 1), ": out of range"), (str(-largest - 2), ": out of range"),
                                  (f"1*{10 * largest}", ": out of range")]
    for k, (value, words) in enumerate(cases):
        folder = tmp_path / f"v{k}"
        folder.mkdir()
        result, left, line = refused(exe, folder, group, f"{name} = {value}")
        if value.startswith("1*"):          # (the repeated value named after the assignment)
            words = f": {value[2:]} is out of range"
        assert_refused(result, left, line, group, name, value, words)


@pytest.mark.parametrize("build", ["release", "debug"])
@pytest.mark.parametrize("group,name", TEXTS, ids=[f"{g}.{n}" for g, n in TEXTS])
def test_a_text_variable_refuses_an_unquoted_value(ellroll, ellroll_debug, tmp_path, build, group, name):
    exe = ellroll if build == "release" else ellroll_debug
    base = name.split("(")[0]
    for k, value in enumerate(UNQUOTED):
        folder = tmp_path / f"v{k}"
        folder.mkdir()
        result, left, line = refused(exe, folder, group, f"{name} = {value}")
        assert_refused(result, left, line, group, name, value,
                       f"is not a valid value for {base} (it takes a text in quotes, e.g. {base} = 'value')")


def test_a_byte_order_mark_is_no_text(ellroll, tmp_path):
    """A UTF-8 byte-order mark at the file's start (some editors save one)
    is read as nothing: the run is the one of the file without it, its
    campaign the same (a resume or merge takes either)."""
    import h5py
    import numpy as np
    text = PAPER_INPUT.read_text().replace("t_end = 30.0", "t_end = 0.5")
    (tmp_path / "plain.nml").write_text(text)
    (tmp_path / "marked.nml").write_bytes(b"\xef\xbb\xbf" + text.encode())
    for name in ("plain", "marked"):
        result = run(ellroll, "run", f"{name}.nml", "-q", "-o", f"{name}.h5", cwd=tmp_path)
        assert result.returncode == 0, result.stderr
    with h5py.File(tmp_path / "plain.h5", "r") as a, h5py.File(tmp_path / "marked.h5", "r") as b:
        assert a.attrs["campaign_id"] == b.attrs["campaign_id"]
        for field in ("contact", "omega", "nutation"):
            assert np.array_equal(a[f"trajectory/{field}"][:], b[f"trajectory/{field}"][:], equal_nan=True)
