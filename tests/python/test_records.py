"""Ground-motion records: PEER NGA .AT2 files, one per axis, equal bitwise to
the same record as a CSV in m/s^2 for every header style and layout; scale;
the ground at rest past a record's end; bad files named by file and line."""
import gzip
import resource
import subprocess

import h5py
import numpy as np
import pytest

from conftest import run

STANDARD_GRAVITY = 9.80665
NPTS, DT = 1999, 0.01

CUP = """&geometry a = 1.0, b = 0.4, c = 0.2 /
&ball radius = 0.2, weight = 2620.0 /
&initial x = 0.0, y = 0.0, omega = 0.0, 0.0, 0.0 /
&integration method = 'rk4', dt = 1.0e-3, t_end = {t_end} /
&excitation kind = 'record', record_file = {files}{extra} /
&output file = 'out.h5', interval = 0.01 /
"""


def ground(seed, n=NPTS, dt=DT):
    """A synthetic record in g, with seven significant digits as PEER prints them."""
    rng = np.random.default_rng(seed)
    t = np.arange(n) * dt
    acc = 0.05 * np.sin(2 * np.pi * 0.5 * t) * np.exp(-0.05 * t) + 0.005 * rng.standard_normal(n)
    return np.array([float(f"{v:.6E}") for v in acc])


def write_at2(path, acc, dt, style="new", per_line=5, crlf=False, lower=False, pad=True):
    """The PEER layout: four header lines, then E15.7 fields (the last line padded)."""
    series = "TIME SERIES" if style == "new" else "TIME HISTORY"
    header = ["PEER NGA STRONG MOTION DATABASE RECORD",
              "SYNTHETIC RECORD FOR ELLROLL TESTS, NOT A RECORDED GROUND MOTION",
              f"ACCELERATION {series} IN UNITS OF G"]
    if style == "new":
        header.append(f"NPTS={len(acc):7d}, DT={dt:9.4f} SEC,   0 POLE @ 30.00000 HZ ...")
    else:
        header.append(f"{len(acc)} {dt:.5f} NPTS, DT")
    values = list(acc) + ([0.0] * (-len(acc) % per_line) if pad else [])
    lines = header + ["".join(f"{v:15.7E}" for v in values[i:i + per_line])
                      for i in range(0, len(values), per_line)]
    end = "\r\n" if crlf else "\n"
    text = end.join(lines) + end
    path.write_bytes((text.lower() if lower else text).encode())


def write_csv(path, components, dt):
    """The same record in m/s^2, with the sample one step past the end at rest."""
    n = max(len(c) for c in components)
    rows = [[k * dt] + [float(c[k] * STANDARD_GRAVITY) if k < len(c) else 0.0 for c in components]
            for k in range(n + 1)]
    path.write_text("t, ax, ay\n" + "".join(", ".join(repr(v) for v in row) + "\n" for row in rows))


def run_case(ellroll, folder, files, name, t_end=19.0, extra=""):
    (folder / f"{name}.nml").write_text(CUP.format(files=files, t_end=t_end, extra=extra))
    result = run(ellroll, "run", f"{name}.nml", "-q", "-o", f"{name}.h5", cwd=folder)
    assert result.returncode == 0, result.stderr
    return folder / f"{name}.h5"


def trajectories(path):
    with h5py.File(path, "r") as f:
        return {name: f["trajectory"][name][()] for name in f["trajectory"] if name not in ("case", "time")}


def assert_same_trajectories(a, b):
    ta, tb = trajectories(a), trajectories(b)
    assert sorted(ta) == sorted(tb)
    for name in ta:
        assert ta[name].tobytes() == tb[name].tobytes(), name


