"""Record files read safely: every sample bounded where it is read (1e4
m/s^2, times its factor), the unit taken from an AT2 header (g, cm/s^2,
m/s^2 as PEER spells them; velocity and displacement records refused),
records that are not regular files or are too large refused at once, numbers
read to the nearest double, and a record shorter than t_end padded with rest
(CSV and AT2 alike)."""
import os

import h5py
import numpy as np
import pytest

from conftest import run
from test_records import CUP, DT, STANDARD_GRAVITY, assert_same_trajectories, ground, run_case, write_at2

BOUND = 1.0e4                       # m/s^2: the largest |sample| of a record
ROOT_FILES = ["H1.AT2", "cup.nml"]


def at2(values, unit="G", quantity="ACCELERATION", npts=None, dt=DT, per_line=5):
    """An AT2 text: PEER's header, the values as written (strings), per_line to a line."""
    npts = len(values) if npts is None else npts
    lines = ["PEER NGA STRONG MOTION DATABASE RECORD", "SYNTHETIC RECORD FOR ELLROLL TESTS",
             f"{quantity} TIME SERIES IN UNITS OF {unit}", f"NPTS={npts:7d}, DT={dt:9.4f} SEC"]
    lines += ["".join(f" {v:>15}" for v in values[i:i + per_line]) for i in range(0, len(values), per_line)]
    return "\n".join(lines) + "\n"


def refused(exe, folder, files="'H1.AT2'", extra="", command="check", t_end=1.0, timeout=20):
    (folder / "cup.nml").write_text(CUP.format(files=files, t_end=t_end, extra=extra))
    result = run(exe, command, "cup.nml", cwd=folder, timeout=timeout)
    assert result.returncode == 2, result.stderr
    return result.stderr


def base_acceleration(path):
    with h5py.File(path, "r") as f:
        return f["time"][()], f["trajectory/base_acceleration"][0]


# --- (a) a bound on every sample, where it is read -------------------------------------------

@pytest.mark.parametrize("build", ["ellroll", "ellroll_debug"])
@pytest.mark.parametrize("value,scale", [(".1E+308", 1.0), (".1E+307", 1000.0), ("1.0E+309", 1.0),
                                         ("1020.", 1.0), ("-.10198E+04", 1.0)])
def test_a_sample_beyond_the_bound_is_refused_with_its_file_line_and_value(request, tmp_path, build, value,
                                                                          scale):
    """1020 g = 10003 m/s^2 is just beyond 1e4 m/s^2; .1E+308 g made the Debug
    build trap in the model and left a journal behind."""
    exe = request.getfixturevalue(build)
    (tmp_path / "H1.AT2").write_text(at2([".1E-01", value, ".1E-01", ".2E-01", "0.0"]))
    stderr = refused(exe, tmp_path, extra=f", scale = {scale}", command="run")
    assert f"H1.AT2:5: value 2 of 5, '{value}' g is beyond the bound on ground acceleration, |a| <= 10000 m/s^2" \
        in stderr, stderr
    assert sorted(p.name for p in tmp_path.iterdir()) == ROOT_FILES


def test_the_bound_itself_is_accepted_and_the_largest_scale_runs_in_the_debug_build(ellroll_debug, tmp_path):
    """+-1e4 m/s^2 on every axis times scale 1000, on a ball of 1e12 kg: every
    method ends the case with a status, none with a signal."""
    (tmp_path / "rec.csv").write_text("0, 10000, -10000, 10000\n0.01, -10000, 10000, -10000\n"
                                      "0.02, 1e4, 1e4, -1e4\n")
    text = CUP.format(files="'rec.csv'", t_end=0.2, extra=", scale = 1000").replace("weight = 2620.0", "mass = 1e12")
    for method in ("rk4", "dop853", "vern9", "gauss4"):
        (tmp_path / "cup.nml").write_text(text.replace("'rk4'", f"'{method}'"))
        result = run(ellroll_debug, "run", "cup.nml", "-q", "--overwrite", "-o", "out.h5", cwd=tmp_path)
        assert result.returncode == 0, (method, result.stderr)
        with h5py.File(tmp_path / "out.h5", "r") as f:
            status = f["summary/status"]
            assert status.attrs["flag_meanings"].split()[status[0]] != "nonfinite", method


