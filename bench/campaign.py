#!/usr/bin/env python3
"""Campaign throughput and memory, measured side by side in one run.

A spin x radius sweep of the paper's cup (t_end = 5 s, dt = 1e-3, contact and
nutation stored every 0.01 s) is run with 1 and 2 threads (and more with
--threads), giving cases/s and the parallel efficiency; then the same
campaign with 1,000 and 10,000 cases (or --rss-cases) gives peak RSS, which
must not grow with the number of cases (trajectories stream to disk).

    python bench/campaign.py [--exe build/ellroll] [--threads 1 2 16] [--cases 10000] [--repeat 3]
                             [--rss-cases 1000 10000 100000]
"""
import argparse
import pathlib
import subprocess
import sys
import tempfile
import time

ROOT = pathlib.Path(__file__).resolve().parents[1]
INPUT = """&geometry    a = 1.0, b = 0.4, c = 0.2 /
&ball        radius = 0.2, weight = 2620.0 /
&initial     x = 0.0, y = 0.0, omega = -2.0, 2.0, 20.0 /
&integration dt = 1.0e-3, t_end = 5.0 /
&output      file = 'bench.h5', interval = 0.01, fields = 'contact', 'nutation' /
&sweep       name = 'omega_z', start = 5, stop = 100, count = {spins} /
&sweep       name = 'radius', start = 0.02, stop = 0.2, count = 10 /
"""
MEASURE = ("import resource, subprocess, sys, time; t = time.perf_counter(); "
           "subprocess.run(sys.argv[1:], check=True, stdout=subprocess.DEVNULL); "
           "print(time.perf_counter() - t, resource.getrusage(resource.RUSAGE_CHILDREN).ru_maxrss)")


def measure(exe, folder, n_cases, threads):
    """(wall seconds, peak RSS in MiB) of one run in a fresh process."""
    (folder / "bench.nml").write_text(INPUT.format(spins=n_cases // 10))
    # the previous run's file is removed outside the timing: --overwrite would
    # free its pages inside it, serially, a cost of that file, not of this run
    (folder / "bench.h5").unlink(missing_ok=True)
    out = subprocess.run([sys.executable, "-c", MEASURE, str(pathlib.Path(exe).resolve()), "run", "bench.nml", "-q",
                          "--threads", str(threads)], cwd=folder, check=True, capture_output=True, text=True)
    seconds, rss_kib = out.stdout.split()
    return float(seconds), int(rss_kib) / 1024


def main():
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--exe", default=str(ROOT / "build" / "ellroll"))
    parser.add_argument("--threads", type=int, nargs="+", default=[1, 2])
    parser.add_argument("--cases", type=int, default=1000)
    parser.add_argument("--repeat", type=int, default=1, help="best of this many runs per thread count")
    parser.add_argument("--rss-cases", type=int, nargs="+", default=[1000, 10000],
                        help="campaign sizes whose peak RSS is compared (the largest thread count)")
    args = parser.parse_args()
    with tempfile.TemporaryDirectory() as tmp:
        folder = pathlib.Path(tmp)
        print(f"campaign of {args.cases} cases, 5,000 RK4 steps each ({time.strftime('%Y-%m-%d')})")
        print(f"{'threads':>8} {'wall s':>8} {'cases/s':>9} {'speed-up':>9} {'efficiency':>11}")
        base = None
        for threads in args.threads:
            seconds = min(measure(args.exe, folder, args.cases, threads)[0] for _ in range(args.repeat))
            rate = args.cases / seconds
            base = base or rate
            print(f"{threads:8d} {seconds:8.2f} {rate:9.1f} {rate / base:9.2f} {rate / base / threads:10.0%}")
        print(f"{'cases':>8} {'peak RSS MiB':>13}")
        rss = {}
        for n in args.rss_cases:
            _, rss[n] = measure(args.exe, folder, n, max(args.threads))
            print(f"{n:8d} {rss[n]:13.1f}")
        low, high = min(rss), max(rss)
        print(f"RSS ratio {high:,} / {low:,} cases: {rss[high] / rss[low]:.2f}")


if __name__ == "__main__":
    main()