@pytest.mark.parametrize("layout", [
    dict(style="new"),
    dict(style="old", per_line=8),
    dict(style="new", crlf=True, lower=True),
    dict(style="old", crlf=True, pad=False),
])
def test_at2_equals_the_csv_bitwise(ellroll, tmp_path, layout):
    x, y = ground(1), ground(2)
    write_at2(tmp_path / "H1.AT2", x, DT, **layout)
    write_at2(tmp_path / "H2.AT2", y, DT, **layout)
    write_csv(tmp_path / "rec.csv", [x, y], DT)
    at2 = run_case(ellroll, tmp_path, "'H1.AT2', 'H2.AT2'", "at2")
    csv = run_case(ellroll, tmp_path, "'rec.csv'", "csv")
    assert_same_trajectories(at2, csv)
    with h5py.File(at2, "r") as f:
        base = f["trajectory/base_acceleration"][0]
        assert np.abs(base[:, 0]).max() > 0.3 and np.all(base[:, 2] == 0)


def test_one_at2_file_shakes_along_x_only(ellroll, tmp_path):
    """inputs.md: an axis without a file is at rest; one AT2 file is x."""
    x = ground(5)
    write_at2(tmp_path / "H1.AT2", x, DT)
    write_csv(tmp_path / "rec.csv", [x, np.zeros(len(x))], DT)
    alone = run_case(ellroll, tmp_path, "'H1.AT2'", "alone", t_end=5.0)
    csv = run_case(ellroll, tmp_path, "'rec.csv'", "csv", t_end=5.0)
    assert_same_trajectories(alone, csv)
    with h5py.File(alone, "r") as f:
        base = f["trajectory/base_acceleration"][0]
        assert np.abs(base[:, 0]).max() > 0.3 and np.all(base[:, 1:] == 0)


@pytest.mark.parametrize("start", [-5.0, -0.5])
def test_a_record_that_ends_before_t_0_is_named(ellroll, tmp_path, start):
    """Samples before 0 are never felt (inputs.md): a record whose samples,
    and its fall to rest, all lie before 0 shakes nothing, and `check` and
    `run` say so (its times offset?); one that reaches past 0 says nothing."""
    rows = "".join(f"{start + k * 0.01!r}, 0.5, 0.2\n" for k in range(100))
    (tmp_path / "rec.csv").write_text("t, ax, ay\n" + rows)
    (tmp_path / "cup.nml").write_text(CUP.format(files="'rec.csv'", t_end=1.0, extra=""))
    for command in ("check", "run"):
        result = run(ellroll, command, "cup.nml", "-q", cwd=tmp_path) if command == "run" else \
            run(ellroll, command, "cup.nml", cwd=tmp_path)
        assert result.returncode == 0, result.stderr
        said = "cup.nml: its record ends before t = 0 (at -4 s, at rest after its last sample)" in result.stderr
        assert said == (start == -5.0), (command, result.stderr)


def test_scale_two_equals_the_doubled_csv(ellroll, tmp_path):
    x, y = ground(3), ground(4)
    write_at2(tmp_path / "H1.AT2", x, DT)
    write_at2(tmp_path / "H2.AT2", y, DT)
    write_csv(tmp_path / "rec.csv", [2 * x, 2 * y], DT)
    scaled = run_case(ellroll, tmp_path, "'H1.AT2', 'H2.AT2'", "scaled", extra=", scale = 2.0")
    doubled = run_case(ellroll, tmp_path, "'rec.csv'", "doubled")
    assert_same_trajectories(scaled, doubled)
    with h5py.File(scaled, "r") as f:
        assert f["case/scale"][0] == 2.0


