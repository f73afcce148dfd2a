"""Messages as a user meets them: a file that is not a namelist, a value of
the wrong type, a misspelt name (did you mean), a missing group, the
progress line and the last block of a run, a resume, dt capping an adaptive
method's steps, the README's Install notes and the bash completion's paths.

The misspellings are generated, seeded: every input variable, group, option
and command at one and two edits (Damerau: insert, delete, substitute, swap
neighbours), each asserted where the name is the only nearest known one.
ELLROLL_FUZZ_BUDGET=N tries N misspellings of each name (default 2)."""
import math
import os
import pathlib
import pty
import random
import re
import select
import signal
import subprocess
import time

import h5py
import pytest

from conftest import run

ROOT = pathlib.Path(__file__).resolve().parents[2]
PER_NAME = max(2, int(os.environ.get("ELLROLL_FUZZ_BUDGET", "0") or 0))

BASE = {
    "geometry": "a = 1.0, b = 0.4, c = 0.2",
    "ball": "radius = 0.2, weight = 2620.0",
    "environment": "g = 9.81",
    "initial": "x = 0.0, y = 0.0, omega = -2.0, 2.0, 20.0",
    "integration": "method = 'rk4', dt = 1.0e-3, t_end = 1.0",
    "output": "file = 'out.h5', interval = 0.01",
}


def namelist(groups):
    return "".join(f"&{name} {body} /\n" for name, body in groups.items())


def write(folder, groups, name="case.nml"):
    (folder / name).write_text(namelist(groups))
    return name


def osa_distance(a, b):
    """Damerau-Levenshtein distance, optimal string alignment (independent
    of the Fortran one)."""
    d = [[0] * (len(b) + 1) for _ in range(len(a) + 1)]
    for i in range(len(a) + 1):
        d[i][0] = i
    for j in range(len(b) + 1):
        d[0][j] = j
    for i in range(1, len(a) + 1):
        for j in range(1, len(b) + 1):
            d[i][j] = min(d[i - 1][j] + 1, d[i][j - 1] + 1, d[i - 1][j - 1] + (a[i - 1] != b[j - 1]))
            if i > 1 and j > 1 and a[i - 1] == b[j - 2] and a[i - 2] == b[j - 1]:
                d[i][j] = min(d[i][j], d[i - 2][j - 2] + 1)
    return d[len(a)][len(b)]


def one_edit(word, rng, alphabet):
    k = rng.randrange(4)
    i = rng.randrange(len(word) + (k == 0))
    if k == 0:
        return word[:i] + rng.choice(alphabet) + word[i:]
    if k == 1 and len(word) > 1:
        return word[:i] + word[i + 1:]
    if k == 2:
        return word[:i] + rng.choice(alphabet) + word[i + 1:]
    if i + 1 < len(word):
        return word[:i] + word[i + 1] + word[i] + word[i + 2:]
    return word + rng.choice(alphabet)


def misspellings(name, known, rng, alphabet, keep=lambda m: True):
    """Up to PER_NAME misspellings of name at 1-2 edits of which name is the
    only nearest of known (and nearer than the misspelling's length)."""
    found = []
    for _ in range(200 * PER_NAME):
        m = one_edit(name, rng, alphabet)
        if rng.random() < 0.5:
            m = one_edit(m, rng, alphabet)
        if m in known or m in found or not keep(m):
            continue
        distances = {k: osa_distance(m, k) for k in known}
        d = distances[name]
        if 0 < d <= 2 and d < len(m) and sorted(distances.values()).count(d) == 1 and min(distances.values()) == d:
            found.append(m)
        if len(found) == PER_NAME:
            break
    return found


def known_variables(ellroll, tmp_path):
    """Each group's variables, as the unknown-variable message lists them."""
    groups = {}
    for group in ["geometry", "ball", "environment", "initial", "integration", "output", "excitation",
                  "campaign", "sweep", "sample", "record", "limit_state"]:
        nml = dict(BASE)
        nml[group] = (nml.get(group, "") + ", zzzzzzzz = 1").lstrip(", ")
        result = run(ellroll, "check", write(tmp_path, nml), cwd=tmp_path)
        m = re.search(r"known in &" + group + r": ([a-z_0-9, ]+)\)", result.stderr)
        assert m, result.stderr
        groups[group] = m.group(1).split(", ")
    return groups