def test_a_csv_sample_beyond_the_bound_is_refused(ellroll, tmp_path):
    (tmp_path / "rec.csv").write_text("t, ax, ay\n0, 0, 0\n0.5, 1, -10000.5\n20, 0, 0\n")
    stderr = refused(ellroll, tmp_path, files="'rec.csv'")
    assert "rec.csv:3: '-10000.5' m/s^2 is beyond the bound on ground acceleration" in stderr, stderr


SUITE = """&geometry a = 1.0, b = 0.4, c = 0.2 /
&ball radius = 0.2, weight = 2620.0 /
&initial omega = 0.0, 0.0, 0.0 /
&integration method = 'rk4', dt = 1.0e-3, t_end = 1.0 /
&excitation kind = 'record' /
&record name = 'one', record_file = 'rec.csv', factor = 1000 /
&output file = 'suite.h5', interval = 0.01 /
"""


@pytest.mark.parametrize("peak,ok", [("10.0", True), ("10.5", False)])
def test_the_bound_applies_after_the_record_factor(ellroll, tmp_path, peak, ok):
    (tmp_path / "rec.csv").write_text(f"0, 0, 0\n0.5, {peak}, 1\n2, 0, 0\n")
    (tmp_path / "suite.nml").write_text(SUITE)
    result = run(ellroll, "check", "suite.nml", cwd=tmp_path)
    if ok:
        assert result.returncode == 0, result.stderr
    else:
        assert result.returncode == 2
        assert "rec.csv:2: '10.5' m/s^2 is beyond the bound on ground acceleration, |a| <= 10000 m/s^2 " \
               "(about 1000 g) times the factor 1000" in result.stderr, result.stderr


# --- (b) units from the header; velocity and displacement refused ----------------------------

UNITS = [("G", STANDARD_GRAVITY, 1.0), ("g", STANDARD_GRAVITY, 1.0), ("CM/SEC/SEC", 1.0, 100.0),
         ("CM/S/S", 1.0, 100.0), ("cm/s^2", 1.0, 100.0), ("CM/SEC**2", 1.0, 100.0), ("GAL", 1.0, 100.0),
         ("M/SEC/SEC", 1.0, 1.0), ("M/S/S", 1.0, 1.0), ("m/s^2", 1.0, 1.0)]


@pytest.mark.parametrize("unit,multiplier,divisor", UNITS, ids=[u[0] for u in UNITS])
def test_the_unit_of_an_at2_file_is_its_headers(ellroll, tmp_path, unit, multiplier, divisor):
    """The record in the header's unit equals, bitwise, the CSV of its values
    in m/s^2 (value * multiplier / divisor, one rounding as Python does it)."""
    raw = ground(31, n=300) * 0.5 / (0.05 * multiplier / divisor)        # about 0.5 m/s^2 in each unit
    words = [f"{v:.7E}" for v in raw]
    (tmp_path / "H1.AT2").write_text(at2(words, unit=unit))
    si = [float(w) * multiplier / divisor for w in words]
    rows = [[k * DT, si[k] if k < len(si) else 0.0, 0.0] for k in range(len(si) + 1)]
    (tmp_path / "rec.csv").write_text("".join(", ".join(repr(v) for v in row) + "\n" for row in rows))
    a = run_case(ellroll, tmp_path, "'H1.AT2'", "at2", t_end=2.0)
    b = run_case(ellroll, tmp_path, "'rec.csv'", "csv", t_end=2.0)
    assert_same_trajectories(a, b)
    t, base = base_acceleration(a)
    assert 0.2 < np.abs(base[:, 0]).max() < 2


@pytest.mark.parametrize("name,header,words", [
    ("H1.AT2", dict(unit="FT/S/S"), "H1.AT2:3: unknown unit 'FT/S/S'"),
    ("H1.AT2", dict(unit=""), "H1.AT2:3: unknown unit ''"),
    ("H1.VT2", dict(), "H1.VT2: a velocity record (.VT2)"),
    ("H1.DT2", dict(), "H1.DT2: a displacement record (.DT2)"),
    ("H1.AT2", dict(quantity="VELOCITY", unit="CM/SEC"), "H1.AT2:3: a velocity record (VELOCITY TIME SERIES"),
    ("H1.AT2", dict(quantity="DISPLACEMENT", unit="CM"), "H1.AT2:3: a displacement record"),
    ("H1.AT2", dict(unit="CM/S"), "H1.AT2:3: 'CM/S' is a unit of velocity"),
    ("H1.AT2", dict(unit="CM"), "H1.AT2:3: 'CM' is a unit of displacement"),
    ("rec.txt", dict(quantity="VELOCITY", unit="CM/S"), "rec.txt:3: a velocity record"),
])
def test_an_at2_header_without_an_acceleration_unit_is_refused(ellroll, tmp_path, name, header, words):
    """12.5 cm/s read as g would be 122.6 m/s^2."""
    (tmp_path / name).write_text(at2(["12.5", "13.0", "12.0", "0.5"], **header))
    stderr = refused(ellroll, tmp_path, files=f"'{name}'")
    assert words in stderr, stderr