def test_axes_of_different_length_and_step_and_the_ground_at_rest_after(ellroll, tmp_path):
    x = ground(5, n=1000, dt=0.01)                  # ends at 9.99 s
    y = ground(6, n=1200, dt=0.005)                 # ends at 5.995 s
    z = ground(7, n=300, dt=0.02)
    for name, acc, dt in (("H1.AT2", x, 0.01), ("H2.AT2", y, 0.005), ("UP.AT2", 0.1 * z, 0.02)):
        write_at2(tmp_path / name, acc, dt)
    path = run_case(ellroll, tmp_path, "'H1.AT2', 'H2.AT2', 'UP.AT2'", "mixed", t_end=15.0)
    with h5py.File(path, "r") as f:
        t, base = f["time"][()], f["trajectory/base_acceleration"][0]
        status = f["summary/status"]
        assert status.attrs["flag_meanings"].split()[status[0]] == "completed"
    g = STANDARD_GRAVITY
    for axis, (acc, dt) in enumerate(((x, 0.01), (y, 0.005), (0.1 * z, 0.02))):
        grid = np.arange(len(acc) + 1) * dt
        expected = np.interp(t, grid, np.r_[acc, 0] * g, right=0.0)
        assert np.abs(base[:, axis] - expected).max() < 1e-12, axis
    assert np.all(base[t >= 10.0] == 0)                        # every record has ended: at rest


BAD = [
    ("truncated", lambda: header(10) + "  .1E-01  .2E-01\n", "H1.AT2:5: the file ends after 2 of NPTS = 10"),
    ("values beyond", lambda: header(4) + "  .1E-01  .2E-01  .3E-01  .4E-01\n  .5E-01\n",
     "H1.AT2:6: 5 values where NPTS = 4 (NPTS disagrees with the values)"),
    ("more on the last line", lambda: header(3) + "  .1E-01  .2E-01  .3E-01  .4E-01\n\n",
     "H1.AT2:5: 4 values where NPTS = 3 (NPTS disagrees with the values)"),
    ("text after the values", lambda: header(3) + "  .1E-01  .2E-01  .3E-01 junk\n",
     "H1.AT2:5: 'junk' after the NPTS = 3 values (the values end at NPTS"),
    ("more than padding", lambda: header(3) + "  .1E-01  .2E-01  .3E-01  0.0  .5E-01\n",
     "H1.AT2:5: 5 values where NPTS = 3 (NPTS disagrees with the values)"),
    ("zeros on a later line", lambda: header(3) + "  .1E-01  .2E-01  .3E-01\n  0.0\n",
     "H1.AT2:6: 4 values where NPTS = 3 (NPTS disagrees with the values)"),
    ("values then text", lambda: header(3) + "  .1E-01  .2E-01\n  .3E-01  .4E-01\n\nEND\n",
     "H1.AT2:8: 'END' after the NPTS = 3 values and 1 more"),
    ("non-numeric", lambda: header(4) + "  .1E-01  abc  .3E-01  .4E-01\n", "H1.AT2:5: 'abc' is not a number"),
    ("missing DT", lambda: "a\nb\nc\nNPTS=   4\n .1 .2 .3 .4\n", "H1.AT2:4: no DT on the fourth line"),
    ("DT not a number", lambda: "a\nb\nc\nNPTS=   4, DT= fast\n .1 .2 .3 .4\n", "H1.AT2:4: DT is missing or not a number"),
    ("no NPTS", lambda: "a\nb\nc\nDT= .01 SEC\n .1 .2 .3 .4\n", "H1.AT2:4: no NPTS"),
    ("short header", lambda: "a\nb\n", "H1.AT2:3: the file ends in its header"),
    ("zero DT", lambda: "a\nb\nc\nNPTS=   4, DT= 0.0 SEC\n .1 .2 .3 .4\n", "DT = 0 s must be between"),
    # a unit other than seconds, against the number or apart (the number alone would be read as seconds)
    ("DT in MSEC", lambda: "a\nb\nc\nNPTS=   4, DT= 20 MSEC\n .1 .2 .3 .4\n", "H1.AT2:4: DT's unit 'msec' is not"),
    ("DT in min", lambda: "a\nb\nc\nNPTS=   4, DT=0.02min\n .1 .2 .3 .4\n", "H1.AT2:4: DT's unit 'min' is not"),
    ("NPTS twice", lambda: "a\nb\nc\nNPTS=   4, NPTS= 6, DT= .01 SEC\n .1 .2 .3 .4\n", "H1.AT2:4: NPTS is given twice"),
    ("DT in USEC", lambda: "a\nb\nc\nNPTS=4, DT= 20000 USEC,\n .1 .2 .3 .4\n", "H1.AT2:4: DT's unit 'usec' is not"),
]


