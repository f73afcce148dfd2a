#!/usr/bin/env python3
"""Campaign throughput and memory, measured side by side in one run.

A spin x radius sweep of the paper's cup (t_end = 5 s, dt = 1e-3, contact and
nutation stored every 0.01 s) is run with 1 and 2 threads (and more with
--threads), giving cases/s and the parallel efficiency; then the same
campaign with 1,000 and 10,000 cases (or --rss-cases) gives peak RSS, which
must not grow with the number of cases (trajectories stream to disk).

The one-thread runs also give `ellroll run --timings`: the sections of the
loop that one thread at a time can be in (the locks, and the writes in place,
which the kernel serialises per file). Their busiest share of the loop bounds
the speed-up of any number of threads, and with the time outside the loop it
bounds the efficiency on --project threads (default 16): a ceiling measured
here, for machines whose cores scale, not a measurement on that many cores.

    .venv/bin/python bench/campaign.py [--exe build/ellroll] [--threads 1 2 16] [--cases 10000]
                                       [--repeat 3] [--rss-cases 1000 10000 100000] [--project 16] [--quick]

--quick (or ELLROLL_BENCH_QUICK=1): 200 cases, one run each, peak RSS at 100
and 200 cases (a smoke test).
"""
import argparse
import pathlib
import re
import subprocess
import sys
import tempfile
import time

from common import executable, quick

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
           "out = subprocess.run(sys.argv[1:], check=True, stdout=subprocess.PIPE, text=True).stdout; "
           "print(time.perf_counter() - t, resource.getrusage(resource.RUSAGE_CHILDREN).ru_maxrss); print(out)")


def measure(exe, folder, n_cases, threads):
    """(wall seconds, peak RSS in MiB, its --timings text) of one run in a fresh process."""
    (folder / "bench.nml").write_text(INPUT.format(spins=n_cases // 10))
    # the previous run's file is removed outside the timing: --overwrite would
    # free its pages inside it, serially, a cost of that file, not of this run
    (folder / "bench.h5").unlink(missing_ok=True)
    out = subprocess.run([sys.executable, "-c", MEASURE, exe, "run", "bench.nml", "-q",
                          "--threads", str(threads), "--timings"], cwd=folder, check=True, capture_output=True, text=True)
    first, timings = out.stdout.split("\n", 1)
    seconds, rss_kib = first.split()
    return float(seconds), int(rss_kib) / 1024, timings


def serial_sections(timings):
    """(seconds in parallel before the loop, loop seconds, {section: seconds inside}) from
    ellroll's --timings text."""
    before = float(re.search(r"([0-9.]+) s in parallel before the loop", timings).group(1))
    loop = float(re.search(r"([0-9.]+) s in the loop", timings).group(1))
    sections = {m.group(1).strip(): float(m.group(2))
                for m in re.finditer(r"^  (\S.{35})\s+([0-9.]+)\s+[0-9.]+$", timings, re.MULTILINE)}
    return before, loop, sections


def main():
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--exe", default=str(ROOT / "build" / "ellroll"))
    parser.add_argument("--threads", type=int, nargs="+", default=[1, 2])
    parser.add_argument("--cases", type=int, default=1000)
    parser.add_argument("--repeat", type=int, default=1, help="best of this many runs per thread count")
    parser.add_argument("--rss-cases", type=int, nargs="+", default=[1000, 10000],
                        help="campaign sizes whose peak RSS is compared (the largest thread count)")
    parser.add_argument("--project", type=int, default=16,
                        help="thread count whose efficiency is bounded from the one-thread run's serial sections")
    parser.add_argument("--quick", action="store_true", help="a tiny campaign (a smoke test)")
    args = parser.parse_args()
    args.exe = executable(args.exe)
    if quick(args.quick):
        args.cases, args.repeat, args.rss_cases = 200, 1, [100, 200]
    with tempfile.TemporaryDirectory() as tmp:
        folder = pathlib.Path(tmp)
        print(f"campaign of {args.cases} cases, 5,000 RK4 steps each ({time.strftime('%Y-%m-%d')})")
        print(f"{'threads':>8} {'wall s':>8} {'cases/s':>9} {'speed-up':>9} {'efficiency':>11}")
        base = None
        one_thread = None
        for threads in args.threads:
            seconds, _, timings = min(measure(args.exe, folder, args.cases, threads) for _ in range(args.repeat))
            rate = args.cases / seconds
            base = base or rate
            print(f"{threads:8d} {seconds:8.2f} {rate:9.1f} {rate / base:9.2f} {rate / base / threads:10.0%}")
            if threads == 1:
                one_thread = seconds, timings
        if one_thread:
            print_ceiling(*one_thread, args.project)
        print(f"{'cases':>8} {'peak RSS MiB':>13}")
        rss = {}
        for n in args.rss_cases:
            rss[n] = measure(args.exe, folder, n, max(args.threads))[1]
            print(f"{n:8d} {rss[n]:13.1f}")
        low, high = min(rss), max(rss)
        print(f"RSS ratio {high:,} / {low:,} cases: {rss[high] / rss[low]:.2f}")


def print_ceiling(wall, timings, threads):
    """The one-thread run's serial sections, and the efficiency they allow on `threads`."""
    before, loop, sections = serial_sections(timings)
    busiest = max(sections, key=sections.get)
    print(f"serial sections of the 1-thread loop ({loop:.2f} s), seconds inside:")
    for name, seconds in sections.items():
        print(f"  {name:36s} {seconds:8.4f}  {seconds / loop:6.2%}")
    serial = wall - loop - before    # process start and exit, file layout, closing
    fastest = serial + before / threads + max(loop / threads, sections[busiest])
    print(f"busiest: {busiest} ({sections[busiest] / loop:.2%} of the loop: the loop speeds up "
          f"{loop / sections[busiest]:.0f}x at most); outside the loop {serial:.3f} s serial, "
          f"{before:.3f} s parallel")
    print(f"ceiling on {threads} threads: {wall / fastest:.1f}x, efficiency at most {wall / fastest / threads:.0%} "
          f"(from the serial sections and the serial time outside the loop; cores assumed to scale)")


if __name__ == "__main__":
    main()
