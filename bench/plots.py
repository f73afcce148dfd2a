#!/usr/bin/env python3
"""ellroll-plot on a sampled campaign: the time and peak memory of every
command and of the report, each in its own process (default 100,000 cases:
5 inputs sampled, paper cup, rk4 dt 1e-3, t_end 1 s, a sample every 0.01 s).

    .venv/bin/python bench/plots.py [--exe build/ellroll] [--cases 100000] [--keep DIR] [--quick]

ellroll-plot is the one on PATH, else the repository's .venv/bin/ellroll-plot.
--quick (or ELLROLL_BENCH_QUICK=1): 200 cases and three of the commands (a
smoke test).
"""
import argparse
import os
import pathlib
import shutil
import subprocess
import sys
import tempfile
import time

from common import executable, quick

ROOT = pathlib.Path(__file__).resolve().parents[1]
INPUT = """&geometry a = 1.0, b = 0.4, c = 0.2 /
&ball radius = 0.2, weight = 2620.0 /
&initial omega = -2.0, 2.0, 20.0 /
&integration method = 'rk4', dt = 1.0e-3, t_end = {t_end} /
&output file = 'campaign.h5', interval = 0.01 /
&campaign samples = {n}, seed = 7 /
&sample name = 'omega_z', low = 5, high = 50 /
&sample name = 'radius', low = 0.05, high = 0.2 /
&sample name = 'x', low = -0.1, high = 0.1 /
&sample name = 'y', low = -0.05, high = 0.05 /
&sample name = 'mu', low = 0.1, high = 0.5 /
"""
COMMANDS = [["trace"], ["nutation"], ["reaction"], ["energy"], ["sweep"], ["sweep", "--x", "omega_z"],
            ["sweep", "--x", "omega_z,radius", "--y", "theta_max,displacement_max"], ["summary", "--format", "csv"],
            ["report"]]


def measure(command, cwd):
    """Wall time (s) and peak resident memory (MiB) of one process."""
    start = time.perf_counter()
    with open(os.devnull, "w") as sink:
        process = subprocess.Popen(command, cwd=cwd, stdout=sink, stderr=subprocess.PIPE)
        _, status, usage = os.wait4(process.pid, 0)
    seconds = time.perf_counter() - start
    if os.waitstatus_to_exitcode(status) != 0:
        sys.exit(f"failed: {' '.join(command)}: {process.stderr.read().decode()}")
    return seconds, usage.ru_maxrss / 1024


def main():
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--exe", default=str(ROOT / "build" / "ellroll"))
    parser.add_argument("--cases", type=int, default=100000)
    parser.add_argument("--t-end", type=float, default=1.0)
    parser.add_argument("--keep", help="run in this folder and keep the file and figures")
    parser.add_argument("--quick", action="store_true", help="200 cases, three commands (a smoke test)")
    args = parser.parse_args()
    args.exe = executable(args.exe)
    commands = COMMANDS
    if quick(args.quick):
        args.cases = 200
        commands = [COMMANDS[1], COMMANDS[5], COMMANDS[7]]
    plot = shutil.which("ellroll-plot") or str(ROOT / ".venv" / "bin" / "ellroll-plot")
    folder = pathlib.Path(args.keep or tempfile.mkdtemp(prefix="ellroll-plots-"))
    folder.mkdir(parents=True, exist_ok=True)
    (folder / "campaign.nml").write_text(INPUT.format(n=args.cases, t_end=args.t_end))
    seconds, _ = measure([args.exe, "run", "campaign.nml", "-q", "--overwrite"], folder)
    size = (folder / "campaign.h5").stat().st_size / 2**30
    print(f"{args.cases} cases, file {size:.2f} GiB, written in {seconds:.1f} s")
    print(f"{'command':<62} {'time, s':>8} {'peak RSS, MiB':>14}")
    for command in commands:
        out = folder / "figures"
        seconds, rss = measure([plot, *command, "campaign.h5"]
                               + (["--out", str(out), "--overwrite"] if command[0] != "summary" else []), folder)
        print(f"{'ellroll-plot ' + ' '.join(command):<62} {seconds:8.2f} {rss:14.0f}")
    if not args.keep:
        shutil.rmtree(folder)


if __name__ == "__main__":
    main()