def header(npts):
    return f"PEER\nSYNTHETIC\nACCELERATION TIME SERIES IN UNITS OF G\nNPTS= {npts:6d}, DT=   .0100 SEC\n"


# The fourth line as PEER files write it, and as hands and other tools do:
# the unit against the number, no blanks, lower case
DT_LINES = ["NPTS=   4, DT=0.01SEC", "NPTS=4,DT=.01 SEC", "NPTS= 4, DT=0.0100s", "npts=     4, dt=   .0100 sec",
            "NPTS=   4, DT= 1.0E-02 SEC", "NPTS=   4, DT=1.0e-2sec   (synthetic)", "NPTS= 4, DT= .01 seconds",
            "NPTS= 4, DT= .01", "NPTS= 4, DT= .01 (s)", "NPTS= 4, DT= .01 SECS, 2001 record"]


@pytest.mark.parametrize("line", DT_LINES)
def test_dt_is_read_with_its_unit_written_against_it(ellroll, tmp_path, line):
    from test_campaign import assert_same_datasets
    values = "  .1E-01  .2E-01  .3E-01  .4E-01\n"
    for name, fourth in (("standard", "NPTS=      4, DT=   .0100 SEC"), ("variant", line)):
        folder = tmp_path / name
        folder.mkdir()
        (folder / "H1.AT2").write_text(f"PEER\nSYNTHETIC\nACCELERATION TIME SERIES IN UNITS OF G\n{fourth}\n{values}")
        (folder / "cup.nml").write_text(CUP.format(files="'H1.AT2'", t_end=0.05, extra=""))
        result = run(ellroll, "run", "cup.nml", "-q", cwd=folder)
        assert result.returncode == 0, result.stderr
    assert_same_datasets(tmp_path / "standard" / "out.h5", tmp_path / "variant" / "out.h5")


@pytest.mark.parametrize("name, content, words", [
    ("H1.AT2", bytes(4096), "H1.AT2: not a text file (byte 1 is a NUL); a record is a CSV or PEER .AT2 text file"),
    ("rec.csv", b"t, ax, ay\n0, 0, 0\n\x001, 0, 0\n", "rec.csv: not a text file (byte 19 is a NUL)"),
    ("H1.AT2", gzip.compress(b"PEER\n" * 100), "H1.AT2: gzip-compressed (it begins 1f 8b): decompress it; a record"),
])
def test_a_binary_record_file_is_named_not_read(ellroll, tmp_path, name, content, words):
    """A record file that is not text (NUL bytes, a gzip file): one line
    naming the file and what it is, not its bytes."""
    (tmp_path / name).write_bytes(content)
    (tmp_path / "cup.nml").write_text(CUP.format(files=f"'{name}'", t_end=1.0, extra=""))
    result = run(ellroll, "run", "cup.nml", cwd=tmp_path)
    assert result.returncode == 2 and words in result.stderr, result.stderr
    assert result.stderr.isascii() and "\x00" not in result.stderr and len(result.stderr.splitlines()) == 1


@pytest.mark.parametrize("label,content,words", BAD, ids=[b[0] for b in BAD])
def test_bad_at2_files(ellroll, tmp_path, label, content, words):
    (tmp_path / "H1.AT2").write_text(content())
    (tmp_path / "cup.nml").write_text(CUP.format(files="'H1.AT2'", t_end=1.0, extra=""))
    result = run(ellroll, "run", "cup.nml", cwd=tmp_path)
    assert result.returncode == 2, result.stderr
    assert "cup.nml:5: &excitation: record_file = 'H1.AT2'" in result.stderr and words in result.stderr, \
        result.stderr
    assert sorted(p.name for p in tmp_path.iterdir()) == ["H1.AT2", "cup.nml"]


