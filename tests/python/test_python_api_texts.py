"""Texts in a dict input (ellroll.namelist, ellroll.run): a namelist text
ends on its line, so a value holding a line break is refused up front,
naming its group and variable; the error never names a line of the text
the package wrote (which nobody wrote)."""
import os
import pathlib
import random
import sys

import pytest

from conftest import ROOT

sys.path.insert(0, str(ROOT / "post"))
import ellroll  # noqa: E402  (the checkout's package, whatever .venv holds)

BASE = {
    "geometry": {"a": 1.0, "b": 0.4, "c": 0.2},
    "ball": {"radius": 0.2, "weight": 2620.0},
    "initial": {"x": 0.0, "y": 0.0, "omega": [-2.0, 2.0, 20.0]},
    "integration": {"method": "rk4", "dt": 1.0e-3, "t_end": 0.01},
    "output": {"file": "t.h5", "interval": 0.01, "fields": ["contact", "theta"]},
    "sweep": [{"name": "omega_z", "values": [5.0, 10.0]}],
}
# (group, variable, index in a list or None) of every text of BASE
TEXTS = [("integration", "method", None), ("output", "file", None), ("output", "fields", 0),
         ("output", "fields", 1), ("sweep", "name", None)]
BREAKS = ["\n", "\r", "\r\n", "\n\n", " /\n&geometry a = 2.0 /\n"]


def with_text(rng):
    """BASE with one seeded text holding a line break: (input, group, variable)."""
    group, name, index = rng.choice(TEXTS)
    inputs = {g: ([dict(m) for m in v] if isinstance(v, list) else dict(v)) for g, v in BASE.items()}
    members = inputs[group][0] if isinstance(inputs[group], list) else inputs[group]
    old = members[name][index] if index is not None else members[name]
    at = rng.randint(0, len(old))
    new = old[:at] + rng.choice(BREAKS) + old[at:]
    if index is not None:
        members[name] = list(members[name])
        members[name][index] = new
    else:
        members[name] = new
    return inputs, group, name


def test_a_line_break_in_a_text_is_refused_naming_group_and_variable():
    """30 seeded inputs, a line break (LF, CR, CRLF, a group's end) put in
    one text, a list's item included: InputError naming the group and the
    variable, no line number."""
    rng = random.Random(1204)
    for _ in range(30):
        inputs, group, name = with_text(rng)
        with pytest.raises(ellroll.InputError) as raised:
            ellroll.namelist(inputs)
        message = str(raised.value)
        assert message.startswith(f"&{group}: {name}: a text value cannot hold a line break"), message
        assert "\n" not in message and "<input>" not in message, message


def test_a_quote_in_a_text_is_written_doubled():
    """What a text may hold (a quote) still reads back as written."""
    text = ellroll.namelist({"output": {"file": "it's.h5"}})
    assert text == "&output\n  file = 'it''s.h5'\n/\n"


def test_run_refuses_it_before_the_library_reads_it(tmp_path):
    """ellroll.run gives the same refusal (nothing run, nothing written)."""
    library = pathlib.Path(os.environ.get("ELLROLL_LIB", ROOT / "build" / "libellroll.so"))
    if not library.exists():
        pytest.skip(f"{library} not built")
    rng = random.Random(77)
    for _ in range(5):
        inputs, group, name = with_text(rng)
        with pytest.raises(ellroll.InputError, match=f"^&{group}: {name}: a text value cannot hold a line break"):
            ellroll.run(inputs, path=str(tmp_path / "input.nml"))
    assert list(tmp_path.iterdir()) == []


# characters a text's line splitting may take for a line's end, but a namelist does not
NOT_LINE_FEEDS = ["\r", "\x0b", "\x0c", "\x1c", "\x1d", "\x1e", "\x85", "\u2028", "\u2029"]


def test_an_input_text_with_other_line_ends_runs_and_is_kept_as_given():
    """20 seeded input texts: CRLF or LF line ends, comments holding CR, VT,
    FF, the separators \\x1c-\\x1e, NEL, U+2028/9, backslashes and a
    backslash before n: ellroll.run runs each, its input_namelist is the text
    given, character for character, and its results are the plain text's."""
    rng = random.Random(1208)
    plain = ellroll.namelist({**BASE, "output": {"interval": 0.01, "fields": ["contact", "nutation"]}})
    reference = ellroll.run(plain, threads=1)
    theta = reference["summary"]["theta_max"].values
    for _ in range(20):
        lines = plain.splitlines()
        for _ in range(rng.randint(1, 3)):
            comment = "! " + "".join(rng.choice(NOT_LINE_FEEDS + ["\\", "\\n", "\\\\", "a", " "])
                                     for _ in range(rng.randint(1, 8)))
            lines.insert(rng.randint(0, len(lines)), comment)
        text = rng.choice(["\n", "\r\n"]).join(lines) + rng.choice(["\n", "\r\n"])
        tree = ellroll.run(text, threads=1)
        assert tree.attrs["input_namelist"] == text, (text, tree.attrs["input_namelist"])
        assert (tree["summary"]["theta_max"].values == theta).all(), text


@pytest.mark.parametrize("end", ["", " ", "\t", "\r", "  ! a comment"])
def test_an_input_text_without_a_final_line_break_runs_as_with_one(end):
    """A text built in code or stripped ends without a line break (a file
    must end with one): ellroll.run runs it as the text with one, its
    results the same bitwise."""
    plain = ellroll.namelist({**BASE, "output": {"interval": 0.01, "fields": ["contact", "nutation"]}})
    assert plain.endswith("\n")
    reference = ellroll.run(plain, threads=1)
    tree = ellroll.run(plain.rstrip("\n") + end, threads=1)
    assert (tree["summary"]["theta_max"].values == reference["summary"]["theta_max"].values).all()
    assert (tree["trajectory"]["contact"].values == reference["trajectory"]["contact"].values).all()