TEXT_VARIABLES = {"method", "error_estimate", "file", "fields", "kind", "record_file", "combine", "invalid",
                  "name", "spacing", "slip", "figure"}
INTEGER_VARIABLES = {"compression", "count", "samples", "seed"}
VECTORS = {"omega": 3, "excitation_amplitude": 3, "velocity": 3}


def with_value(group, variable, value):
    nml = dict(BASE)
    kept = [a for a in nml.get(group, "").split(", ") if a and not a.startswith(variable + " ")]
    if group == "initial" and variable == "omega":
        kept = ["x = 0.0"]
    nml[group] = ", ".join(kept + [f"{variable} = {value}"])
    return nml


def test_an_hdf5_file_a_binary_file_and_a_folder_as_input(ellroll, paper_file, tmp_path):
    """run/check of an HDF5 file points to `ellroll summary`; a binary file
    and a folder are named for what they are; summary of a missing file or a
    folder says so; all exit 2."""
    h5 = tmp_path / "a.h5"
    h5.write_bytes(pathlib.Path(paper_file).read_bytes())
    for command in ["run", "check"]:
        result = run(ellroll, command, "a.h5", cwd=tmp_path)
        assert result.returncode == 2
        assert ("a.h5 is not a namelist file (it looks like an HDF5 file; did you mean `ellroll summary a.h5`?)"
                in result.stderr), result.stderr
    (tmp_path / "b.dat").write_bytes(bytes(random.Random(43).randrange(256) for _ in range(3000)) + b"\0\n")
    result = run(ellroll, "run", "b.dat", cwd=tmp_path)
    assert result.returncode == 2 and "b.dat is not a namelist file (it holds binary data" in result.stderr
    (tmp_path / "folder").mkdir()
    result = run(ellroll, "run", "folder", cwd=tmp_path)
    assert result.returncode == 2 and "folder: a folder, not an input file" in result.stderr
    result = run(ellroll, "summary", "nosuch.h5", cwd=tmp_path)
    assert result.returncode == 2 and "nosuch.h5: no such file" in result.stderr
    result = run(ellroll, "summary", "folder", cwd=tmp_path)
    assert result.returncode == 2 and "folder: a folder, not an output file" in result.stderr
    if os.geteuid() != 0:                       # root reads any file
        locked = tmp_path / "locked.h5"
        locked.write_bytes(h5.read_bytes())
        locked.chmod(0)
        result = run(ellroll, "summary", "locked.h5", cwd=tmp_path)
        assert result.returncode == 2 and "locked.h5: cannot read it" in result.stderr


def test_every_number_input_given_a_word(ellroll, tmp_path):
    """Every real and integer variable of every group given `fast`: 'FILE:
    &group: NAME = fast is not a number', exit 2, never gfortran's words;
    an integer given 1.5 is not a whole number; a vector with a word among
    its values names the word; too many values are counted."""
    tried = 0
    for group, variables in known_variables(ellroll, tmp_path).items():
        for variable in variables:
            if variable in TEXT_VARIABLES:
                continue
            result = run(ellroll, "check", write(tmp_path, with_value(group, variable, "fast")), cwd=tmp_path)
            assert result.returncode == 2, (group, variable, result.stderr)
            assert f"case.nml:" in result.stderr and f"&{group}: {variable} = fast is not a number" in result.stderr, \
                (group, variable, result.stderr)
            assert "gfortran" not in result.stderr and "Cannot match" not in result.stderr
            tried += 1
            if variable in INTEGER_VARIABLES:
                result = run(ellroll, "check", write(tmp_path, with_value(group, variable, "1.5")), cwd=tmp_path)
                assert result.returncode == 2
                assert f"&{group}: {variable} = 1.5 is not a whole number" in result.stderr, result.stderr
            if variable in VECTORS:
                result = run(ellroll, "check", write(tmp_path, with_value(group, variable, "1.0, fast, 3.0")),
                             cwd=tmp_path)
                assert f"&{group}: {variable} = 1.0, fast, 3.0: fast is not a number" in result.stderr, result.stderr
                result = run(ellroll, "check", write(tmp_path, with_value(group, variable, "1, 2, 3, 4")),
                             cwd=tmp_path)
                assert f"{variable} = 1, 2, 3, 4: 4 values given; {variable} holds 3" in result.stderr, result.stderr
    assert tried >= 30
    result = run(ellroll, "check", write(tmp_path, with_value("integration", "dt", "1.0e-3, 2.0e-3")), cwd=tmp_path)
    assert "dt = 1.0e-3, 2.0e-3: 2 values given; dt holds one" in result.stderr