@pytest.mark.parametrize("third", ["ACCELERATION TIME SERIES", "ACCELERATION TIME SERIES IN GAL",
                                   "ACCELERATION TIME SERIES IN M/S^2"])
def test_an_at2_header_naming_no_unit_is_refused(ellroll, tmp_path, third):
    """A unit is read after the word UNITS only (a G elsewhere in a title
    is no unit): the message says so."""
    (tmp_path / "H1.AT2").write_text(f"PEER\nSYNTHETIC\n{third}\nNPTS=  4, DT= .01 SEC\n .1 .2 .3 .4\n")
    stderr = refused(ellroll, tmp_path)
    assert "H1.AT2:3: the header names no unit after the word UNITS" in stderr and f"'{third}'" in stderr, stderr


@pytest.mark.parametrize("line,factor", [("# units: g", STANDARD_GRAVITY), ("#units = cm/s^2", 0.01),
                                         ("# Units: M/S/S", 1.0), ("", 1.0)])
def test_a_csv_units_line(ellroll, tmp_path, line, factor):
    """Without a units line the accelerations are m/s^2."""
    raw = ground(32, n=200) * 10
    words = [f"{v:.6E}" for v in raw]
    body = "".join(f"{k * DT!r}, {w}, 0\n" for k, w in enumerate(words)) + f"{len(words) * DT!r}, 0, 0\n"
    (tmp_path / "given.csv").write_text(f"{line}\ntime, ax, ay\n" + body)
    si = [float(w) * STANDARD_GRAVITY if factor == STANDARD_GRAVITY else float(w) / 100 if factor == 0.01
          else float(w) for w in words]
    (tmp_path / "si.csv").write_text("".join(f"{k * DT!r}, {v!r}, 0\n" for k, v in enumerate(si + [0.0])))
    a = run_case(ellroll, tmp_path, "'given.csv'", "given", t_end=1.5)
    b = run_case(ellroll, tmp_path, "'si.csv'", "si", t_end=1.5)
    assert_same_trajectories(a, b)


@pytest.mark.parametrize("content,words", [
    ("# units: furlongs\n0, 0, 0\n2, 0, 0\n", "rec.csv:1: unknown unit of acceleration 'furlongs'"),
    ("# units: cm/s\n0, 0, 0\n2, 0, 0\n", "rec.csv:1: unknown unit of acceleration 'cm/s'"),
    ("0, 0, 0\n# units: g\n2, 0, 0\n", "rec.csv:2: a units line comes only once, before the first sample"),
])
def test_bad_csv_units_lines(ellroll, tmp_path, content, words):
    (tmp_path / "rec.csv").write_text(content)
    stderr = refused(ellroll, tmp_path, files="'rec.csv'")
    assert words in stderr, stderr


# --- (c) regular files of bounded size -------------------------------------------------------

@pytest.mark.parametrize("command", [("check",), ("run",), ("run", "--resume")])
def test_a_fifo_is_refused_at_once(ellroll, tmp_path, command):
    """Opening a FIFO waits for a writer: the record is refused before it is opened."""
    os.mkfifo(tmp_path / "H1.AT2")
    (tmp_path / "cup.nml").write_text(CUP.format(files="'H1.AT2'", t_end=1.0, extra=""))
    result = run(ellroll, *command, "cup.nml", cwd=tmp_path, timeout=20)
    assert result.returncode == 2, result.stderr
    assert "record_file = 'H1.AT2': H1.AT2: a FIFO (named pipe), not a regular file" in result.stderr, result.stderr
    assert sorted(p.name for p in tmp_path.iterdir()) == ROOT_FILES


@pytest.mark.parametrize("target,words", [("/dev/zero", "/dev/zero: a character device, not a regular file"),
                                          (".", "a folder, not a regular file")])
