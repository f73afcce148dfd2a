"""The docs as a user meets them: a short README whose links all lead
somewhere, every doc file reached from it, and no development log in the
repository's files (history belongs in commit messages)."""
import concurrent.futures
import os
import re
import subprocess
import time

import pytest

import docs_blocks
from conftest import ROOT

FOLDERS = ["docs", "src", "post", "tests", "bench", "examples", "input", "cmake"]
# words of a development log: numbered steps of the work, sessions, the
# machines figures were borrowed from
# (Fortran's `error stop 1` and `stop 2` statements and pytest's
# scope="session" are not)
FORTRAN_STOP = re.compile(r"\s*(error )?stop \d+\s*")
LOG_WORDS = re.compile(r"(?<!error )\b(stop|stops) \d+\b|(?<!scope=\")\bsession\b|\bborrowed\b|\blent machine\b",
                       re.I)


def links(markdown):
    return [target for target in re.findall(r"\]\(([^)#\s]+)", markdown) if "://" not in target]


def test_readme_is_short_and_its_links_resolve():
    readme = (ROOT / "README.md").read_text()
    assert len(readme.splitlines()) <= 250
    targets = links(readme)
    assert {"docs/usage.md", "docs/inputs.md", "docs/output.md", "docs/performance.md", "docs/design.md",
            "LICENSE", "CITATION.cff"} <= set(targets)
    for target in targets:
        assert (ROOT / target).exists(), target
    reached = {pathlib_name for pathlib_name in (t.split("/")[-1] for t in targets)}
    for doc in (ROOT / "docs").glob("*.md"):
        assert doc.name in reached, f"docs/{doc.name} is not linked from the README"
        for target in links(doc.read_text()):
            assert (doc.parent / target).exists(), f"docs/{doc.name}: {target}"


def repository_text_files():
    paths = [ROOT / "README.md", ROOT / "CMakeLists.txt", ROOT / "CITATION.cff"]
    for folder in FOLDERS:
        paths += [p for p in (ROOT / folder).rglob("*") if p.is_file() and p.suffix in
                  {".md", ".f90", ".c", ".py", ".sh", ".nml", ".cmake", ".txt", ".in", ".bash", ".toml", ".sbatch"}
                  and "egg-info" not in str(p)]
    return paths


def test_no_file_outside_the_repository_is_cited():
    """The model's derivation is docs/model.md; nothing refers to notes that are not in the repository."""
    outside = re.compile(r"physics\.md|\.\./shared\b")
    found = [f"{path.relative_to(ROOT)}:{number}: {line.strip()}" for path in repository_text_files()
             if path.name != "test_docs.py"
             for number, line in enumerate(path.read_text(errors="replace").splitlines(), 1) if outside.search(line)]
    assert found == []


def test_no_development_log_in_the_files():
    found = []
    for path in repository_text_files():
        if path.name == "test_docs.py":
            continue
        for number, line in enumerate(path.read_text(errors="replace").splitlines(), 1):
            if LOG_WORDS.search(line) and not FORTRAN_STOP.fullmatch(line):
                found.append(f"{path.relative_to(ROOT)}:{number}: {line.strip()}")
    assert found == []


# Docs as tests: every shell block and Python snippet of the README, docs/*.md
# and post/README.md runs, page by page, in a fresh folder (docs_blocks.py
# says how, and what the HTML comments above some blocks mean).
PARSED, PARSE_ERRORS = {}, []
for _page in docs_blocks.pages():
    try:
        PARSED[_page] = docs_blocks.parse(_page)
    except ValueError as error:
        PARSE_ERRORS.append(str(error))
        PARSED[_page] = []
RUNNABLE = [block for blocks in PARSED.values() for block in blocks if block.kind != "text"]
# the longest pages first: two pages run at a time
ORDER = sorted(PARSED, key=lambda page: page not in ("docs/performance.md", "README.md"))


@pytest.fixture(scope="module")
def docs_run(tmp_path_factory):
    for needed in (ROOT / "build" / "ellroll", ROOT / ".venv" / "bin" / "python"):
        if not needed.exists():
            pytest.skip(f"{needed} is not there (.ci/setup makes it)")
    files = docs_blocks.repository_files()
    before = docs_blocks.snapshot(files)
    base = tmp_path_factory.mktemp("docs")
    start = time.monotonic()
    with concurrent.futures.ThreadPoolExecutor(max_workers=2) as pool:
        futures = {page: pool.submit(docs_blocks.run_page, page, PARSED[page],
                                     base / page.replace("/", "_").removesuffix(".md"), files) for page in ORDER}
        results = {page: futures[page].result() for page in ORDER}
    return {"results": results, "seconds": time.monotonic() - start, "before": before,
            "after": docs_blocks.snapshot(files)}


