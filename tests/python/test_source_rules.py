"""Rules of the Fortran sources that the compiler does not enforce.

No function returns a deferred-length character (`character(len=:),
allocatable` result): gfortran 12 keeps the length of such a result in a
static variable of the caller, so two threads calling it at once corrupt each
other's text (a format string read as '(f40.7', a message cut short). A
result's length is given by a pure function of the arguments instead, or the
text is an intent(out) argument of a subroutine."""
import re

from conftest import ROOT

FUNCTION = re.compile(r"^\s*(?:(?:pure|elemental|impure|recursive|module)\s+)*"
                      r"(?:[\w()=,*]+\s+)?function\s+(\w+)\s*\(.*?\)\s*(?:result\s*\(\s*(\w+)\s*\))?",
                      re.I)


def deferred_length_functions(text):
    """(name, line number) of each function whose result is deferred-length."""
    found = []
    lines = text.splitlines()
    for number, line in enumerate(lines):
        match = FUNCTION.match(line)
        if not match:
            continue
        result = (match.group(2) or match.group(1)).lower()
        for declaration in lines[number + 1:]:
            if re.match(r"\s*end\s+function", declaration, re.I):
                break
            if re.search(r"character\s*\(\s*len\s*=\s*:\s*\).*allocatable.*::(.*)", declaration, re.I):
                names = re.search(r"::(.*)", declaration).group(1)
                if result in [n.strip().split("(")[0].lower() for n in names.split(",")]:
                    found.append((match.group(1), number + 1))
                    break
    return found


def test_the_rule_finds_what_it_looks_for():
    sample = ("  pure function bad(i) result(s)\n    integer, intent(in) :: i\n"
              "    character(len=:), allocatable :: s\n  end function bad\n"
              "  function fine(i) result(s)\n    character(len=4) :: s\n"
              "    character(len=:), allocatable :: scratch\n  end function fine\n")
    assert deferred_length_functions(sample) == [("bad", 1)]


def test_no_function_returns_a_deferred_length_character():
    found = []
    for path in sorted((ROOT / "src").rglob("*.f90")) + sorted((ROOT / "bench").glob("*.f90")):
        found += [f"{path.relative_to(ROOT)}:{line}: {name}"
                  for name, line in deferred_length_functions(path.read_text())]
    assert found == []


# Sizes that keep a unit readable in one sitting (docs/design.md): a source
# file of at most 700 lines, a routine (its internal procedures counted) of at
# most 120.
MAX_FILE_LINES = 700
MAX_ROUTINE_LINES = 120

ROUTINE_START = re.compile(r"^\s*(?:(?:pure|elemental|impure|recursive|module|non_overridable)\s+)*"
                           r"(?:(?:integer|real|logical|character|type|class|complex)[\w()=,*:\s]*?\s+)?"
                           r"(subroutine|function)\s+(\w+)", re.I)
ROUTINE_END = re.compile(r"^\s*end\s+(subroutine|function)\b", re.I)


def routine_lengths(text):
    """(name, first line, lines) of each subroutine and function, internal
    procedures counted in their host's lines."""
    found, open_routines = [], []
    for number, line in enumerate(text.splitlines(), 1):
        code = line.split("!")[0]
        if ROUTINE_END.match(code):
            if open_routines:
                name, first = open_routines.pop()
                found.append((name, first, number - first + 1))
        elif ROUTINE_START.match(code) and not re.match(r"\s*(module\s+)?procedure\b", code, re.I):
            open_routines.append((ROUTINE_START.match(code).group(2), number))
    return found


def test_the_routine_measure_counts_internal_procedures_in_the_host():
    sample = ("  pure real(wp) function f(x) result(y)\n    y = x\n  end function f\n"
              "  subroutine host(a)\n    a = 1\n  contains\n    subroutine inner()\n    end subroutine inner\n"
              "  end subroutine host\n  module procedure g\n")
    assert routine_lengths(sample) == [("f", 1, 3), ("inner", 7, 2), ("host", 4, 6)]


def test_no_source_file_or_routine_is_longer_than_the_rule():
    too_long = []
    for path in sorted((ROOT / "src").rglob("*.f90")) + sorted((ROOT / "src").rglob("*.c")):
        text = path.read_text()
        lines = len(text.splitlines())
        if lines > MAX_FILE_LINES:
            too_long.append(f"{path.relative_to(ROOT)}: {lines} lines")
        if path.suffix == ".f90":
            too_long += [f"{path.relative_to(ROOT)}:{first}: {name} {length} lines"
                         for name, first, length in routine_lengths(text) if length > MAX_ROUTINE_LINES]
    assert too_long == []
