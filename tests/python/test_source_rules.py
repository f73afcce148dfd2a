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
