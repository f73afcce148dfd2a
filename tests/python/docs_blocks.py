"""Docs as tests: the shell blocks and Python snippets of README.md, docs/*.md
and post/README.md, run the way a reader meets them (test_docs.py drives it).

A page's blocks run in order in one fresh folder that looks like the
repository root: a copy of the repository's files, with build/ and .venv/
linked to the repository's own, so `build/ellroll`, `.venv/bin/ellroll-plot`,
`.venv/bin/python bench/x.py` and `input/...` mean what they mean at the root,
and whatever a block writes stays in that folder (a later block of the page
may read it). Shell blocks run in bash with `set -eo pipefail`; Python
snippets with the repository's .venv/bin/python. PATH is the caller's
without the repository's build/ and .venv/bin (a fresh shell at the root has
neither), and MPLBACKEND=Agg.

HTML comments right above a block (blank lines between allowed) tell the
test more; they do not show when the page is rendered:

    <!-- docs-test: skip (REASON) -->         not run here (a cluster, an install); counted and reported
    <!-- docs-test: env NAME=VALUE ... -->    set for the block (ELLROLL_BENCH_QUICK=1: a bench's tiny size)
    <!-- docs-test: creates PATH ... -->      the block makes these files (a claim of the text)
    <!-- docs-test: output shape -->          compare the output block below by its shape (see below)

An untagged block right after a runnable one (only blank lines between) is
the output it prints on stdout, and is compared: line by line, where `...`
alone on a line stands for any lines and `...` inside a line for any text.
With `output shape` (benchmark tables, whose figures are timings and whose
quick run prints fewer rows) every line without a number must be printed as
shown, and every printed line with numbers must begin, up to its first number
or colon, like a line shown.

ELLROLL_TEST_FULL=1 ignores the markers' ELLROLL_BENCH_QUICK: the benches of
docs/performance.md then run at the sizes written (many minutes).
"""
import dataclasses
import os
import pathlib
import re
import shutil
import signal
import subprocess
import sys
import threading
import time

from conftest import FULL

ROOT = pathlib.Path(__file__).resolve().parents[2]
QUICK = "ELLROLL_BENCH_QUICK"
BLOCK_TIMEOUT = 3600 if FULL else 300
MARKER = re.compile(r"^<!--\s*docs-test:\s*(.*?)\s*-->\s*$")
FENCE = re.compile(r"^```\s*(\S*)\s*$")
SHELL, PYTHON = {"sh", "bash", "shell"}, {"python", "py"}
NUMBER = re.compile(r"(?<![A-Za-z_])[-+]?(?:\d[\d,]*\.?\d*|\.\d+)(?:[eE][-+]?\d+)?|\b(?:nan|inf)\b")
# what a line that runs something begins with (such a line belongs in a fenced sh block)
COMMAND = re.compile(r"^\s*(?:\$ )?(?:build[\w-]*/|\.venv/|ellroll(?:-plot)?\b|python3?\b|bash\b|cmake\b|pip\b|"
                     r"source\b|examples/|import\b|from \S+ import\b)")


def pages():
    return ["README.md", *(f"docs/{p.name}" for p in sorted((ROOT / "docs").glob("*.md"))), "post/README.md"]


@dataclasses.dataclass
class Block:
    page: str
    line: int
    kind: str                       # "sh", "python" or "text" (namelists, diagrams: not run)
    code: str
    skip: str = ""
    env: dict = dataclasses.field(default_factory=dict)
    creates: list = dataclasses.field(default_factory=list)
    shape: bool = False
    output: str = None              # the output block right below, if any
    output_line: int = 0

    @property
    def name(self):
        return f"{self.page}:{self.line}"


@dataclasses.dataclass
class Result:
    block: Block
    status: str = "not run"         # passed, failed, skipped, not run
    message: str = ""
    seconds: float = 0.0            # wall time
    cpu: float = 0.0                # CPU time of the block's processes (the machine's other load aside)
    checks: int = 0                 # output blocks compared and files claimed


def apply_marker(block, text, where):
    verb, _, rest = text.partition(" ")
    if verb == "skip":
        reason = re.fullmatch(r"\((.+)\)", rest.strip())
        if not reason:
            raise ValueError(f"{where}: skip needs a reason in parentheses: {text}")
        block.skip = reason.group(1)
    elif verb == "env":
        rest = re.sub(r"\s*\(.*\)\s*$", "", rest)      # a comment in parentheses at the end
        for item in rest.split():
            name, equals, value = item.partition("=")
            if not equals or not re.fullmatch(r"[A-Za-z_]\w*", name):
                raise ValueError(f"{where}: env takes NAME=VALUE: {item}")
            block.env[name] = value
    elif verb == "creates":
        block.creates += rest.split()
    elif text == "output shape":
        block.shape = True
    else:
        raise ValueError(f"{where}: unknown docs-test marker: {text}")