def test_a_device_or_a_folder_is_refused(ellroll, tmp_path, target, words):
    """/dev/zero never ends: read as a record it would take all memory."""
    stderr = refused(ellroll, tmp_path, files=f"'{target}'", timeout=10)
    assert words in stderr, stderr


def test_a_record_file_beyond_1_gib_is_refused_unread(ellroll, tmp_path):
    with open(tmp_path / "big.csv", "wb") as f:       # sparse: no disk, no reading
        f.truncate(2**30 + 1)
    stderr = refused(ellroll, tmp_path, files="'big.csv'", timeout=10)
    assert "big.csv: 1073741825 bytes, more than a record file may hold (1 GiB)" in stderr, stderr


def test_a_missing_record_says_why(ellroll, tmp_path):
    stderr = refused(ellroll, tmp_path, files="'none.AT2'")
    assert "cannot open none.AT2: No such file or directory" in stderr, stderr


# --- (d) the numbers as written, to the nearest double ---------------------------------------

def test_values_are_read_to_the_nearest_double_in_every_form(ellroll, tmp_path):
    """Long mantissas, PEER's E forms, D exponents, integers, tiny and
    subnormal-looking values: the AT2 file runs bitwise as the CSV of
    Python's correctly rounded float() of each text times g (a difference of
    one bit in one sample would show in the trajectories). On a cup under g
    = 1e4 m/s^2, which keeps the ball down through the whole record."""
    rng = np.random.default_rng(33)
    forms = [lambda: f"{rng.uniform(-1, 1):.7E}".replace("0.", "."),
             lambda: f"-0.{rng.integers(10**7, 10**8)}E+00",
             lambda: f".{rng.integers(1000, 9999)}E-{rng.integers(1, 9):02d}",
             lambda: f"{rng.uniform(-1, 1):.17e}",
             lambda: f"0.{rng.integers(10**17, 10**18)}{rng.integers(10**17, 10**18)}",
             lambda: f"{rng.uniform(-9, 9):.3f}D-0{rng.integers(0, 9)}",
             lambda: str(rng.integers(-50, 50)),
             lambda: f"+.{rng.integers(10**8, 10**9)}e-{rng.integers(300, 330)}",
             lambda: f"{rng.integers(1, 9)}.{rng.integers(10**15, 10**16)}E-{rng.integers(200, 320)}",
             lambda: "9007199254740993e-16"]
    words = [forms[k % len(forms)]() for k in range(2000)]
    (tmp_path / "H1.AT2").write_text(at2(words, per_line=7))
    si = [float(w.replace("D", "e")) * STANDARD_GRAVITY for w in words] + [0.0]
    (tmp_path / "rec.csv").write_text("".join(f"{k * DT!r}, {v!r}, 0\n" for k, v in enumerate(si)))
    heavy = ", scale = 1.0 /\n&environment g = 10000.0"
    a = run_case(ellroll, tmp_path, "'H1.AT2'", "at2", t_end=19.0, extra=heavy)
    b = run_case(ellroll, tmp_path, "'rec.csv'", "csv", t_end=19.0, extra=heavy)
    assert_same_trajectories(a, b)
    t, base = base_acceleration(a)
    assert len(t) == 1901 and np.all(np.isfinite(base[:, 0])) and np.abs(base[:, 0]).max() > 100


@pytest.mark.parametrize("row", ["1, 1/2, 3", "1, 2*0.5, 3", "1, 0.5, 3.0e", "1, 0x1p-1, 3"])
def test_a_csv_row_is_decimal_numbers_only(ellroll, tmp_path, row):
    """A list-directed read took '1, 1/2, 3' as 1, 1, 0 (the slash ends the
    read) and '2*0.5' as two values: refused as not numbers."""
    (tmp_path / "rec.csv").write_text(f"0, 0, 0\n{row}\n20, 0, 0\n")
    stderr = refused(ellroll, tmp_path, files="'rec.csv'")
    assert f"rec.csv:2: not numbers: {row}" in stderr, stderr


@pytest.mark.parametrize("row,column", [("1,,0.5,0", 2), (",1,0.5,0", 1), ("1;0.5;;0.2", 3), ("1, ,0.5,0", 2),
                                        ("1,0.5,,,0", 3)])
def test_a_csv_row_with_an_empty_value_before_others_is_refused(ellroll, tmp_path, row, column):
    """A spreadsheet's empty cell ('1,,0.5,0': ax left blank) would shift the
    values after it into its column (ay read as ax): refused, naming it."""
    (tmp_path / "rec.csv").write_text(f"time,ax,ay,az\n0,0,0,0\n{row}\n20,0,0,0\n")
    stderr = refused(ellroll, tmp_path, files="'rec.csv'")
    assert f"rec.csv:3: column {column} is empty" in stderr, stderr


