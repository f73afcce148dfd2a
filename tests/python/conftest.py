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
# The README's test command meets a large product of cases (damaged files x
# subcommands, failures x places) by a seeded cover: each item of every
# factor at least once, in turn. ELLROLL_TEST_FULL=1 runs every combination
# (and the larger budgets of test_faults, test_sliding_truth and the docs).
FULL = os.environ.get("ELLROLL_TEST_FULL", "0") not in ("", "0")


def in_turn(items, k):
    """What the k-th case of a product meets of `items`: every item with
    ELLROLL_TEST_FULL, else the one at k in turn."""
    items = list(items)
    return items if FULL else [items[k % len(items)]]


def pairs_in_turn(first, second):
    """The parameter pairs of first x second: every pair with
    ELLROLL_TEST_FULL, else each item of first with one of second in turn
    (and every item of second met)."""
    first, second = list(first), list(second)
    if FULL:
        return [(a, b) for a in first for b in second]
    count = max(len(first), len(second))
    return [(first[k % len(first)], second[k % len(second)]) for k in range(count)]


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


def plot_in_process(*args, cwd=None):
    """ellroll-plot's main(argv) in this process, as `python -m
    ellroll_post.cli ARGS` would run it from cwd (its entry point runs as a
    process in test_figures and the docs' tests): a CompletedProcess with the
    exit code and what it printed. (A second interpreter and matplotlib's
    import cost a second a call.)"""
    import contextlib
    import io
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    from ellroll_post.cli import main
    out, err = io.StringIO(), io.StringIO()
    here = os.getcwd()
    try:
        if cwd is not None:
            os.chdir(cwd)
        with contextlib.redirect_stdout(out), contextlib.redirect_stderr(err):
            try:
                code = main([str(a) for a in args])
            except SystemExit as exc:          # argparse
                code = exc.code
    finally:
        os.chdir(here)
        plt.close("all")
    return subprocess.CompletedProcess(["ellroll-plot", *map(str, args)], code, out.getvalue(), err.getvalue())
