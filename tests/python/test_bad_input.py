"""Every class of bad input: exit 2, a message naming file, line, group,
variable and value, and no output file created or touched."""
import re

import pytest

from conftest import PAPER_INPUT, ROOT, run

# (id, edits to the paper's input, words the message must contain)
CASES = [
    ("unknown group", [("&geometry", "&geomtry")], ["case.nml:4:", "unknown group &geomtry"]),
    ("unknown variable", [("radius = 0.2", "radus = 0.2")],
     ["case.nml:5:", "&ball", "unknown variable radus = 0.2", "radius"]),
    ("missing value", [(", c = 0.2", "")], ["case.nml:4:", "&geometry", "c is required"]),
    ("missing group", [("&ball        radius = 0.2, weight = 2620.0 /", "")], ["&ball", "missing"]),
    ("negative length", [("b = 0.4", "b = -0.4")], ["case.nml:4:", "&geometry", "b = -0.4", "must be"]),
    ("zero dt", [("dt = 1.0e-3", "dt = 0.0")], ["case.nml:8:", "&integration", "dt = 0.0", "must be > 0"]),
    ("ball does not fit", [("radius = 0.2", "radius = 0.9")],
     ["case.nml:5:", "&ball", "radius = 0.9", "does not fit", "0.8 m"]),
    ("ball within the fit margin", [("radius = 0.2", "radius = 0.7999995")],
     ["case.nml:5:", "&ball", "radius = 0.7999995", "does not fit", "below 0.8 m / (1 + fit_margin) = 0.7999992 m"]),
    ("start outside the cup", [("x = 0.0", "x = 1.5")], ["case.nml:7:", "&initial", "x = 1.5", "not inside the cup"]),
    ("interval not a multiple of dt", [("interval = 0.01", "interval = 0.0125")],
     ["case.nml:9:", "&output", "interval = 0.0125", "whole number of steps"]),
    ("t_end not a multiple of interval", [("interval = 0.01", "interval = 0.07")],
     ["&output", "interval = 0.07", "whole number of output intervals"]),
    ("malformed number", [("dt = 1.0e-3", "dt = 1.0e-3.5")], ["case.nml:8:", "&integration", "dt = 1.0e-3.5", "dt = 1.0e-3.5 is not a number"]),
    ("text for a number", [("dt = 1.0e-3", "dt = 'fast'")], ["&integration", "dt = 'fast'", "dt = 'fast' is not a number"]),
    # (gfortran's namelist read takes a sign alone for 0)
    ("a sign alone", [("x = 0.0", "x = -")], ["case.nml:7:", "&initial", "x = - is not a number"]),
    ("a plus sign alone", [("dt = 1.0e-3", "dt = +")], ["case.nml:8:", "&integration", "dt = + is not a number"]),
    ("a repeated sign alone", [("interval = 0.01", "interval = 1*-")], ["&output", "interval = 1*-: - is not a number"]),
    ("NaN", [("a = 1.0", "a = NaN")], ["case.nml:4:", "&geometry", "a = NaN", "finite"]),
    ("infinity", [("t_end = 30.0", "t_end = Inf")], ["&integration", "t_end = Inf", "finite"]),
    ("huge", [("a = 1.0", "a = 1e300")], ["&geometry", "a = 1e300", "must be between"]),
    ("given twice", [("a = 1.0", "a = 1.0, a = 2.0")], ["case.nml:4:", "&geometry", "given twice"]),
    ("vector and its element", [("omega = -2.0, 2.0, 20.0", "omega(3) = 5.0, omega = -2.0, 2.0, 20.0")],
     ["case.nml:7:", "&initial", "omega = -2.0, 2.0, 20.0", "given twice"]),
    ("group twice", [("&environment g = 9.81 /", "&environment g = 9.81 /\n&environment g = 9.8 /")],
     ["&environment appears twice"]),
    ("unknown method", [("'rk4'", "'euler'")], ["&integration", "method = 'euler'", "unknown method", "rk4"]),
    ("unknown field", [("interval = 0.01 /", "interval = 0.01, fields = 'speed' /")],
     ["&output", "unknown field 'speed'", "nutation"]),
    ("compression out of range", [("interval = 0.01 /", "interval = 0.01, compression = 12 /")],
     ["case.nml:9:", "&output", "compression = 12", "0 (none) to 9"]),
    ("too few omega components", [("omega = -2.0, 2.0, 20.0", "omega = -2.0, 2.0")],
     ["case.nml:7:", "&initial", "omega = -2.0, 2.0", "three finite numbers"]),
    ("weight and mass", [("weight = 2620.0", "weight = 2620.0, mass = 267.0")], ["&ball", "not both"]),
    ("text outside groups", [("&output", "garbage\n&output")], ["case.nml:9:", "unexpected text", "garbage"]),
    ("group not closed", [("interval = 0.01 /", "interval = 0.01")], ["&output", "not closed"]),
    ("no trailing newline", [("interval = 0.01 /   ! every 0.01 s\n", "interval = 0.01 /   ! every 0.01 s")],
     ["case.nml:9:", "does not end with a newline"]),
    ("unclosed string", [("'rk4'", "'rk4")], ["case.nml:8:", "string is not closed"]),
    ("equals without a name", [("dt = 1.0e-3", "= 1.0e-3")], ["case.nml:8:", "without a variable name"]),
    ("empty value", [("dt = 1.0e-3", "dt = ")], ["case.nml:8:", "dt = (nothing)"]),
]


