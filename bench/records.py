#!/usr/bin/env python3
"""Reading ground-motion records: ellroll's reader beside numpy's, per value.

Writes --files PEER .AT2 files of --values accelerations each (E15.7 fields,
five to a line, as PEER writes them) and one CSV of as many values (time and
three components, 17 significant digits as Python's repr writes them), then
takes the best of --repeat runs of
  ellroll   build/bench_record_read: load_ground_motion in-process, as
            `ellroll check` and `run` read records (checks, units, the grid)
  numpy     numpy.loadtxt of the same files (an AT2 file's values after its
            four header lines)
in processor time (user + system: on a machine shared with other work, wall
time measures the others too; the wall times are printed beside), and
`ellroll check` of the AT2 files as a suite of records against the same
check of a fixed cup: the reading as the command line sees it.

    python bench/records.py [--bench build/bench_record_read] [--exe build/ellroll]
                            [--files 10] [--values 200000] [--repeat 5]
"""
import argparse
import pathlib
import resource
import subprocess
import tempfile
import time

import numpy as np

ROOT = pathlib.Path(__file__).resolve().parents[1]
CUP = """&geometry a = 1.0, b = 0.4, c = 0.2 /
&ball radius = 0.2, weight = 2620.0 /
&initial omega = 0.0, 0.0, 0.0 /
&integration method = 'rk4', dt = 1.0e-3, t_end = 10.0 /
&output file = 'suite.h5', interval = 0.01 /
"""


def write_files(folder, n_files, n_values):
    """The AT2 files and the CSV; their paths."""
    rng = np.random.default_rng(1990)
    at2 = []
    for k in range(n_files):
        acc = 0.05 * rng.standard_normal(n_values)
        fields = [f"{v:15.7E}" for v in acc]
        lines = ["PEER NGA STRONG MOTION DATABASE RECORD", f"SYNTHETIC RECORD {k} FOR bench/records.py",
                 "ACCELERATION TIME SERIES IN UNITS OF G", f"NPTS={n_values:8d}, DT=   .0050 SEC"]
        lines += ["".join(fields[i:i + 5]) for i in range(0, n_values, 5)]
        path = folder / f"S{k}.AT2"
        path.write_text("\n".join(lines) + "\n")
        at2.append(path)
    rows = n_values // 4
    t = (np.arange(rows) * 0.005).tolist()
    a = (0.5 * rng.standard_normal((rows, 3))).tolist()
    csv = folder / "record.csv"
    csv.write_text("time, ax, ay, az\n" + "".join(f"{t[k]!r}, {a[k][0]!r}, {a[k][1]!r}, {a[k][2]!r}\n"
                                                  for k in range(rows)))
    return at2, csv, rows * 4


def children_cpu():
    usage = resource.getrusage(resource.RUSAGE_CHILDREN)
    return usage.ru_utime + usage.ru_stime


def ellroll_read(bench, paths, repeat):
    """(processor s, wall s) of the in-process reader, best of repeat."""
    out = subprocess.run([str(bench), str(repeat), *map(str, paths)], check=True, capture_output=True, text=True)
    cpu, wall = out.stdout.split()[:2]
    return float(cpu), float(wall)


def numpy_read(paths, skip, repeat, **options):
    best_cpu, best_wall = float("inf"), float("inf")
    for _ in range(repeat):
        cpu, wall = time.process_time(), time.perf_counter()
        for path in paths:
            np.loadtxt(path, skiprows=skip, **options)
        best_cpu = min(best_cpu, time.process_time() - cpu)
        best_wall = min(best_wall, time.perf_counter() - wall)
    return best_cpu, best_wall


def check_time(exe, folder, name, repeat):
    """(processor s, wall s) of `ellroll check name`, best of repeat."""
    best_cpu, best_wall = float("inf"), float("inf")
    for _ in range(repeat):
        cpu, wall = children_cpu(), time.perf_counter()
        subprocess.run([str(exe), "check", name], cwd=folder, check=True, capture_output=True)
        best_cpu = min(best_cpu, children_cpu() - cpu)
        best_wall = min(best_wall, time.perf_counter() - wall)
    return best_cpu, best_wall


def main():
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--bench", default=str(ROOT / "build" / "bench_record_read"))
    parser.add_argument("--exe", default=str(ROOT / "build" / "ellroll"))
    parser.add_argument("--files", type=int, default=10)
    parser.add_argument("--values", type=int, default=200000, help="values per AT2 file (a multiple of 5)")
    parser.add_argument("--repeat", type=int, default=5)
    args = parser.parse_args()
    values = args.values - args.values % 5
    with tempfile.TemporaryDirectory() as tmp:
        folder = pathlib.Path(tmp)
        at2, csv, csv_values = write_files(folder, args.files, values)
        at2_values = args.files * values
        print(f"reading records, best of {args.repeat} ({time.strftime('%Y-%m-%d')}): ns per value, "
              "processor time (wall)")
        print(f"{'files':<28} {'values':>9} {'ellroll':>16} {'numpy.loadtxt':>16} {'numpy / ellroll':>16}")
        for label, paths, n, skip, options in (
                (f"{args.files} AT2, E15.7, 5 a line", at2, at2_values, 4, {}),
                ("1 CSV, 4 columns, repr", [csv], csv_values, 1, {"delimiter": ","})):
            ours = ellroll_read(args.bench, paths, args.repeat)
            theirs = numpy_read(paths, skip, args.repeat, **options)
            per = [1e9 * s / n for s in ours + theirs]
            print(f"{label:<28} {n:>9} {per[0]:>7.0f} ({per[1]:>6.0f}) {per[2]:>7.0f} ({per[3]:>6.0f}) "
                  f"{theirs[0] / ours[0]:>16.2f}")
        records = "".join(f"&record name = 'R{k}', record_file = '{p.name}' /\n" for k, p in enumerate(at2))
        (folder / "suite.nml").write_text(CUP + "&excitation kind = 'record' /\n" + records)
        (folder / "fixed.nml").write_text(CUP)
        suite = check_time(args.exe, folder, "suite.nml", args.repeat)
        fixed = check_time(args.exe, folder, "fixed.nml", args.repeat)
        print(f"ellroll check of the {args.files} AT2 files as a suite: {suite[0]:.3f} s processor "
              f"({suite[1]:.3f} s wall); of a fixed cup {fixed[0]:.3f} s ({fixed[1]:.3f} s): "
              f"{1e9 * (suite[0] - fixed[0]) / at2_values:.0f} ns per value")


if __name__ == "__main__":
    main()