def test_did_you_mean_for_misspelt_variables_and_groups(ellroll, tmp_path):
    """Seeded misspellings of every variable of every group and of every
    group name, at one or two edits: the message suggests the name."""
    rng = random.Random(4301)
    alphabet = "abcdefghijklmnopqrstuvwxyz_"
    groups = known_variables(ellroll, tmp_path)
    checked = 0
    for group, variables in groups.items():
        for variable in variables:
            keep = lambda m: m[0].isalpha()
            for wrong in misspellings(variable, variables, rng, alphabet, keep):
                nml = dict(BASE)
                nml[group] = (nml.get(group, "") + f", {wrong} = 1").lstrip(", ")
                result = run(ellroll, "check", write(tmp_path, nml), cwd=tmp_path)
                assert result.returncode == 2
                assert f"unknown variable {wrong} = 1; did you mean {variable}?" in result.stderr, \
                    (group, wrong, result.stderr)
                checked += 1
    for group in groups:
        for wrong in misspellings(group, list(groups), rng, alphabet, lambda m: m[0].isalpha()):
            nml = dict(BASE)
            nml[wrong] = "a = 1"
            result = run(ellroll, "check", write(tmp_path, nml), cwd=tmp_path)
            assert f"unknown group &{wrong}; did you mean &{group}?" in result.stderr, (wrong, result.stderr)
            checked += 1
    assert checked >= 100
    # the issue's own examples, a sweep's name among them
    for group, wrong, right in [("initial", "omeg", "omega"), ("ball", "radus", "radius")]:
        nml = dict(BASE)
        nml[group] += f", {wrong} = 1"
        assert f"did you mean {right}?" in run(ellroll, "check", write(tmp_path, nml), cwd=tmp_path).stderr
    nml = dict(BASE, sweep="name = 'omegaz', values = 1, 2")
    assert "did you mean omega_z?" in run(ellroll, "check", write(tmp_path, nml), cwd=tmp_path).stderr
    nml = dict(BASE, ball="radius = 0.2, weight = 2620.0, inertia = 0.4")
    assert "did you mean inertia_factor?" in run(ellroll, "check", write(tmp_path, nml), cwd=tmp_path).stderr


OPTIONS = ["--output", "--threads", "--shard", "--format", "--overwrite", "--resume", "--quiet", "--timings",
           "--help", "--version"]
COMMANDS = ["run", "check", "merge", "summary", "methods", "inputs", "modes", "help", "version"]
ACCEPTED = set(OPTIONS + COMMANDS) | {"-o", "-q", "-h", "-V"}


def test_did_you_mean_for_misspelt_options_and_commands(ellroll, tmp_path):
    rng = random.Random(4302)
    checked = 0
    for option in OPTIONS:
        for wrong in misspellings(option, OPTIONS, rng, "abcdefghijklmnopqrstuvwxyz-",
                                  lambda m: m.startswith("-") and m not in ACCEPTED):
            result = run(ellroll, "run", "a.nml", wrong, cwd=tmp_path)
            assert result.returncode == 2
            assert f"unknown option {wrong}; did you mean {option}?" in result.stderr, result.stderr
            checked += 1
    for command in COMMANDS:
        for wrong in misspellings(command, COMMANDS, rng, "abcdefghijklmnopqrstuvwxyz",
                                  lambda m: m[:1].isalpha() and m not in ACCEPTED):
            result = run(ellroll, wrong, "a.nml", cwd=tmp_path)
            assert result.returncode == 2
            assert f"unknown command '{wrong}'; did you mean ellroll {command}?" in result.stderr, result.stderr
            checked += 1
    assert checked >= 25
    assert "did you mean --threads?" in run(ellroll, "run", "a.nml", "--thread", "2", cwd=tmp_path).stderr
    assert "did you mean" not in run(ellroll, "run", "a.nml", "--zzzzzz", cwd=tmp_path).stderr