def test_mutated_at2_files_end_cleanly_in_the_debug_build(ellroll_debug, tmp_path):
    """Deleted, doubled and changed characters anywhere: a clean result or a
    clean error (exit 2), never a signal, under -fcheck=all and traps."""
    write_at2(tmp_path / "good.AT2", ground(8, n=40), DT)
    text = (tmp_path / "good.AT2").read_text()
    rng = np.random.default_rng(9)
    (tmp_path / "cup.nml").write_text(CUP.format(files="'H1.AT2'", t_end=0.3, extra=""))
    codes = set()
    for _ in range(60):
        chars = list(text)
        for _ in range(rng.integers(1, 4)):
            k = int(rng.integers(len(chars)))
            op = rng.integers(3)
            if op == 0:
                del chars[k]
            elif op == 1:
                chars.insert(k, chars[k])
            else:
                chars[k] = str(rng.choice(list("0159.-+E ,=\nxN")))
        (tmp_path / "H1.AT2").write_text("".join(chars))
        result = run(ellroll_debug, "check", "cup.nml", cwd=tmp_path)
        assert result.returncode in (0, 2), result.stderr
        codes.add(result.returncode)
    assert codes == {0, 2}


SUITE = """&geometry a = 1.0, b = 0.4, c = 0.2 /
&ball radius = 0.2, weight = 2620.0 /
&initial omega = 0.0, 0.0, 0.0 /
&integration method = 'rk4', dt = 1.0e-3, t_end = 12.0 /
&excitation kind = 'record' /
&record name = 'first', record_file = 'A1.AT2', 'A2.AT2' /
&record name = 'second', record_file = 'B1.AT2', 'B2.AT2', factor = 0.5 /
&record name = 'third', record_file = 'C.csv' /
&sweep name = 'scale', values = 1.0, 2.0 /
&output file = 'suite.h5', interval = 0.01 /
"""


def write_suite_records(folder):
    for name, seed in (("A1", 21), ("A2", 22), ("B1", 23), ("B2", 24)):
        write_at2(folder / f"{name}.AT2", ground(seed), DT)
    write_csv(folder / "C.csv", [ground(25), ground(26)], DT)


def test_a_suite_is_each_record_run_alone(ellroll, tmp_path):
    """Records vary slowest, then the sweep; each case equals the same record
    run alone at the same scale (a record's factor times the values)."""
    write_suite_records(tmp_path)
    (tmp_path / "suite.nml").write_text(SUITE)
    result = run(ellroll, "run", "suite.nml", "-q", cwd=tmp_path)
    assert result.returncode == 0, result.stderr
    with h5py.File(tmp_path / "suite.h5", "r") as f:
        assert [n.decode().strip() for n in f["case/record"][:]] == ["first"] * 2 + ["second"] * 2 + ["third"] * 2
        assert list(f["case/record_factor"][:]) == [1, 1, 0.5, 0.5, 1, 1]
        assert list(f["case/scale"][:]) == [1, 2] * 3
        suite = {name: f["trajectory"][name][()] for name in f["trajectory"] if name not in ("case", "time")}
    alone = [("'A1.AT2', 'A2.AT2'", 1.0), ("'A1.AT2', 'A2.AT2'", 2.0), ("'B1.AT2', 'B2.AT2'", 0.5),
             ("'B1.AT2', 'B2.AT2'", 1.0), ("'C.csv'", 1.0), ("'C.csv'", 2.0)]
    for case, (files, scale) in enumerate(alone):
        single = trajectories(run_case(ellroll, tmp_path, files, f"alone{case}", t_end=12.0,
                                       extra=f", scale = {scale}"))
        for name in single:
            assert single[name][0].tobytes() == suite[name][case].tobytes(), (case, name)


