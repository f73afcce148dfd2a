#!/usr/bin/env python3
"""Small campaigns on 1 and 2 threads (and more with --threads): wall time
and parallel efficiency, side by side in one run, best of --repeat.

The paper's cup swept over omega_z, RK4 dt = 1e-4, no trajectories stored:
- 8 cases on a fixed cup: one SIMD batch of 8 (the campaign is batched, so
  the 8 cases are one block of work);
- 8 cases with gauss4 (dt = 1e-3), which does not run in SIMD batches: a
  block per case;
- 2 cases on a fixed cup: fewer than a batch, a block per case.

    .venv/bin/python bench/small_campaigns.py [--exe build/ellroll] [--threads 1 2] [--repeat 3] [--quick]

--quick (or ELLROLL_BENCH_QUICK=1): each campaign 1/40 as long, one run (a
smoke test).
"""
import argparse
import pathlib
import subprocess
import tempfile
import time

from common import executable, quick

ROOT = pathlib.Path(__file__).resolve().parents[1]
BASE = """&geometry a = 1.0, b = 0.4, c = 0.2 /
&ball radius = 0.2, weight = 2620.0 /
&initial omega = -2.0, 2.0, 20.0 /
&integration method = 'rk4', dt = 1.0e-4, t_end = {t_end} /
&output file = 'small.h5', interval = 0.01, fields = 'none' /
&sweep name = 'omega_z', start = 10, stop = 80, count = {n} /
"""
GAUSS4 = ("method = 'rk4', dt = 1.0e-4", "method = 'gauss4', dt = 1.0e-3")


def campaigns(scale=1.0):
    """(title, input) of each campaign, t_end multiplied by scale."""
    return [("8 cases, fixed cup (one SIMD batch)", BASE.format(n=8, t_end=120.0 * scale)),
            ("8 cases with gauss4 (a block each)", BASE.format(n=8, t_end=40.0 * scale).replace(*GAUSS4)),
            ("2 cases, fixed cup (a block each)", BASE.format(n=2, t_end=120.0 * scale))]


def wall(exe, folder, threads, repeat):
    best = float("inf")
    for _ in range(repeat):
        start = time.perf_counter()
        subprocess.run([exe, "run", "small.nml", "-q", "--overwrite", "--threads", str(threads)], cwd=folder,
                       check=True, stdout=subprocess.DEVNULL)
        best = min(best, time.perf_counter() - start)
    return best


def main():
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--exe", default=str(ROOT / "build" / "ellroll"))
    parser.add_argument("--threads", type=int, nargs="+", default=[1, 2])
    parser.add_argument("--repeat", type=int, default=3)
    parser.add_argument("--quick", action="store_true", help="short campaigns, one run (a smoke test)")
    args = parser.parse_args()
    args.exe = executable(args.exe)
    scale = 1.0
    if quick(args.quick):
        scale, args.repeat = 1 / 40, 1
    print(f"{'campaign':<38} {'threads':>7} {'wall s':>8} {'speed-up':>9} {'efficiency':>11}")
    with tempfile.TemporaryDirectory() as folder:
        for title, text in campaigns(scale):
            (pathlib.Path(folder) / "small.nml").write_text(text)
            times = {t: wall(args.exe, folder, t, args.repeat) for t in args.threads}
            one = times[args.threads[0]] * args.threads[0]
            for threads, seconds in times.items():
                speedup = one / seconds
                print(f"{title:<38} {threads:7d} {seconds:8.3f} {speedup:9.2f} {speedup / threads:10.0%}")


if __name__ == "__main__":
    main()
