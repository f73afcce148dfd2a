"""Shared fixtures: the ellroll executables and a run of the paper's case."""
import os
import pathlib
import shutil
import subprocess

import pytest

ROOT = pathlib.Path(__file__).resolve().parents[2]
# tests/run_all.sh runs some files again on the sanitizer build: there a
# test of a numerical property (long runs) is left out, and the random
# searches take a smaller budget (the sanitizer looks for memory errors)
SANITIZED = os.environ.get("ELLROLL_BUILD") == "sanitize"
PAPER_INPUT = ROOT / "input" / "legeza1990.nml"


def _exe(variable, default):
    path = pathlib.Path(os.environ.get(variable, ROOT / default))
    if not path.exists():
        pytest.skip(f"{path} not built")
    return path


@pytest.fixture(scope="session")
def ellroll():
    return _exe("ELLROLL_EXE", "build/ellroll")


@pytest.fixture(scope="session")
def ellroll_debug():
    """The Debug build: -fcheck=all and floating-point traps."""
    return _exe("ELLROLL_DEBUG_EXE", "build-debug/ellroll")


def run(exe, *args, cwd=None, timeout=120):
    return subprocess.run([str(exe), *map(str, args)], cwd=cwd, capture_output=True,
                          text=True, timeout=timeout)


def run_shards_and_merge(exe, name, folder, order, merged="merged.h5"):
    """Namelist `name` run in len(order) shards (shard_i.h5), then merged in
    the given order of the shards into `merged`."""
    for i in range(len(order)):
        result = run(exe, "run", name, "-q", "--shard", f"{i}/{len(order)}", "-o", f"shard_{i}.h5", cwd=folder)
        assert result.returncode == 0, result.stderr
    result = run(exe, "merge", merged, *(f"shard_{i}.h5" for i in order), cwd=folder)
    assert result.returncode == 0, result.stderr
    return folder / merged


@pytest.fixture(scope="session")
def paper_file(ellroll, tmp_path_factory):
    """The paper's case run once, as written by the program."""
    folder = tmp_path_factory.mktemp("paper")
    shutil.copy(PAPER_INPUT, folder / "legeza1990.nml")
    result = run(ellroll, "run", "legeza1990.nml", cwd=folder)
    assert result.returncode == 0, result.stderr
    return folder / "legeza1990.h5"
