"""The bench command docs/performance.md shows for the work-precision
figure, run as written (at the tests' tiny size) from a folder that looks
like the repository root: it leaves the repository's files as they are
(docs/workprecision.png and .csv, the figure docs/accuracy.md shows, among
them) and writes its figure and CSV in the current folder."""
import hashlib
import shutil
import subprocess

import pytest

import docs_blocks
from conftest import ROOT


def digest(folder):
    return {p.relative_to(folder).as_posix(): hashlib.sha256(p.read_bytes()).hexdigest()
            for p in sorted(folder.rglob("*")) if p.is_file() and "__pycache__" not in p.parts}


def test_the_documented_workprecision_command_leaves_docs_as_they_are(ellroll, tmp_path):
    python = ROOT / ".venv" / "bin" / "python"
    if not python.exists():
        pytest.skip(f"{python} is not there (.ci/setup makes it)")
    blocks = [b for b in docs_blocks.parse("docs/performance.md") if "bench/workprecision.py" in b.code]
    assert len(blocks) == 1, blocks
    block = blocks[0]
    assert block.code.strip().startswith(".venv/bin/python bench/workprecision.py"), block.code
    root = tmp_path / "checkout"
    for folder in ("bench", "docs"):
        shutil.copytree(ROOT / folder, root / folder)
    (root / "build").mkdir()
    (root / "build" / "ellroll").symlink_to(ellroll)
    (root / ".venv").symlink_to(ROOT / ".venv")
    before = digest(root / "docs"), digest(root / "bench")
    done = subprocess.run(["bash", "-c", "set -eo pipefail\n" + block.code], cwd=root, capture_output=True,
                          text=True, env=docs_blocks.environment(block), timeout=600)
    assert done.returncode == 0, done.stderr[-3000:]
    assert (digest(root / "docs"), digest(root / "bench")) == before
    for name in ("workprecision.png", "workprecision.csv"):
        assert (root / name).stat().st_size > 0, name
    rows = (root / "workprecision.csv").read_text().splitlines()
    assert rows[0] == "method,setting,error_m,time_s,rhs_evaluations" and len(rows) > 5
    assert "wrote workprecision.png and workprecision.csv" in done.stderr, done.stderr[-500:]