@pytest.mark.parametrize("change,words", [
    (("name = 'second'", "name = 'first'"), "name = 'first': already names the &record at line 6"),
    (("name = 'third', ", ""), "&record: name is required"),
    (("&excitation kind = 'record' /", "&excitation kind = 'harmonic', frequency = 1 /"),
     "kind = 'harmonic': must be 'record' with &record groups"),
    (("&excitation kind = 'record' /", "&excitation kind = 'record', record_file = 'C.csv' /"),
     "the &record groups give the records"),
    (("factor = 0.5", "factor = -1"), "factor = -1: must be between 0 and 1000"),
    (("'B1.AT2', 'B2.AT2'", "'B1.AT2', 'missing.AT2'"), "suite.nml:7: &record: record_file = 'B1.AT2', "
                                                        "'missing.AT2': cannot open"),
])
def test_bad_suites(ellroll, tmp_path, change, words):
    write_suite_records(tmp_path)
    (tmp_path / "suite.nml").write_text(SUITE.replace(*change))
    result = run(ellroll, "check", "suite.nml", cwd=tmp_path)
    assert result.returncode == 2 and words in result.stderr, result.stderr


def test_a_suite_without_excitation_group_is_a_record_campaign(ellroll, tmp_path):
    write_suite_records(tmp_path)
    (tmp_path / "suite.nml").write_text(SUITE.replace("&excitation kind = 'record' /\n", "")
                                        .replace("&sweep name = 'scale', values = 1.0, 2.0 /\n", ""))
    result = run(ellroll, "check", "suite.nml", cwd=tmp_path)
    assert result.returncode == 0 and "campaign: 3 cases" in result.stdout, result.stderr


def test_a_suite_is_the_same_for_any_thread_count_and_sharding(ellroll, tmp_path):
    from test_campaign import assert_same_datasets
    write_suite_records(tmp_path)
    (tmp_path / "suite.nml").write_text(SUITE.replace("t_end = 12.0", "t_end = 3.0")
                                        .replace("weight = 2620.0 /", "weight = 2620.0, rolling_resistance = 1.0e-4 /"))
    assert run(ellroll, "run", "suite.nml", "-q", "-o", "one.h5", "--threads", "1", cwd=tmp_path).returncode == 0
    assert run(ellroll, "run", "suite.nml", "-q", "-o", "two.h5", "--threads", "2", cwd=tmp_path).returncode == 0
    for index in range(2):
        assert run(ellroll, "run", "suite.nml", "-q", "--shard", f"{index}/2", "-o", f"s{index}.h5",
                   cwd=tmp_path).returncode == 0
    assert run(ellroll, "merge", "merged.h5", "s0.h5", "s1.h5", cwd=tmp_path).returncode == 0
    assert_same_datasets(tmp_path / "one.h5", tmp_path / "two.h5")
    assert_same_datasets(tmp_path / "one.h5", tmp_path / "merged.h5")


def test_a_long_record_is_held_once_for_every_case_of_a_batch(ellroll, tmp_path):
    """A record of 2e6 samples (64 MB in memory) shaking 16 cases (two SIMD
    batches) in a process limited to 1.2 GB of address space (ulimit -v):
    held once for all, the cases complete. (A copy per case, ball and lane
    would be 25 of them for a batch of 8.)"""
    n = 2_000_000
    period = " ".join(f"{0.01 * np.sin(2 * np.pi * k / 1000):.4E}" for k in range(1000))
    values = " ".join([period] * (n // 1000))
    (tmp_path / "long.AT2").write_text(f"PEER\nX\nACCELERATION TIME SERIES IN UNITS OF G\nNPTS= {n}, DT= 0.0010 SEC\n"
                                       f"{values}\n")
    (tmp_path / "cup.nml").write_text(CUP.format(files="'long.AT2'", t_end=0.5, extra="")
                                      + "&sweep name = 'scale', start = 1, stop = 2, count = 16 /\n")
    limit = 1200 << 20
    result = subprocess.run([str(ellroll), "run", "cup.nml", "-q", "--threads", "1"], cwd=tmp_path,
                            capture_output=True, text=True, timeout=120,
                            preexec_fn=lambda: resource.setrlimit(resource.RLIMIT_AS, (limit, limit)))
    assert result.returncode == 0, result.stderr
    with h5py.File(tmp_path / "out.h5", "r") as f:
        assert np.all(f["summary/status"][:] == 1)
