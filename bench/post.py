#!/usr/bin/env python3
"""Reading ellroll files with h5py: one case's full trajectory and the whole
summary of a 10^4-case campaign (a case's samples are one piece of each
contiguous trajectory dataset, so reading a case is one read per dataset).

    .venv/bin/python bench/post.py [--exe build/ellroll] [--cases 10000] [--quick]

--quick (or ELLROLL_BENCH_QUICK=1): 100 cases (a smoke test).
"""
import argparse
import pathlib
import subprocess
import tempfile
import time

import h5py
import numpy as np

from common import executable, quick

ROOT = pathlib.Path(__file__).resolve().parents[1]
INPUT = """&geometry a = 1.0, b = 0.4, c = 0.2 /
&ball radius = 0.2, weight = 2620.0 /
&initial omega = -2.0, 2.0, 20.0 /
&integration dt = 1.0e-3, t_end = 2.0 /
&output file = 'post.h5', interval = 0.01 /
&sweep name = 'omega_z', start = 5, stop = 100, count = {n} /
"""


def best_of(function, repeats=5):
    times = []
    for _ in range(repeats):
        start = time.perf_counter()
        function()
        times.append(time.perf_counter() - start)
    return min(times)


def main():
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--exe", default=str(ROOT / "build" / "ellroll"))
    parser.add_argument("--cases", type=int, default=10000)
    parser.add_argument("--quick", action="store_true", help="100 cases (a smoke test)")
    args = parser.parse_args()
    args.exe = executable(args.exe)
    if quick(args.quick):
        args.cases = 100
    with tempfile.TemporaryDirectory() as tmp:
        folder = pathlib.Path(tmp)
        (folder / "post.nml").write_text(INPUT.format(n=args.cases))
        subprocess.run([args.exe, "run", "post.nml", "-q"], cwd=folder, check=True, stdout=subprocess.DEVNULL)
        path = folder / "post.h5"
        size = path.stat().st_size / 2**20
        rng = np.random.default_rng(0)
        cases = rng.integers(0, args.cases, 20)
        with h5py.File(path, "r") as f:
            def one_case():
                for case in cases:
                    for name in f["trajectory"]:
                        if name != "case":
                            f["trajectory"][name][case]
            def summary():
                for name in f["summary"]:
                    f["summary"][name][()]
            per_case = best_of(one_case) / len(cases)
            whole_summary = best_of(summary)
        print(f"file: {args.cases} cases x 201 samples x all fields, {size:.0f} MiB")
        print(f"one case's full trajectory (every field): {1e3 * per_case:.2f} ms")
        print(f"the whole summary ({args.cases} cases, every dataset): {1e3 * whole_summary:.2f} ms "
              f"({1e6 * whole_summary / args.cases:.2f} us per case)")


if __name__ == "__main__":
    main()