@pytest.mark.parametrize("group", ["geometry", "ball", "initial", "integration", "output"])
def test_a_missing_group_lists_its_needs_and_its_example_line_works(ellroll, tmp_path, group):
    nml = dict(BASE)
    del nml[group]
    result = run(ellroll, "check", write(tmp_path, nml), cwd=tmp_path)
    assert result.returncode == 2
    m = re.search(rf"group &{group} is missing \(it is required; it needs ([^;]+); add a line such as: (&.*/)\)",
                  result.stderr)
    assert m, result.stderr
    needs, example = m.groups()
    for variable in re.findall(r"[a-z_]+", BASE[group]):
        if variable in ["method", "x", "y", "g"]:            # (defaults)
            continue
        if variable in needs:
            assert variable in example
    (tmp_path / "fixed.nml").write_text(namelist(nml) + example + "\n")
    result = run(ellroll, "check", "fixed.nml", cwd=tmp_path)
    assert result.returncode == 0, result.stderr


CAMPAIGN = dict(BASE, integration="method = 'rk4', dt = 1.0e-3, t_end = 2.0",
                sweep="name = 'omega_z', start = 5, stop = 40, count = 40")


def test_the_last_block_of_a_run(ellroll, tmp_path):
    """In a log: the last progress line says done, without ETA; then the
    wall time, cases run, cases per second and the file's size; a recap of
    the warnings (invalid cases skipped)."""
    nml = dict(CAMPAIGN, campaign="invalid = 'skip'", sweep="name = 'radius', values = 0.1, 0.2, 5.0, 0.15")
    result = run(ellroll, "run", write(tmp_path, nml), "--threads", "1", cwd=tmp_path)
    assert result.returncode == 0, result.stderr
    lines = result.stderr.splitlines()
    progress = [line for line in lines if re.match(r"ellroll: \d+/\d+ cases", line)]
    assert progress[-1].startswith("ellroll: 4/4 cases (100%)") and "ETA" not in progress[-1]
    assert re.search(r", done in \d+:\d\d:\d\d$", progress[-1])
    done = [line for line in lines if line.startswith("ellroll: done in")]
    assert len(done) == 1
    m = re.match(r"ellroll: done in ([\d.]+) s: (\d+) cases run, ([\d.]+) cases/s; out.h5: ([\d.]+) (B|KiB|MiB)$",
                 done[0])
    assert m, done[0]
    seconds, cases, rate, size, unit = m.groups()
    assert int(cases) == 3                                 # the invalid case is not run
    size_bytes = float(size) * {"B": 1, "KiB": 1024, "MiB": 2**20}[unit]
    assert size_bytes == pytest.approx((tmp_path / "out.h5").stat().st_size, rel=0.06)
    recap = result.stderr[result.stderr.index("ellroll: warnings: "):]
    assert recap.startswith("ellroll: warnings: 1\n    1 invalid cases skipped")
    # quiet: nothing on stderr but warnings
    result = run(ellroll, "run", "case.nml", "-q", "--overwrite", cwd=tmp_path)
    assert "done in" not in result.stderr


def test_the_terminal_line_ends_without_a_stale_eta(ellroll, tmp_path):
    """On a terminal the line is redrawn with a carriage return: the last
    drawing must cover an ETA drawn before it."""
    # about 3 s: 12 cases of 3 million steps, a line a second
    nml = dict(CAMPAIGN, integration="method = 'rk4', dt = 1.0e-3, t_end = 3000.0",
               output="file = 'out.h5', interval = 1.0", sweep="name = 'omega_z', start = 5, stop = 40, count = 12")
    name = write(tmp_path, nml)
    leader, follower = pty.openpty()
    proc = subprocess.Popen([str(ellroll), "run", name, "--threads", "1"], cwd=tmp_path,
                            stdout=subprocess.DEVNULL, stderr=follower)
    os.close(follower)
    data = b""
    while True:
        ready, _, _ = select.select([leader], [], [], 60)
        if not ready:
            break
        try:
            chunk = os.read(leader, 4096)
        except OSError:
            break
        if not chunk:
            break
        data += chunk
    assert proc.wait(timeout=60) == 0
    os.close(leader)
    text = data.decode()
    first_line = text.split("\n")[0] if "\n" in text else text
    assert "ETA" in first_line, "no line with an ETA was drawn: the case is too fast to show the point"
    screen = ""
    for drawing in first_line.split("\r"):                 # what the terminal shows at the end
        screen = drawing + screen[len(drawing):]
    assert "ETA" not in screen and "12/12 cases (100%)" in screen and "done in" in screen, repr(screen)