@pytest.mark.parametrize("rows", ["0,0,0,\n1,0.5,0,\n20,0,0,\n", "0 0 0\n1 0.5 0\n20 0 0\n",
                                  "0;0;0;;\n1;0.5;0;;\n20;0;0;;\n"])
def test_empty_values_at_a_rows_end_shift_nothing(ellroll, tmp_path, rows):
    """Separators at the end of a row (a trailing comma) leave every value
    in its column: the record is the one without them."""
    (tmp_path / "rec.csv").write_text(rows)
    (tmp_path / "plain.csv").write_text("0,0,0\n1,0.5,0\n20,0,0\n")
    a = run_case(ellroll, tmp_path, "'rec.csv'", "a", t_end=2.0)
    b = run_case(ellroll, tmp_path, "'plain.csv'", "b", t_end=2.0)
    assert_same_trajectories(a, b)


def test_control_characters_a_message_quotes_are_shown_as_question_marks(ellroll, tmp_path):
    """A record line of control bytes (ESC, CR, form feed, bell, DEL) quoted
    in the error: none of them reaches the terminal, the message is one line."""
    (tmp_path / "rec.csv").write_bytes(b"0, 0, 0\n1, \x1b[31mred\x1b[0m\x0c\x07\x7f\r, 2\n20, 0, 0\n")
    stderr = refused(ellroll, tmp_path, files="'rec.csv'")
    assert "rec.csv:2: not numbers: 1, ?[31mred?[0m" in stderr, repr(stderr)
    assert len(stderr.splitlines()) == 1 and not any(ord(c) < 32 and c != "\n" or ord(c) == 127 for c in stderr)


def test_mutated_csv_files_end_cleanly_in_the_debug_build(ellroll_debug, tmp_path):
    """Deleted, doubled and changed characters: a result or a clean error.
    60 files, seeded; ELLROLL_FUZZ_BUDGET=N runs N."""
    text = "# units: g\ntime, ax, ay\n" + "".join(f"{k * 0.01!r}, {v:.6E}, {-v:.4E}\n"
                                              for k, v in enumerate(ground(34, n=30)))
    rng = np.random.default_rng(35)
    (tmp_path / "cup.nml").write_text(CUP.format(files="'rec.csv'", t_end=0.2, extra=""))
    codes = set()
    for _ in range(int(os.environ.get("ELLROLL_FUZZ_BUDGET", "60"))):
        chars = list(text)
        for _ in range(rng.integers(1, 4)):
            k = int(rng.integers(len(chars)))
            op = rng.integers(3)
            if op == 0:
                del chars[k]
            elif op == 1:
                chars.insert(k, chars[k])
            else:
                chars[k] = str(rng.choice(list("0159.-+Ee,;#\t\nxd")))
        (tmp_path / "rec.csv").write_text("".join(chars))
        result = run(ellroll_debug, "check", "cup.nml", cwd=tmp_path)
        assert result.returncode in (0, 2), result.stderr
        codes.add(result.returncode)
    assert codes == {0, 2}


# --- (e) a record shorter than t_end: rest after its end, CSV and AT2 alike ------------------

def test_a_short_csv_is_padded_with_rest_as_an_at2_file_is(ellroll, tmp_path):
    """A 5 s record in a 9 s run: linear to zero over one more step past its
    last sample, then zero; the CSV and the AT2 of the same samples give the
    same run bitwise."""
    acc = ground(36, n=500)                               # g, ends at 4.99 s
    write_at2(tmp_path / "H1.AT2", acc, DT)
    si = [float(v * STANDARD_GRAVITY) for v in acc]
    (tmp_path / "short.csv").write_text("".join(f"{k * DT!r}, {v!r}, 0\n" for k, v in enumerate(si)))
    a = run_case(ellroll, tmp_path, "'H1.AT2'", "at2", t_end=9.0)
    b = run_case(ellroll, tmp_path, "'short.csv'", "csv", t_end=9.0)
    assert_same_trajectories(a, b)
    t, base = base_acceleration(b)
    grid = np.arange(len(si) + 1) * DT
    expected = np.interp(t, grid, np.r_[si, 0.0], right=0.0)
    assert np.abs(base[:, 0] - expected).max() < 1e-12
    assert np.all(base[t >= 5.0 - 1e-12, 0] == 0) and np.abs(base[t < 4.99, 0]).max() > 0.3