def test_docs_markers_parse_and_every_command_is_in_a_block():
    problems = PARSE_ERRORS + [p for page in PARSED for p in docs_blocks.lint(page)]
    assert problems == []
    assert len(RUNNABLE) >= 20


# the tests of docs_run on one pytest-xdist worker (--dist loadgroup): the
# fixture runs every block of the docs, once a worker
ONE_WORKER = pytest.mark.xdist_group("docs_run")


@ONE_WORKER
@pytest.mark.parametrize("block", RUNNABLE, ids=lambda block: block.name)
def test_docs_block_runs_as_written(docs_run, block):
    result = next(r for r in docs_run["results"][block.page] if r.block is block)
    if result.status == "skipped":
        pytest.skip(f"{block.name}: {result.message}")
    assert result.status == "passed", f"{block.name} ({result.status}): {result.message}"


@ONE_WORKER
def test_docs_blocks_leave_the_repository_as_it_was(docs_run):
    changed = [name for name in docs_run["before"] if docs_run["before"][name] != docs_run["after"][name]]
    assert changed == []


@ONE_WORKER
def test_docs_blocks_summary(docs_run, capsys):
    """Prints what ran: blocks found, run, skipped (with the reasons), output checks, time."""
    results = [r for page in ORDER for r in docs_run["results"][page]]
    ran = [r for r in results if r.status in ("passed", "failed")]
    skipped = [r for r in results if r.status == "skipped"]
    lines = [f"docs as tests: {len(RUNNABLE)} blocks found "
             f"({sum(b.kind == 'sh' for b in RUNNABLE)} sh, {sum(b.kind == 'python' for b in RUNNABLE)} python) "
             f"on {sum(bool(PARSED[p]) for p in PARSED)} pages; {len(ran)} run, {len(skipped)} skipped, "
             f"{sum(r.checks for r in results)} output checks; {docs_run['seconds']:.1f} s, "
             f"{sum(r.cpu for r in results):.1f} s of CPU"
             + (" (ELLROLL_TEST_FULL)" if docs_blocks.FULL else "")]
    lines += [f"  skipped {r.block.name}: {r.message}" for r in skipped]
    for page in ORDER:
        if docs_run["results"][page]:
            page_results = docs_run["results"][page]
            lines.append(f"  {page}: {sum(r.seconds for r in page_results):.1f} s, "
                         f"{sum(r.cpu for r in page_results):.1f} s of CPU; lines "
                         + ", ".join(f"{r.block.line} {r.status}" for r in page_results))
    with capsys.disabled():
        print("\n" + "\n".join(lines))
    assert all(r.status in ("passed", "failed", "skipped", "not run") for r in results)


def test_docs_output_checks_catch_a_difference():
    """The comparisons behind the output blocks fail where the output differs."""
    shown = "legeza1990.h5: 1 cases\n  steps: ... s\n...\n  theta_max: 0.2340974889... rad\n"
    assert docs_blocks.compare_exact(shown, "legeza1990.h5: 1 cases\n  steps: 0.03 s\nmore\n"
                                            "  theta_max: 0.23409748897743754 rad\n") == ""
    assert docs_blocks.compare_exact(shown, "legeza1990.h5: 1 cases\n  steps: 0.03 s\n"
                                            "  theta_max: 0.2340974890 rad\n") != ""
    assert docs_blocks.compare_exact(shown, "legeza1990.h5: 2 cases\n  steps: 0.03 s\n"
                                            "  theta_max: 0.23409748897743754 rad\n") != ""
    table = "method   time s\nellroll rk4  dt=0.1   1.0e-04\nscipy  rtol=0.01  7.6e-02\n"
    assert docs_blocks.compare_shape(table, "method   time s\nellroll rk4  dt=0.01   3.0e-04\n") == ""
    assert docs_blocks.compare_shape(table, "method   time\nellroll rk4  dt=0.01   3.0e-04\n") != ""
    assert docs_blocks.compare_shape(table, "method   time s\nellroll gauss4  dt=0.01   3.0e-04\n") != ""
    assert docs_blocks.compare_shape(table, "method   time s\n") != ""


