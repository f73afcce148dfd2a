"""What the Python benches share: the ellroll executable they are given, and
their quick mode.

The benches run ellroll from temporary folders, so a relative --exe
(`--exe build/ellroll`, as docs/performance.md writes it) is taken from the
folder the bench was started in; a bare name is looked up on PATH.

Quick mode (--quick, or ELLROLL_BENCH_QUICK=1 in the environment) runs each
bench at a tiny size with the same table layout: a smoke test whose figures
mean nothing. tests/python/test_docs.py runs docs/performance.md's commands so.
"""
import os
import pathlib
import shutil
import sys

QUICK_VARIABLE = "ELLROLL_BENCH_QUICK"


def executable(path):
    """The absolute path of the executable given as `path`; exits with a message if there is none."""
    found = shutil.which(path) if os.sep not in path else None
    resolved = pathlib.Path(found or path).resolve()
    if not (resolved.is_file() and os.access(resolved, os.X_OK)):
        sys.exit(f"{path}: no such executable (build it: cmake --build build)")
    return str(resolved)


def quick(flag=False):
    """Whether to run at the quick size: --quick, or ELLROLL_BENCH_QUICK set to anything but 0."""
    return bool(flag) or os.environ.get(QUICK_VARIABLE, "0") not in ("", "0")