def test_a_resume_says_what_it_kept_and_what_it_runs(ellroll, tmp_path):
    nml = dict(CAMPAIGN, integration="method = 'rk4', dt = 1.0e-4, t_end = 4.0")
    name = write(tmp_path, nml)
    journal = tmp_path / "out.h5.journal"
    proc = subprocess.Popen([str(ellroll), "run", name, "-q", "--threads", "1"], cwd=tmp_path,
                            stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    while proc.poll() is None and not (journal.exists() and journal.stat().st_size > 4096):
        time.sleep(0.002)
    assert proc.poll() is None, "the run finished before the signal"
    proc.send_signal(signal.SIGTERM)
    assert proc.wait(timeout=30) == 128 + signal.SIGTERM
    result = run(ellroll, "run", name, "--resume", "--threads", "2", cwd=tmp_path)
    assert result.returncode == 0, result.stderr
    m = re.search(r"ellroll: resuming out.h5: kept (\d+) of 40 cases from the journal; running (\d+)", result.stderr)
    assert m, result.stderr
    kept, running = map(int, m.groups())
    assert kept >= 1 and kept + running == 40
    assert f": {running} cases run," in result.stderr


PAPER_DOP853 = dict(BASE, integration="method = 'dop853', dt = 1.0e-3, t_end = 30.0")


def test_dt_capping_an_adaptive_method_is_said(ellroll, tmp_path):
    """The paper's case switched to dop853 keeping dt = 1e-3: 30000 steps at
    any rtol, and check and run say so; with dt left out rtol decides (465
    steps) and nothing is said; a dt that caps most steps without the probe
    (t_end / dt = 600) is said after the run."""
    name = write(tmp_path, PAPER_DOP853)
    warning = "dt = 0.001 caps dop853's steps: it will take >= 30000 steps whatever rtol"
    for command in ["check", "run"]:
        result = run(ellroll, command, name, cwd=tmp_path)
        assert result.returncode == 0 and warning in result.stderr, result.stderr
        assert "raise dt (the largest step) to let rtol decide" in result.stderr
    assert "steps, all cases: 30000;" in result.stdout
    assert re.search(r"ellroll: warnings: 1\n    dt = 0.001 caps dop853's steps", result.stderr)
    free = dict(PAPER_DOP853, integration="method = 'dop853', rtol = 1.0e-9, t_end = 30.0")
    result = run(ellroll, "run", write(tmp_path, free, "free.nml"), "-o", "free.h5", cwd=tmp_path)
    steps = int(re.search(r"steps, all cases: (\d+);", result.stdout).group(1))
    assert steps < 3000 and "caps" not in result.stderr
    coarse = dict(PAPER_DOP853, integration="method = 'dop853', dt = 0.05, t_end = 30.0")
    name = write(tmp_path, coarse, "coarse.nml")
    assert "caps" not in run(ellroll, "check", name, cwd=tmp_path).stderr
    result = run(ellroll, "run", name, "-o", "coarse.h5", cwd=tmp_path)
    steps_capped = int(re.search(r"steps, all cases: (\d+);", result.stdout).group(1))
    assert steps_capped >= 0.9 * 600 and steps_capped > steps
    assert "dt = 0.05 caps dop853's steps (1 of 1 completed cases took t_end / dt steps" in result.stderr


def test_readme_install_names_the_portable_build_and_the_extra():
    readme = (ROOT / "README.md").read_text()
    install = readme[readme.index("## Install"):readme.index("## Licence")]
    assert "-DELLROLL_NATIVE=OFF" in install and "-march=native" in install
    extras = re.search(r"\[project.optional-dependencies\]\n(.*?)\n\n", (ROOT / "post/pyproject.toml").read_text(),
                       re.S).group(1)
    for extra in re.findall(r"^(\w+) =", extras, re.M):
        assert f'pip install "./post[{extra}]"' in install, extra


def completion(tmp_path, *words):
    script = ROOT / "src/app/ellroll-completion.bash"
    line = " ".join(f"'{w}'" for w in words)
    shell = (f"source '{script}'; COMP_WORDS=(ellroll {line}); COMP_CWORD={len(words)}; _ellroll; "
             'printf "%s\\n" "${COMPREPLY[@]}"')
    result = subprocess.run(["bash", "-c", shell], cwd=tmp_path, capture_output=True, text=True)
    assert result.returncode == 0, result.stderr
    return sorted(result.stdout.split())


def test_bash_completion_completes_paths(tmp_path):
    """Folders on the way to an input or output file, files by their kind."""
    (tmp_path / "input").mkdir()
    (tmp_path / "input" / "legeza1990.nml").write_text("")
    (tmp_path / "input" / "notes.txt").write_text("")
    (tmp_path / "results").mkdir()
    (tmp_path / "results" / "out.h5").write_text("")
    (tmp_path / "inline.nml").write_text("")
    assert completion(tmp_path, "run", "in") == ["inline.nml", "input"]
    assert completion(tmp_path, "check", "input/") == ["input/legeza1990.nml"]
    assert completion(tmp_path, "summary", "re") == ["results"]
    assert completion(tmp_path, "summary", "results/") == ["results/out.h5"]
    assert completion(tmp_path, "run", "inline.nml", "-o", "res") == ["results"]
    assert completion(tmp_path, "run", "--thr") == ["--threads"]


def tangent_vz(a, b, c, x, y, vx, vy):
    """The vz that makes (vx, vy, vz) tangent to the cup x^2/a^2 + y^2/b^2 +
    (z - c)^2/c^2 = 1 at its point over (x, y) (independent of the Fortran)."""
    import math
    s = math.sqrt(1 - (x / a) ** 2 - (y / b) ** 2)
    normal = (x / a**2, y / b**2, -s / c)          # the gradient there, (z - c) / c^2 = -s / c
    return -(vx * normal[0] + vy * normal[1]) / normal[2]


SLIDING_START = {
    "geometry": "a = 1.0, b = 0.4, c = 0.2",
    "ball": "radius = 0.05, weight = 2620.0, mu = 0.1, slip = 'slide'",
    "integration": "method = 'rk4', dt = 1.0e-3, t_end = 0.1",
    "output": "file = 'out.h5', interval = 0.01",
}


def test_a_velocity_not_tangent_is_refused_with_the_tangent_vz(ellroll, tmp_path):
    """Seeded starts off the centre: a vz off by 1e-6 |v| is refused, and the
    message gives the tolerance and the tangent vz to full precision (it
    passes); one off by 1e-11 |v| is taken."""
    import math
    rng = random.Random(14)
    for _ in range(6):
        while True:
            x, y = rng.uniform(-0.7, 0.7), rng.uniform(-0.28, 0.28)
            if (x / 1.0) ** 2 + (y / 0.4) ** 2 < 0.5:
                break
        vx, vy = rng.uniform(-1, 1), rng.uniform(-1, 1)
        vz = tangent_vz(1.0, 0.4, 0.2, x, y, vx, vy)
        speed = math.sqrt(vx * vx + vy * vy + vz * vz)

        def check(vz_given):
            groups = dict(SLIDING_START, initial=f"x = {x!r}, y = {y!r}, omega = 0.0, 0.0, 0.0, "
                                                 f"velocity = {vx!r}, {vy!r}, {vz_given!r}")
            return run(ellroll, "check", write(tmp_path, groups), cwd=tmp_path)

        result = check(vz + 1e-6 * speed)
        assert result.returncode == 2, result.stderr
        assert "&initial: velocity = " in result.stderr and "(|v . n| <= 1e-09 |v|)" in result.stderr, result.stderr
        given = float(re.search(r"tangent velocity has vz = (\S+) m/s", result.stderr).group(1))
        assert abs(given - vz) <= 1e-14 * max(speed, 1e-300), (given, vz)
        assert check(given).returncode == 0
        assert check(vz + 1e-11 * speed).returncode == 0


@pytest.mark.parametrize("component", ["x", "y", "z"])
def test_a_swept_velocity_component_breaking_tangency_names_the_velocity(ellroll, tmp_path, component):
    """The case names the swept component, the message the whole vector (not
    the component the check looked at first) and the tangent vz."""
    groups = dict(SLIDING_START, initial="x = 0.0, y = 0.0, omega = 0.0, 0.0, 0.0, velocity = 0.1, 0.2, 0.0",
                  sweep=f"name = 'velocity_{component}', values = 0.0, 0.3")
    result = run(ellroll, "check", write(tmp_path, groups), cwd=tmp_path)
    velocity = {"x": [0.3, 0.2, 0.0], "y": [0.1, 0.3, 0.0], "z": [0.1, 0.2, 0.3]}[component]
    if component != "z":                       # at the centre n = z: vx, vy do not break it
        assert result.returncode == 0, result.stderr
        return
    assert result.returncode == 2, result.stderr
    assert f"case.nml: case 1 (velocity_z = 0.3): velocity = {', '.join(f'{v:g}' for v in velocity)}: " \
           "must be tangent" in result.stderr, result.stderr
    assert "velocity_x = " not in result.stderr and "tangent velocity has vz = 0 m/s" in result.stderr


def test_a_fixed_step_that_does_not_resolve_the_excitation_is_said(ellroll, tmp_path):
    """rk4 at dt = 1e-3 under a vertical 12 m/s^2 at 1000 Hz samples the sine
    at its zeros only: check and run warn, naming the file, &integration dt and
    &excitation frequency. The warning is due: dop853 finds the lift-off where
    the cup's 12 sin(2 pi f t) m/s^2 first reaches -g. Seeded (dt, frequency) pairs warn exactly
    where dt * frequency > 1/20 (none within 1 % of it); a record warns where
    dt exceeds its sample spacing."""
    aliased = dict(BASE, integration="method = 'rk4', dt = 1e-3, t_end = 1.0",
                   initial="x = 0.0, y = 0.0, omega = 0.0, 0.0, 0.0",
                   excitation="kind = 'harmonic', amplitude = 0.0, 0.0, 12.0, frequency = 1000.0")
    name = write(tmp_path, aliased, "aliased.nml")
    for args in (["check"], ["run", "-q"]):
        result = run(ellroll, *args, name, cwd=tmp_path)
        assert result.returncode == 0, result.stderr
        assert "aliased.nml: 1 of 1 cases: &integration dt does not resolve the harmonic excitation" in result.stderr
        assert "&integration dt = 0.001 s, &excitation frequency = 1000 Hz, dt * frequency = 1 >= 1/2" in result.stderr
        assert "dt <= 5e-05 s would do" in result.stderr
    adaptive = dict(aliased, integration="method = 'dop853', rtol = 1e-10, t_end = 1.0")
    result = run(ellroll, "run", write(tmp_path, adaptive, "adaptive.nml"), "-q", "-o", "adaptive.h5", cwd=tmp_path)
    assert result.returncode == 0 and "resolve" not in result.stderr, result.stderr

    with h5py.File(tmp_path / "adaptive.h5") as f:
        assert f["summary/status"][0] == 5        # liftoff
        truth = (math.pi + math.asin(9.81 / 12.0)) / (2 * math.pi * 1000.0)      # g + 12 sin(2 pi f t) = 0
        assert abs(f["summary/t_final"][0] - truth) < 1e-9, (f["summary/t_final"][0], truth)
    rng = random.Random(11)
    for k in range(12):
        dt = rng.choice([1e-4, 2e-4, 5e-4, 1e-3])
        frequency = 10.0 ** rng.uniform(-1, 4)
        if abs(dt * frequency * 20 - 1) < 0.01:
            continue
        case = dict(aliased, integration=f"method = '{rng.choice(['rk4', 'gauss4'])}', dt = {dt!r}, t_end = 0.01",
                    excitation=f"kind = 'harmonic', amplitude = 0.0, 0.0, 1.0, frequency = {frequency!r}")
        result = run(ellroll, "check", write(tmp_path, case, f"f{k}.nml"), cwd=tmp_path)
        assert result.returncode == 0, result.stderr
        assert ("does not resolve" in result.stderr) == (dt * frequency > 1 / 20), (dt, frequency, result.stderr)
    (tmp_path / "ground.csv").write_text("".join(f"{0.002 * i!r}, {math.sin(i)!r}, 0.0\n" for i in range(200)))
    for dt, said in ((1e-3, False), (2e-3, False), (5e-3, True)):
        case = dict(aliased, integration=f"method = 'rk4', dt = {dt!r}, t_end = 0.2",
                    excitation="kind = 'record', record_file = 'ground.csv'")
        result = run(ellroll, "check", write(tmp_path, case, "record.nml"), cwd=tmp_path)
        assert result.returncode == 0, result.stderr
        assert ("longer than the spacing of their record's samples" in result.stderr) == said, (dt, result.stderr)