def test_the_readme_shows_the_paper_case_input_as_it_is():
    readme = (ROOT / "README.md").read_text()
    shown = re.search(r"The paper's case, `input/legeza1990.nml`:\n\n```\n(.*?)```", readme, re.S).group(1)
    case = [line for line in (ROOT / "input" / "legeza1990.nml").read_text().splitlines(keepends=True)
            if not line.startswith("!")]
    assert shown == "".join(case)


def test_the_installed_paper_case_example_runs(tmp_path):
    """`cmake --install build --prefix P`, then P/share/ellroll/examples/paper_case.sh from a
    folder of one's own, with P/bin/ellroll and the ellroll-plot on PATH (pip install ./post)."""
    plot = ROOT / ".venv" / "bin" / "ellroll-plot"
    if not (ROOT / "build" / "ellroll").exists() or not plot.exists():
        pytest.skip("needs build/ellroll and .venv/bin/ellroll-plot (.ci/setup makes them)")
    prefix, work = tmp_path / "prefix", tmp_path / "work"
    work.mkdir()
    subprocess.run(["cmake", "--install", str(ROOT / "build"), "--prefix", str(prefix)], check=True,
                   capture_output=True)
    env = {k: v for k, v in os.environ.items() if k not in ("ELLROLL", "ELLROLL_PLOT")}
    env.update(PATH=f"{plot.parent}{os.pathsep}/usr/bin{os.pathsep}/bin", MPLBACKEND="Agg")
    done = subprocess.run(["bash", str(prefix / "share" / "ellroll" / "examples" / "paper_case.sh")], cwd=work,
                          env=env, capture_output=True, text=True, timeout=300)
    assert done.returncode == 0, done.stderr
    for name in ("legeza1990.h5", "legeza1990_fig2_trace.png", "legeza1990_fig3_nutation.png", "report/index.html"):
        assert (work / "results" / name).stat().st_size > 0, name
    assert "theta_max: 0.2340975229" in done.stdout
    # the installed README and pages link to each other where they are installed
    docs = prefix / "share" / "doc" / "ellroll"
    pages = sorted(docs.rglob("*.md"))
    assert docs / "README.md" in pages and docs / "docs" / "usage.md" in pages and docs / "post" / "README.md" in pages
    broken = [(str(page.relative_to(docs)), target) for page in pages for target in links(page.read_text())
              if not (page.parent / target).exists()]
    assert broken == []


def test_slurm_submit_finds_the_checkouts_ellroll(tmp_path):
    """The README's `examples/slurm/submit.sh ...` from the repository root, where ellroll is not
    on PATH: the jobs get the checkout's build/ellroll (sbatch here is a stand-in that records
    how it was called)."""
    ellroll = ROOT / "build" / "ellroll"
    if not ellroll.exists():
        pytest.skip("needs build/ellroll")
    stubs = tmp_path / "bin"
    stubs.mkdir()
    (stubs / "sbatch").write_text('#!/bin/bash\necho "$* ELLROLL=${ELLROLL:-}" >> "$SBATCH_LOG"\necho 42\n')
    (stubs / "sbatch").chmod(0o755)
    log = tmp_path / "sbatch.log"
    env = {k: v for k, v in os.environ.items() if k != "ELLROLL"}
    env.update(PATH=f"{stubs}{os.pathsep}/usr/bin{os.pathsep}/bin", SBATCH_LOG=str(log))
    done = subprocess.run(["examples/slurm/submit.sh", "input/spin_sweep.nml", str(tmp_path / "on_slurm.h5"),
                           "16", "8"], cwd=ROOT, env=env, capture_output=True, text=True, timeout=60)
    assert done.returncode == 0, done.stderr
    assert done.stdout == "array job 42, merge job 42\n"
    array, merge = log.read_text().splitlines()
    assert "--array=0-15 --cpus-per-task=8" in array and "campaign.sbatch" in array
    assert "--dependency=afterok:42" in merge and "merge.sbatch" in merge
    for call in (array, merge):
        assert call.endswith(f"ELLROLL={ellroll.resolve()}")
    assert not (tmp_path / "on_slurm.h5").exists()
