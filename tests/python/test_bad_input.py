"""Every class of bad input: exit 2, a message naming file, line, group,
variable and value, and no output file created or touched."""
import pytest

from conftest import PAPER_INPUT, run

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
    ("start outside the cup", [("x = 0.0", "x = 1.5")], ["case.nml:7:", "&initial", "x = 1.5", "not inside the cup"]),
    ("interval not a multiple of dt", [("interval = 0.01", "interval = 0.0125")],
     ["case.nml:9:", "&output", "interval = 0.0125", "whole number of steps"]),
    ("t_end not a multiple of interval", [("interval = 0.01", "interval = 0.07")],
     ["&output", "interval = 0.07", "whole number of output intervals"]),
    ("malformed number", [("dt = 1.0e-3", "dt = 1.0e-3.5")], ["case.nml:8:", "&integration", "dt = 1.0e-3.5", "dt = 1.0e-3.5 is not a number"]),
    ("text for a number", [("dt = 1.0e-3", "dt = 'fast'")], ["&integration", "dt = 'fast'", "dt = 'fast' is not a number"]),
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


def test_empty_file(ellroll, tmp_path):
    (tmp_path / "empty.nml").write_text("")
    result = run(ellroll, "check", "empty.nml", cwd=tmp_path)
    assert result.returncode == 2 and "empty.nml:1: the file is empty" in result.stderr