@pytest.mark.parametrize("edits,words", [c[1:] for c in CASES], ids=[c[0] for c in CASES])
def test_bad_input_exits_2_and_touches_no_output(ellroll, tmp_path, edits, words):
    text = PAPER_INPUT.read_text()
    for old, new in edits:
        assert old in text, old
        text = text.replace(old, new)
    (tmp_path / "case.nml").write_text(text)

    # no output file is created
    result = run(ellroll, "run", "case.nml", "-o", "new.h5", cwd=tmp_path)
    assert result.returncode == 2, result.stdout + result.stderr
    message = result.stderr
    assert message.startswith("ellroll: error: case.nml"), message
    for w in words:
        assert w in message, f"{w!r} not in {message!r}"
    assert sorted(p.name for p in tmp_path.iterdir()) == ["case.nml"]

    # an existing good file is left byte-identical
    good = tmp_path / "legeza1990.h5"
    good.write_bytes(b"\x89HDF\r\n\x1a\n a good result")
    before = good.read_bytes()
    for command in (["run", "case.nml", "--overwrite"], ["check", "case.nml"]):
        result = run(ellroll, *command, cwd=tmp_path)
        assert result.returncode == 2
    assert good.read_bytes() == before
    assert sorted(p.name for p in tmp_path.iterdir()) == ["case.nml", "legeza1990.h5"]


@pytest.mark.parametrize("args,words", [
    (["run"], "needs an input file"),
    (["run", "missing.nml"], "missing.nml: input file not found"),
    (["run", "."], ".: a folder, not an input file"),
    (["run", "a.nml", "b.nml"], "more than one input file"),
    (["run", "a.nml", "--fast"], "unknown option --fast"),
    (["run", "a.nml", "-o"], "-o needs a value"),
    (["run", "a.nml", "-o", ""], "-o needs a file name, not an empty text"),
    (["run", "a.nml", "--output", "  "], "--output needs a file name, not an empty text"),
    (["run", "a.nml", "--threads", "0"], "--threads needs a positive number"),
    (["run", "a.nml", "--shard", "2/2"], "--shard needs I/N"),
    (["run", "a.nml", "--resume", "--overwrite"], "exclude each other"),
    (["merge", "out.h5"], "at least one shard file"),
    ([], "no command given"),
])
def test_bad_command_line(ellroll, tmp_path, args, words):
    result = run(ellroll, *args, cwd=tmp_path)
    assert result.returncode == 2
    assert words in result.stderr


@pytest.mark.parametrize("command, needs", [("run", "an input file"), ("check", "an input file"),
                                            ("summary", "an input file"), ("modes", "an input file"),
                                            ("merge", "an output file and shard files")])