def parse(page):
    """The blocks of a page, in order, with their markers and output blocks."""
    lines = (ROOT / page).read_text().splitlines()
    blocks, markers, previous, i = [], [], None, 0
    while i < len(lines):
        line = lines[i]
        marker = MARKER.match(line)
        fence = FENCE.match(line)
        if marker:
            markers.append((i + 1, marker.group(1)))
        elif fence:
            end = next((j for j in range(i + 1, len(lines)) if lines[j].startswith("```")), None)
            if end is None:
                raise ValueError(f"{page}:{i + 1}: the block is not closed")
            code = "\n".join(lines[i + 1:end]) + "\n"
            tag = fence.group(1).lower()
            kind = "sh" if tag in SHELL else "python" if tag in PYTHON else "text"
            if kind == "text" and previous is not None and not markers:
                previous.output, previous.output_line = code, i + 1
                previous = None
            else:
                block = Block(page, i + 1, kind, code)
                for number, text in markers:
                    if kind == "text":
                        raise ValueError(f"{page}:{number}: a marker above a block that does not run")
                    apply_marker(block, text, f"{page}:{number}")
                blocks.append(block)
                previous = block if kind != "text" else None
            markers = []
            i = end
        elif line.strip():
            if markers:
                raise ValueError(f"{page}:{markers[0][0]}: a docs-test marker must be right above a block")
            previous = None
        i += 1
    if markers:
        raise ValueError(f"{page}:{markers[0][0]}: a docs-test marker must be right above a block")
    return blocks


def lint(page):
    """Commands outside fenced sh/python blocks (which would not run): indented
    code blocks, and untagged fenced blocks that are not a command's output."""
    problems = []
    lines = (ROOT / page).read_text().splitlines()
    in_fence = False
    for number, line in enumerate(lines, 1):
        if FENCE.match(line) or line.startswith("```"):
            in_fence = not in_fence
            continue
        indented = (not in_fence and line.startswith("    ") and number > 1 and not lines[number - 2].strip())
        if indented and COMMAND.match(line):
            problems.append(f"{page}:{number}: a command in an indented block (use a ```sh block): {line.strip()}")
    for block in parse(page):
        first = block.code.strip().splitlines()[0] if block.code.strip() else ""
        if block.kind == "text" and COMMAND.match(first):
            problems.append(f"{page}:{block.line}: an untagged block that looks like code (tag it sh or "
                            f"python): {first}")
    return problems


def repository_files():
    """The repository's files (tracked, and new ones git does not ignore), relative to ROOT."""
    try:
        listed = subprocess.run(["git", "-C", str(ROOT), "ls-files", "-z", "--cached", "--others",
                                 "--exclude-standard"], capture_output=True, check=True).stdout
        return sorted({p for p in listed.decode().split("\0") if p and (ROOT / p).is_file()})
    except (OSError, subprocess.CalledProcessError):
        skip = {".git", ".venv", "results", ".pytest_cache"}
        return sorted(str(p.relative_to(ROOT)) for p in ROOT.rglob("*") if p.is_file()
                      and p.relative_to(ROOT).parts[0] not in skip and not p.relative_to(ROOT).parts[0].startswith("build")
                      and "__pycache__" not in p.parts)


def snapshot(files):
    """Size and modification time of each repository file: the test must leave them as they are."""
    state = {}
    for name in files:
        path = ROOT / name
        state[name] = (path.stat().st_size, path.stat().st_mtime_ns) if path.exists() else None
    return state


def make_folder(folder, files):
    """A fresh folder that looks like the repository root: its files copied, build/ and .venv/ linked."""
    folder.mkdir(parents=True)
    for name in files:
        target = folder / name
        target.parent.mkdir(parents=True, exist_ok=True)
        shutil.copy2(ROOT / name, target)
    for name in ("build", ".venv"):
        if (ROOT / name).exists():
            (folder / name).symlink_to(ROOT / name)


def environment(block):
    env = dict(os.environ)
    for name in ("ELLROLL", "ELLROLL_PLOT", QUICK, "VIRTUAL_ENV", "PYTHONHOME"):
        env.pop(name, None)
    hidden = {(ROOT / "build").resolve(), (ROOT / ".venv" / "bin").resolve(), ROOT / "build", ROOT / ".venv" / "bin"}
    env["PATH"] = os.pathsep.join(p for p in env.get("PATH", "").split(os.pathsep)
                                  if p and pathlib.Path(p) not in hidden and pathlib.Path(p).resolve() not in hidden)
    env["MPLBACKEND"] = "Agg"
    env.update({k: v for k, v in block.env.items() if not (FULL and k == QUICK)})
    return env


