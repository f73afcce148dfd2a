"""The docs as a user meets them: a short README whose links all lead
somewhere, every doc file reached from it, and no development log in the
repository's files (history belongs in commit messages)."""
import os
import re
import subprocess

import pytest

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
    assert "theta_max: 0.2340974889" in done.stdout


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
