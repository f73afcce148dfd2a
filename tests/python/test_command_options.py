"""Every command against every option of `ellroll --help`: an option that
the command's usage (`ellroll COMMAND --help`) does not list is refused
with one line naming both, exit 2, nothing written; one it lists is taken."""
import re

import pytest

from conftest import run
from test_campaign import write

VALUES = {"-o": "new.h5", "--output": "new.h5", "--threads": "1", "--shard": "0/2", "--format": "csv"}


def help_text(ellroll, *words):
    result = run(ellroll, *words, "--help")
    assert result.returncode == 0, result.stderr
    return result.stdout


def all_options(ellroll):
    """The options of `ellroll --help` and of every command's usage."""
    text = help_text(ellroll)
    found = set(re.findall(r"^\s+(-\w), (--[\w-]+)", text, re.M))
    names = {name for pair in found for name in pair}
    names |= set(re.findall(r"^\s+(--[\w-]+)", text, re.M))
    names |= set(re.findall(r"\[(--?[\w-]+)", text))
    return sorted(names - {"--help", "--version"})


def commands(ellroll):
    return sorted(set(re.findall(r"^\s+ellroll (\w+)", help_text(ellroll), re.M)))


def listed(ellroll, command):
    """The options the command's usage lists (a short name with its long one)."""
    usage = help_text(ellroll, command).split("\n\n")[0]
    names = set(re.findall(r"(--?[\w-]+)", usage.split(command, 1)[1]))
    for short, long in (("-o", "--output"), ("-q", "--quiet")):
        if short in names or long in names:
            names |= {short, long}
    return names


@pytest.fixture(scope="module")
def files(ellroll, tmp_path_factory):
    folder = tmp_path_factory.mktemp("options")
    write(folder, "&sweep name = 'omega_z', values = 10, 20 /\n", t_end=0.2, name="a.nml")
    for i in range(2):
        assert run(ellroll, "run", "a.nml", "-q", "--shard", f"{i}/2", "-o", f"s{i}.h5", cwd=folder).returncode == 0
    return folder


def arguments(command):
    return {"run": ["a.nml", "-o", "x.h5"], "check": ["a.nml"], "modes": ["a.nml"], "merge": ["m.h5", "s0.h5", "s1.h5"],
            "summary": ["s0.h5"]}.get(command, [])


def positional(command):
    return [a for a in arguments(command) if a not in ("-o", "x.h5")]


def snapshot(folder):
    return {p.name: (p.stat().st_size, p.stat().st_mtime_ns) for p in folder.iterdir()}


def test_the_help_lists_the_commands_and_options(ellroll):
    assert commands(ellroll) == ["check", "inputs", "merge", "methods", "modes", "run", "summary"]
    assert {"-o", "--output", "--overwrite", "--resume", "--threads", "--shard", "-q", "--quiet", "--timings",
            "--format", "--suite"} <= set(all_options(ellroll))


def test_every_command_refuses_every_option_it_does_not_take(ellroll, files):
    taken = 0
    for command in commands(ellroll) + ["version"]:
        ok = listed(ellroll, command) if command != "version" else set()
        for option in all_options(ellroll):
            argv = [command, *arguments(command), option] + ([VALUES[option]] if option in VALUES else [])
            before = snapshot(files)
            result = run(ellroll, *argv, cwd=files)
            if option in ok:
                taken += 1
                assert "does not take" not in result.stderr, (argv, result.stderr)
                for name in ("x.h5", "new.h5", "m.h5"):
                    (files / name).unlink(missing_ok=True)
                continue
            assert result.returncode == 2, (argv, result.stderr)
            assert result.stderr == f"ellroll: error: {command} does not take {option} " \
                f"(see 'ellroll {command} --help')\n", argv
            assert result.stdout == "" and snapshot(files) == before, argv
    assert taken == 9 + 4 + 1 + 2       # run's, check's, merge's, summary's (-o, -q and their long names)


def test_merge_refuses_o_and_leaves_the_shards(ellroll, files):
    before = snapshot(files)
    for extra in ([], ["--overwrite"]):
        result = run(ellroll, "merge", "-o", "new.h5", "s0.h5", "s1.h5", *extra, cwd=files)
        assert result.returncode == 2 and "merge does not take -o" in result.stderr
    assert snapshot(files) == before


@pytest.mark.parametrize("command", ["methods", "inputs", "version"])
def test_commands_without_files_refuse_an_argument(ellroll, command):
    result = run(ellroll, command, "extra")
    assert result.returncode == 2 and result.stdout == ""
    assert f"{command} takes no argument (extra)" in result.stderr


def test_an_option_with_a_value_given_twice_or_an_option_for_its_value_is_refused(ellroll, files):
    """The last of two values would win without a word (-o a.h5 -o b.h5
    never writes a.h5), and an option taken as a value (-o -q) names a
    file '-q': both refused in one line, nothing written."""
    for command in commands(ellroll):
        for option in sorted(listed(ellroll, command) & set(VALUES)):
            for again in {option, {"-o": "--output", "--output": "-o"}.get(option, option)}:
                argv = [command, *positional(command), option, VALUES[option], again, VALUES[again]]
                before = snapshot(files)
                result = run(ellroll, *argv, cwd=files)
                assert result.returncode == 2 and result.stderr == \
                    f"ellroll: error: {again} given twice; give it once (see 'ellroll --help')\n", (argv, result.stderr)
                assert snapshot(files) == before, argv
            for value in ("-q", "--overwrite", "--threads"):
                argv = [command, *positional(command), option, value]
                result = run(ellroll, *argv, cwd=files)
                assert result.returncode == 2 and f"{option} needs a value, not the option {value}" in result.stderr, \
                    (argv, result.stderr)


@pytest.mark.parametrize("blanks", [" ", "  ", "\t "])
def test_a_file_name_that_ends_in_a_blank_is_refused_and_no_other_file_is_touched(ellroll, files, blanks):
    """A Fortran text's trailing blanks do not count: 'x.h5 ' would read or
    replace x.h5. Every file argument of every command (and -o) that ends in
    a blank is refused in one line naming it, the files with the name
    without it (there) untouched."""
    for command in commands(ellroll):
        argv = arguments(command)
        slots = [i for i, a in enumerate(argv) if a != "-o"]
        for i in slots:
            edited = list(argv)
            edited[i] = argv[i] + blanks
            if command == "run":
                edited.append("--overwrite")
            before = snapshot(files)
            result = run(ellroll, command, *edited, cwd=files)
            assert result.returncode == 2, (command, edited, result.stderr)
            assert f"'{edited[i]}': a file name that ends in a blank" in result.stderr, (command, edited, result.stderr)
            assert snapshot(files) == before, (command, edited)