def test_a_short_csv_off_a_uniform_grid_ends_over_its_last_step(ellroll, tmp_path):
    (tmp_path / "rec.csv").write_text("0, 0, 0\n0.3, 1.0, 0\n0.5, 2.0, 0\n")     # last step 0.2 s
    path = run_case(ellroll, tmp_path, "'rec.csv'", "uneven", t_end=1.0)
    t, base = base_acceleration(path)
    expected = np.interp(t, [0, 0.3, 0.5, 0.7], [0, 1.0, 2.0, 0.0], right=0.0)
    assert np.abs(base[:, 0] - expected).max() < 1e-12
    assert np.all(base[t >= 0.7 - 1e-12, 0] == 0)


@pytest.mark.parametrize("content,words", [
    ("1, 0, 0\n5, 1, 1\n", "rec.csv: the record starts at 1 s; it must cover t = 0"),
    ("0, 0, 0\n0.0000001, 1, 1\n", "rec.csv:2: time 1e-07 s follows 0 s by less than 1e-06 s"),
    ("0, 0, 0\n2e10, 1, 1\n", "rec.csv:2: time 2e+10 s is beyond +-1e+10 s"),
])
def test_bad_csv_times(ellroll, tmp_path, content, words):
    (tmp_path / "rec.csv").write_text(content)
    stderr = refused(ellroll, tmp_path, files="'rec.csv'")
    assert words in stderr, stderr


@pytest.mark.parametrize("first,words", [("0.0, 0.5x, 0.0", "rec.csv:1: not numbers: 0.0, 0.5x, 0.0"),
                                         ("0.0, 0.5", "rec.csv:1: expected 3 or 4 numbers"),
                                         ("0.0; 0.5; 0.0; 0.1; 0.2", "rec.csv:1: expected 3 or 4 numbers")])
def test_a_csv_s_first_line_led_by_a_number_is_a_sample_with_its_own_error(ellroll, tmp_path, first, words):
    """A header's first word is not a number: a first line led by one is a
    sample, and its typo is named on its line (not dropped as a header,
    which left the record starting at its second sample)."""
    (tmp_path / "rec.csv").write_text(f"{first}\n0.01, 1.0, 0.0\n0.02, 0.0, 0.0\n")
    stderr = refused(ellroll, tmp_path, files="'rec.csv'")
    assert words in stderr, stderr


def test_a_csv_with_a_byte_order_mark_or_a_typo_in_its_first_sample(ellroll, tmp_path):
    """Seeded CSV records (3 or 4 columns, a header line or none): with a
    UTF-8 byte order mark before the first line (a spreadsheet's "CSV
    UTF-8") the run is the plain file's, bit for bit; a first sample line
    with one field mistyped (a letter for a digit) is refused naming line 1,
    not taken for a header (which would drop the sample at t = 0)."""
    rng = np.random.default_rng(1213)
    for trial in range(4):
        columns = int(rng.choice([3, 4]))
        times = np.arange(40) * 0.05
        rows = [[f"{t:.2f}", *(f"{v:.5f}" for v in 0.02 * rng.standard_normal(columns - 1))] for t in times]
        header = ["time,ax,ay" + (",az" if columns == 4 else "")] if trial % 2 else []
        text = "\n".join(header + [",".join(r) for r in rows]) + "\n"
        folder = tmp_path / f"t{trial}"
        folder.mkdir()
        (folder / "plain.csv").write_text(text)
        (folder / "bom.csv").write_bytes(b"\xef\xbb\xbf" + text.encode())
        plain = run_case(ellroll, folder, "'plain.csv'", "plain", t_end=1.0)
        bom = run_case(ellroll, folder, "'bom.csv'", "bom", t_end=1.0)
        assert_same_trajectories(plain, bom)
        typo = [list(r) for r in rows]
        field = int(rng.integers(columns))
        typo[0][field] = typo[0][field].replace("0", "O", 1) if "0" in typo[0][field] else "x" + typo[0][field]
        (folder / "typo.csv").write_text("\n".join(",".join(r) for r in typo) + "\n")
        stderr = refused(ellroll, folder, files="'typo.csv'")
        assert f"typo.csv:1: not numbers: {','.join(typo[0])}" in stderr, stderr
