"""One version, set in CMakeLists.txt, in the binary, its files, the Python
package and CITATION.cff; the Python package installs from post/."""
import pathlib
import re
import subprocess
import sys

import h5py

from conftest import ROOT, run

CMAKE_VERSION = re.search(r"project\(ellroll VERSION ([0-9.]+)", (ROOT / "CMakeLists.txt").read_text()).group(1)


def test_one_version_everywhere(ellroll, paper_file, tmp_path):
    stated = run(ellroll, "--version").stdout.split()[1]
    assert stated == CMAKE_VERSION or stated.startswith(CMAKE_VERSION + "+git.")
    with h5py.File(paper_file, "r") as f:
        assert f.attrs["version"] == stated
    citation = (ROOT / "CITATION.cff").read_text()
    assert re.search(r'^version: "([0-9.]+)"$', citation, re.M).group(1) == CMAKE_VERSION
    # the package as pip builds it from post/ (no index needed)
    target = tmp_path / "site"
    result = subprocess.run([sys.executable, "-m", "pip", "install", "-q", "--no-deps", "--no-build-isolation",
                             "--target", str(target), str(ROOT / "post")], capture_output=True, text=True)
    assert result.returncode == 0, result.stderr
    metadata = next(target.glob("ellroll_post-*.dist-info")) / "METADATA"
    assert f"Version: {CMAKE_VERSION}\n" in metadata.read_text()
    assert (target / "bin" / "ellroll-plot").exists()
    assert (target / "ellroll" / "__init__.py").exists()        # the Python API, beside ellroll_post
    requires = [line for line in metadata.read_text().splitlines() if line.startswith("Requires-Dist")]
    assert requires and all(">=" in line for line in requires), requires


def test_licence_and_citation_present():
    assert (ROOT / "LICENSE").read_text().startswith("BSD 3-Clause License")
    assert "Legeza" in (ROOT / "CITATION.cff").read_text()