def test_a_command_without_its_file_is_one_trimmed_line(ellroll, tmp_path, command, needs):
    result = run(ellroll, command, cwd=tmp_path)
    assert result.returncode == 2
    assert result.stderr == f"ellroll: error: {command} needs {needs} (see 'ellroll --help')\n", result.stderr


def test_the_docs_name_only_commands_ellroll_has(ellroll):
    """Every `ellroll WORD` the docs write is a command of `ellroll --help`."""
    usage = run(ellroll, "--help").stdout
    commands = set(re.findall(r"^  ellroll ([a-z]+)", usage, flags=re.M))
    assert {"run", "check", "merge", "summary"} <= commands, usage
    pages = [ROOT / "README.md", ROOT / "post" / "README.md", *sorted((ROOT / "docs").glob("*.md"))]
    named = {(page.name, word) for page in pages for word in re.findall(r"`ellroll ([a-z]+)", page.read_text())}
    assert {(page, word) for page, word in named if word not in commands} == set()


def test_empty_file(ellroll, tmp_path):
    (tmp_path / "empty.nml").write_text("")
    result = run(ellroll, "check", "empty.nml", cwd=tmp_path)
    assert result.returncode == 2 and "empty.nml:1: the file is empty" in result.stderr


@pytest.mark.parametrize("path", ["/proc/self/status", "/proc/self/environ", "/proc/cpuinfo"])
def test_a_file_that_holds_more_than_its_size_is_refused_as_such(ellroll, tmp_path, path):
    """procfs gives its files size 0 and text: not 'empty', but not a file on a disk."""
    for command in ("check", "run"):
        result = run(ellroll, command, path, cwd=tmp_path)
        assert result.returncode == 2, result.stderr
        assert f"{path}: the file holds more than its size (0 bytes)" in result.stderr, result.stderr
        assert "regular file" in result.stderr and len(result.stderr.splitlines()) == 1, result.stderr
    assert list(tmp_path.iterdir()) == []


# Every list input of the namelist, a number that is not finite (each
# spelling gfortran reads) at its first, a middle and its last place: the
# list is refused, naming the value and its place. (A trailing NaN is where
# a list that starts as NaN cannot tell it from an entry not given.)
NOT_FINITE = ["NaN", "nan", "NaN()", "-NaN", "nan(0x7ff4)", "Inf", "-Infinity", "+inf"]
LIST_BASE = {
    "geometry": {"a": "1.0", "b": "0.4", "c": "0.2"},
    "ball": {"radius": "0.2", "weight": "2620.0", "mu": "0.1", "slip": "'slide'"},
    "initial": {"x": "0.0", "y": "0.0", "omega": "0.0, 0.0, 0.0", "velocity": "0.5, 0.0, 0.0"},
    "integration": {"method": "'rk4'", "dt": "1.0e-3", "t_end": "1.0"},
    "excitation": {"kind": "'record'", "record_file": "'{records}/SYN1_H1.AT2', '{records}/SYN1_H2.AT2'",
                   "sa_periods": "0.2, 0.5, 1.0"},
    "output": {"file": "'x.h5'", "interval": "0.01"},
    "sweep": {"name": "'mu'", "values": "0.05, 0.1"},
}
# (group, variable, good values)
LISTS = [
    ("initial", "omega", ["0.0", "0.0", "0.0"]),
    ("initial", "velocity", ["0.5", "0.0", "0.0"]),
    ("excitation", "sa_periods", ["0.2", "0.5", "1.0", "2.0"]),
    ("sweep", "values", ["0.05", "0.1", "0.2", "0.3"]),
]
RANDOM_LISTS = 4