def python():
    venv = ROOT / ".venv" / "bin" / "python"
    return str(venv) if venv.exists() else sys.executable


def mask(line):
    return " ".join(NUMBER.sub("#", line).split())


def compare_exact(expected, actual):
    """'' if actual (stdout) is what the block shows, with `...` as a wildcard; else why not."""
    pattern = ""
    for line in expected.rstrip("\n").splitlines():
        if line.strip() == "...":
            pattern += r"(?:[^\n]*\n)*?"
        else:
            pattern += ".*?".join(re.escape(part) for part in line.rstrip().split("...")) + r"[ \t]*\n"
    text = "\n".join(line.rstrip() for line in actual.rstrip("\n").splitlines()) + "\n"
    if re.fullmatch(pattern, text, re.S):
        return ""
    return f"the output differs from the block shown:\n--- shown\n{expected}--- printed\n{actual}"


def label(line):
    """A masked line's label: its text up to its first number or colon (what follows may vary)."""
    return re.split(r"#|(?<=:)", line, maxsplit=1)[0].strip()


def compare_shape(expected, actual):
    """'' if actual has the shape of the block shown (see the module's docstring); else why not."""
    shown = [mask(line) for line in expected.splitlines() if line.strip()]
    printed = [mask(line) for line in actual.splitlines() if line.strip()]
    headings = {line for line in shown if "#" not in line}
    labels = {label(line) for line in shown if "#" in line}
    problems = [f"not printed: {line!r}" for line in sorted(headings - set(printed))]
    problems += [f"printed, not shown: {line!r}" for line in printed
                 if ("#" not in line and line not in headings) or ("#" in line and label(line) not in labels)]
    if labels and not any("#" in line for line in printed):
        problems.append("no line with figures printed")
    return "" if not problems else ("the output has not the shape of the block shown:\n" + "\n".join(problems[:20])
                                    + f"\n--- printed\n{actual}")


def execute(command, folder, env):
    """(exit status, stdout, stderr, CPU seconds) of a command in its own process group, killed
    with its children after BLOCK_TIMEOUT."""
    process = subprocess.Popen(command, cwd=folder, env=env, stdin=subprocess.DEVNULL, stdout=subprocess.PIPE,
                               stderr=subprocess.PIPE, start_new_session=True)
    streams = {}

    def read(name, stream):
        streams[name] = stream.read().decode(errors="replace")
    readers = [threading.Thread(target=read, args=item) for item in (("out", process.stdout),
                                                                       ("err", process.stderr))]
    for reader in readers:
        reader.start()
    timer = threading.Timer(BLOCK_TIMEOUT, os.killpg, (process.pid, signal.SIGKILL))
    timer.start()
    _, status, usage = os.wait4(process.pid, 0)     # wait4: the CPU time of the block and its children
    timer.cancel()
    process.returncode = os.waitstatus_to_exitcode(status)
    for reader in readers:
        reader.join()
    process.stdout.close()
    process.stderr.close()
    return process.returncode, streams["out"], streams["err"], usage.ru_utime + usage.ru_stime


def run_block(block, folder):
    result = Result(block)
    command = (["bash", "-c", "set -eo pipefail\n" + block.code] if block.kind == "sh"
               else [python(), "-c", block.code])
    start = time.monotonic()
    status, stdout, stderr, result.cpu = execute(command, folder, environment(block))
    result.seconds = time.monotonic() - start
    if status != 0:
        result.status = "failed"
        why = f"killed after {BLOCK_TIMEOUT} s" if status == -signal.SIGKILL else f"exit {status}"
        result.message = f"{why}\n--- stdout\n{stdout[-3000:]}--- stderr\n{stderr[-3000:]}"
        return result
    problems = []
    if block.output is not None:
        problem = (compare_shape if block.shape else compare_exact)(block.output, stdout)
        if problem:
            problems.append(f"{block.page}:{block.output_line}: {problem}")
        result.checks += 1
    for path in block.creates:
        if not (folder / path).is_file() or (folder / path).stat().st_size == 0:
            problems.append(f"did not create {path}")
        result.checks += 1
    if problems:
        result.status, result.message = "failed", "\n".join(problems) + f"\n--- stderr\n{stderr[-2000:]}"
    else:
        result.status = "passed"
    return result


def run_page(page, blocks, folder, files):
    """Every runnable block of a page, in order, in its own folder; a block after a failed one is not run."""
    results = []
    if any(b.kind != "text" and not b.skip for b in blocks):
        make_folder(folder, files)
    failed = None
    for block in blocks:
        if block.kind == "text":
            continue
        if block.skip:
            results.append(Result(block, "skipped", block.skip))
        elif failed:
            results.append(Result(block, "not run", f"{failed} failed before it"))
        else:
            results.append(run_block(block, folder))
            if results[-1].status == "failed":
                failed = block.name
    return results
