"""Random edits of a valid namelist never crash the program: every run of the
Debug build (runtime checks and floating-point traps on) exits 0 or 2, and
every exit 2 explains itself. Inputs that pass `check` and are short are run."""
import random
import re

from conftest import PAPER_INPUT, SANITIZED, run

N_EDITS = 150 if SANITIZED else 400
CRASH_SIGNS = ["Fortran runtime error", "Backtrace", "Error termination", "Program received signal",
               "SIGFPE", "SIGSEGV", "Floating-point exception", "Segmentation"]
NUMBERS = ["0", "-0.0", "1e308", "-1e308", "1e-308", "4.9e-324", "NaN", "Inf", "-Inf", "-1", "1e18",
           "0.19999999", "0.2000001", "1d0", "2*0.5", "3*", "1e", ".", "+", "1,2", "'x'", ".true.", "7/"]


def mutate(text, rng):
    lines = text.splitlines(keepends=True)
    kind = rng.randrange(8)
    if kind == 0 and len(text) > 1:                      # delete a character
        i = rng.randrange(len(text))
        return text[:i] + text[i + 1:]
    if kind == 1:                                        # duplicate a character
        i = rng.randrange(len(text))
        return text[:i] + text[i] + text[i:]
    if kind == 2 and len(text) > 2:                      # swap two characters
        i = rng.randrange(len(text) - 1)
        return text[:i] + text[i + 1] + text[i] + text[i + 2:]
    if kind == 3:                                        # delete a line
        del lines[rng.randrange(len(lines))]
        return "".join(lines)
    if kind == 4:                                        # duplicate a line
        i = rng.randrange(len(lines))
        lines.insert(i, lines[i])
        return "".join(lines)
    if kind == 5 and len(lines) > 1:                     # swap two lines
        i, j = rng.sample(range(len(lines)), 2)
        lines[i], lines[j] = lines[j], lines[i]
        return "".join(lines)
    if kind == 6:                                        # replace a number
        numbers = list(re.finditer(r"-?\d+\.?\d*(e-?\d+)?", text))
        if numbers:
            m = rng.choice(numbers)
            return text[:m.start()] + rng.choice(NUMBERS) + text[m.end():]
    i = rng.randrange(len(text))                         # insert a stray character
    return text[:i] + rng.choice("&/=,'\"!()*$ \t\n\r\x00é") + text[i:]


def test_random_edits_never_crash(ellroll_debug, tmp_path):
    rng = random.Random(20261123)
    base = (PAPER_INPUT.read_text().replace("t_end = 30.0", "t_end = 0.5")
            + "&sweep name = 'omega_z', values = 5, 20 /\n&campaign invalid = 'skip' /\n")
    outcomes = {0: 0, 2: 0}
    ran = 0
    for trial in range(N_EDITS):
        text = base
        for _ in range(rng.randint(1, 3)):
            text = mutate(text, rng)
        path = tmp_path / f"fuzz{trial}.nml"
        path.write_text(text, encoding="utf-8", errors="surrogateescape")
        result = run(ellroll_debug, "check", path.name, cwd=tmp_path, timeout=30)
        detail = f"trial {trial}, input:\n{text}\nstdout:\n{result.stdout}\nstderr:\n{result.stderr}"
        assert not any(sign in result.stderr for sign in CRASH_SIGNS), detail
        assert result.returncode in (0, 2), detail
        outcomes[result.returncode] += 1
        if result.returncode == 2:
            assert result.stderr.startswith(f"ellroll: error: {path.name}"), detail
            assert len(result.stderr.strip()) > len(f"ellroll: error: {path.name}") + 10, detail
            continue
        steps = int(re.search(r"steps per case = (\d+)", result.stdout).group(1))
        if steps <= 20000:
            result = run(ellroll_debug, "run", path.name, "-o", f"fuzz{trial}.h5", cwd=tmp_path, timeout=60)
            assert result.returncode == 0 and not any(s in result.stderr for s in CRASH_SIGNS), detail
            ran += 1
    print(f"fuzz: {N_EDITS} edited inputs, {outcomes[0]} valid ({ran} integrated), {outcomes[2]} rejected")
    assert outcomes[2] > N_EDITS // 4 and outcomes[0] > 10