def list_inputs(rng):
    """(group, variable, value text, place of the bad value) for every list
    input, each bad spelling at its first, middle and last place, and lists
    of random length with a bad value at a random place (seeded)."""
    for group, variable, good in LISTS:
        for place in (0, len(good) // 2, len(good) - 1):
            for bad in NOT_FINITE:
                values = list(good)
                values[place] = bad
                yield group, variable, ", ".join(values), place + 1
        if variable in ("values", "sa_periods"):
            for _ in range(RANDOM_LISTS):
                n = rng.randint(1, 12)
                values = [f"{0.05 * (k + 1):.3g}" for k in range(n)]
                place = rng.randrange(n)
                values[place] = rng.choice(NOT_FINITE)
                yield group, variable, ", ".join(values), place + 1


def test_a_list_with_a_value_not_finite_anywhere_is_refused(ellroll, tmp_path):
    import random
    rng = random.Random(8)
    records = (PAPER_INPUT.parent / "records").resolve()
    tried = 0
    for group, variable, value, place in list_inputs(rng):
        groups = {name: dict(body) for name, body in LIST_BASE.items()}
        groups[group][variable] = value
        text = "".join(f"&{name} " + ", ".join(f"{k} = {v}" for k, v in body.items()) + " /\n"
                       for name, body in groups.items()).format(records=records)
        (tmp_path / "case.nml").write_text(text)
        result = run(ellroll, "check", "case.nml", cwd=tmp_path)
        context = f"{group} {variable} = {value}: {result.stderr}"
        assert result.returncode == 2, context
        line = list(groups).index(group) + 1
        assert result.stderr.startswith(f"ellroll: error: case.nml:{line}: &{group}: {variable} = {value}: "), context
        if variable in ("values", "sa_periods"):
            assert f"value {place} is " in result.stderr, context
        else:
            assert "three finite numbers are needed" in result.stderr, context
        tried += 1
    assert tried == 3 * len(NOT_FINITE) * len(LISTS) + 2 * RANDOM_LISTS


@pytest.mark.parametrize("assignment,words", [
    ("values = 5.0, , 10.0", "value 2 is not given"),
    ("values(3) = 2.0", "value 1 is not given"),
    ("values = 2*NaN", "value 1 is NaN"),
    ("values = 0.1, 2*Inf", "value 2 is Infinity"),
])
def test_a_gap_or_repeated_bad_value_in_a_sweep_is_named(ellroll, tmp_path, assignment, words):
    text = PAPER_INPUT.read_text() + f"&sweep name = 'omega_z', {assignment} /\n"
    (tmp_path / "case.nml").write_text(text)
    result = run(ellroll, "check", "case.nml", cwd=tmp_path)
    assert result.returncode == 2 and f"&sweep: {assignment}: {words}" in result.stderr, result.stderr


def shard_specs(rng, n):
    """n malformed --shard values (seeded): a well-formed I/N with text
    before, inside or after it, and I/N outside 0 <= I < N."""
    garbage = ["/3", "x", " ", ",", ",3", "/", ".0", "e0", "+", "-", "*", "0x", "\t", "/2/3"]
    specs = ["1/2/3", "1/2x", "1/", "/2", "/", "", "1", "2/2", "3/2", "-1/2", "1/0", "99999999999/1",
             "0/99999999999"]
    while len(specs) < n:
        count = rng.randint(1, 40)
        index = rng.randrange(count)
        where, piece = rng.randrange(4), rng.choice(garbage)
        spec = [f"{piece}{index}/{count}", f"{index}{piece}/{count}", f"{index}/{piece}{count}",
                f"{index}/{count}{piece}"][where]
        specs.append(spec)
    return specs


def test_malformed_shards_are_refused_and_good_ones_taken(ellroll, tmp_path):
    import random
    rng = random.Random(12)
    (tmp_path / "case.nml").write_text(PAPER_INPUT.read_text())
    for spec in shard_specs(rng, 60):
        result = run(ellroll, "check", "case.nml", "--shard", spec, cwd=tmp_path)
        assert result.returncode == 2, spec
        index, _, count = spec.partition("/")
        if re.fullmatch("[0-9]+", index) and re.fullmatch("[0-9]+", count) and int(count) > 2147483647:
            assert f"--shard {spec}: too large (N at most 2147483647) " in result.stderr, (spec, result.stderr)
        else:
            assert f"--shard needs I/N with 0 <= I < N, not {spec} " in result.stderr, (spec, result.stderr)
    for _ in range(5):
        count = rng.randint(1, 40)
        spec = f"{rng.randrange(count)}/{count}"
        assert run(ellroll, "check", "case.nml", "--shard", spec, cwd=tmp_path).returncode == 0, spec
    # N beyond a default integer (leading zeros do not count; an I beyond it is not below N)
    assert run(ellroll, "check", "case.nml", "--shard", "1/2147483647", cwd=tmp_path).returncode == 0
    for spec in ("1/2147483648", "1/99999999999", "0/9999999999999999999999", "0001/00002147483648"):
        result = run(ellroll, "check", "case.nml", "--shard", spec, cwd=tmp_path)
        assert result.returncode == 2, spec
        assert f"--shard {spec}: too large (N at most 2147483647) " in result.stderr, (spec, result.stderr)
    for threads in ["2/3", "2 x", "1.5", "+2", "0x2", ""]:
        result = run(ellroll, "check", "case.nml", "--threads", threads, cwd=tmp_path)
        assert result.returncode == 2 and f"--threads needs a positive number, not {threads} " in result.stderr, \
            (threads, result.stderr)
    result = run(ellroll, "check", "case.nml", "--threads", "99999999999", cwd=tmp_path)
    assert result.returncode == 2 and "--threads 99999999999: too large (at most 2147483647" in result.stderr, \
        result.stderr


# mu: unset is 'not limited'; a given mu must be > 0, whatever the slip
# mode, and a 0 in a sweep makes that case invalid, with the same words.
MU_ZERO = ["0", "0.0", "-0.0", "0e0", "0.000", "+0d0"]


@pytest.mark.parametrize("slip", ["end", "slide"])
def test_mu_zero_is_refused_with_the_way_to_unlimited_friction(ellroll, tmp_path, slip):
    for zero in MU_ZERO:
        text = PAPER_INPUT.read_text().replace("weight = 2620.0", f"weight = 2620.0, mu = {zero}, slip = '{slip}'")
        (tmp_path / "case.nml").write_text(text)
        for command in ("check", "run"):
            result = run(ellroll, command, "case.nml", "-o", "x.h5", cwd=tmp_path)
            assert result.returncode == 2, (zero, result.stderr)
            assert result.stderr.startswith(f"ellroll: error: case.nml:5: &ball: mu = {zero}: must be > 0 and "
                                            "<= 1000000 (leave mu out for unlimited friction)"), result.stderr
        assert not (tmp_path / "x.h5").exists()


def test_a_sweep_of_mu_reaching_zero_makes_that_case_invalid(ellroll, tmp_path):
    import random
    import h5py
    rng = random.Random(7)
    for trial in range(3):
        values = [round(rng.uniform(0.05, 0.5), 3) for _ in range(rng.randint(2, 5))]
        zero = rng.randrange(len(values))
        values[zero] = 0.0
        sweep = f"&sweep name = 'mu', values = {', '.join(map(str, values))} /\n"
        (tmp_path / "case.nml").write_text(PAPER_INPUT.read_text().replace("t_end = 30.0", "t_end = 0.5") + sweep)
        result = run(ellroll, "check", "case.nml", cwd=tmp_path)
        assert result.returncode == 2, result.stderr
        assert f"case.nml: case {zero} (mu = 0): mu = 0: must be > 0 and <= 1000000 (leave mu out for " \
               "unlimited friction)" in result.stderr, result.stderr
        (tmp_path / "case.nml").write_text((tmp_path / "case.nml").read_text() + "&campaign invalid = 'skip' /\n")
        result = run(ellroll, "run", "case.nml", "-q", "--overwrite", "-o", "x.h5", cwd=tmp_path)
        assert result.returncode == 0, result.stderr
        with h5py.File(tmp_path / "x.h5") as f:
            meanings = f["summary/status"].attrs["flag_meanings"].split()
            statuses = [meanings[s] for s in f["summary/status"][:]]
            assert [s == "invalid" for s in statuses] == [k == zero for k in range(len(values))], statuses
            assert list(f["case/mu"][:]) == values


def test_a_sweep_of_the_displacement_capacity_is_checked_case_by_case(ellroll, tmp_path):
    """&output capacity swept (docs/campaigns.md): a case at 0 or below is
    invalid with the range's words, the others run."""
    sweep = "&sweep name = 'capacity', values = 0.05, 0.0, -1.0, 0.2 /\n"
    (tmp_path / "case.nml").write_text(PAPER_INPUT.read_text().replace("t_end = 30.0", "t_end = 0.5") + sweep)
    result = run(ellroll, "check", "case.nml", cwd=tmp_path)
    assert result.returncode == 2, result.stderr
    for case, value in ((1, "0"), (2, "-1")):
        assert f"case.nml: case {case} (capacity = {value}): capacity = {value}: must be > 0 and <= 1000000 m" \
            in result.stderr, result.stderr
    assert "case 0" not in result.stderr and "case 3" not in result.stderr


def test_mu_left_out_is_not_limited(ellroll, tmp_path):
    """The paper's case needs up to 0.0759 of friction: unset, no limit
    ends it, and /case/mu is NaN; mu just below what it needs ends it with slip."""
    import h5py
    import math
    text = PAPER_INPUT.read_text().replace("t_end = 30.0", "t_end = 1.0")
    (tmp_path / "case.nml").write_text(text)
    assert run(ellroll, "run", "case.nml", "-q", "-o", "free.h5", cwd=tmp_path).returncode == 0
    with h5py.File(tmp_path / "free.h5") as f:
        meanings = f["summary/status"].attrs["flag_meanings"].split()
        assert meanings[f["summary/status"][0]] == "completed" and math.isnan(f["case/mu"][0])
        needed = float(f["summary/friction_needed_max"][0])
    assert needed > 0.01
    (tmp_path / "case.nml").write_text(text.replace("weight = 2620.0", f"weight = 2620.0, mu = {needed * 0.9!r}"))
    assert run(ellroll, "run", "case.nml", "-q", "-o", "slip.h5", cwd=tmp_path).returncode == 0
    with h5py.File(tmp_path / "slip.h5") as f:
        meanings = f["summary/status"].attrs["flag_meanings"].split()
        assert meanings[f["summary/status"][0]] == "slip" and f["case/mu"][0] == needed * 0.9


@pytest.mark.parametrize("where", ["a value", "text before the first variable"])
def test_a_value_of_megabytes_is_refused_with_a_short_message_on_a_small_stack(ellroll, tmp_path, where):
    """A 12 MB value (600,000 sweep values; the limit is 10,000) or 12 MB of
    stray text: exit 2 naming the group and the value's start and length,
    under a 1 MiB stack (the text is never copied to the stack)."""
    values = ", ".join(repr(1 + k * 1e-6) for k in range(600_000))
    if where == "a value":
        text = PAPER_INPUT.read_text() + f"&sweep name = 'radius', values = {values} /\n"
        words = ["case.nml:", "&sweep: values = 1.0, 1.000001,", "characters): 600000 values given; values holds 10000"]
    else:
        text = PAPER_INPUT.read_text() + f"&sweep {values} name = 'radius', values = 0.2 /\n"
        words = ["case.nml:", 'unexpected text "1.0, 1.000001,', "characters)\" in &sweep before the first variable"]
    (tmp_path / "case.nml").write_text(text)
    result = run("bash", "-c", f"ulimit -s 1024 && exec {ellroll} check case.nml", cwd=tmp_path)
    assert result.returncode == 2, result.stderr[-300:]
    assert len(result.stderr) < 400
    for word in words:
        assert word in result.stderr


@pytest.mark.parametrize("kind", ["fifo", "pipe"])
def test_an_input_that_is_not_a_regular_file_is_refused_by_name(ellroll, tmp_path, kind):
    """A FIFO with no writer would block for ever, a pipe reads as empty:
    both refused, naming the path and what it is."""
    import os
    import subprocess
    if kind == "fifo":
        os.mkfifo(tmp_path / "in.nml")
        result = run(ellroll, "check", "in.nml", cwd=tmp_path, timeout=20)
        path = "in.nml"
    else:
        result = subprocess.run([str(ellroll), "check", "/dev/stdin"], input=PAPER_INPUT.read_text(), cwd=tmp_path,
                                capture_output=True, text=True, timeout=20)
        path = "/dev/stdin"
    assert result.returncode == 2
    assert f"{path}: a FIFO (named pipe), not a regular file; an input file is read from a regular file" \
        in result.stderr
