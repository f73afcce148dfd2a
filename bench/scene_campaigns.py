#!/usr/bin/env python3
"""What a scene and the summary cost (the ratios of issue #44), for each build
given, side by side in one run: the kernels' paths (bench_throughput), one
case's scenes (bench_scene_cost) and harmonic and record campaigns against the
same campaign on a fixed cup, per case-step.

From bench_throughput and bench_scene_cost beside each ellroll (the same build
folder), each ratio from one run of the binary (its two paths measured
moments apart), the median over --rounds runs:
  batch summary / integrate   a batch of 8 keeping the summary over integrating only
  one case summary / integrate
  batch of 1 / one case       a case alone in a batch over the one-case path (both
                              summary only)
  full output / summary       one case and a batch of 8
  record, uneven, harmonic, rolling resistance / fixed cup   one case each

Three campaigns of the paper's cup and ball, RK4 at dt = 1e-3, summary only
(fields = 'none'), one thread, in SIMD batches where the build batches them:
  spin sweep      32 spins omega_z = 5..36 rad/s over 60 s, on a fixed cup
  harmonic sweep  the same 32 cases, the cup shaken along x and y (0.3 m/s^2,
                  0.5 Hz)
  rolling-resistance sweep  the same 32 cases with rolling resistance 1e-3 m
                  (each lane its mode per step; rest events where the rolling
                  stops)
  record suite    the six synthetic records of input/records at scales 0.5,
                  1 and 1.5 ... (15 cases, 40 s) against the same 15 cases on
                  a fixed cup
Each build's runs take turns (--rounds times, best of each), so that every
build sees the same machine; a campaign is timed by its processor time.
Printed: the ratios above, ns per case-step of
each campaign and the ratios harmonic / fixed, rolling resistance / fixed and
record suite / fixed, per build.

    python bench/scene_campaigns.py --exe build/ellroll [--exe OTHER/ellroll ...] [--revision REV]
                                    [--revision-build DIR] [--rounds 3] [--quick]

--revision REV builds git revision REV's Release ellroll and benches in a
temporary worktree and puts it first (--revision-build DIR: REV's build folder,
already built). --quick (or ELLROLL_BENCH_QUICK=1): 2 s campaigns, one round,
no revision built (a smoke test).
"""
import argparse
import os
import pathlib
import re
import resource
import shutil
import statistics
import subprocess
import tempfile

ROOT = pathlib.Path(__file__).resolve().parents[1]
CUP = """&geometry a = 1.0, b = 0.4, c = 0.2 /
&ball radius = 0.2, weight = 2620.0 /
&initial x = 0.05, y = 0.02, omega = -2.0, 2.0, 20.0 /
&integration method = 'rk4', dt = 1.0e-3, t_end = {t_end} /
&output file = 'out.h5', interval = 0.01, fields = 'none' /
"""
SPINS = ", ".join(str(5 + k) for k in range(32))
RECORDS = ["SYN1_H1", "SYN1_H2", "SYN2_H1", "SYN2_H2", "SYN3_H1"]
SCALES = [0.5, 1.0, 1.5]


def campaigns(quick):
    """name: (namelist text, cases, steps per case)."""
    t_spin, t_suite = (2.0, 2.0) if quick else (60.0, 40.0)
    sweep = f"&sweep name = 'omega_z', values = {SPINS} /\n"
    harmonic = "&excitation kind = 'harmonic', amplitude = 0.3, 0.3, 0.0, frequency = 0.5 /\n"
    resisting = CUP.format(t_end=t_spin).replace("weight = 2620.0 /", "weight = 2620.0, rolling_resistance = 1.0e-3 /")
    records = "".join(f"&record name = '{r}', record_file = '{ROOT / 'input' / 'records' / (r + '.AT2')}' /\n"
                      for r in RECORDS)
    scales = "&sweep name = 'scale', values = " + ", ".join(map(str, SCALES)) + " /\n"
    suite_fixed = "&sweep name = 'omega_z', values = " + ", ".join(str(5 + k) for k in range(15)) + " /\n"
    n_spin, n_suite = round(t_spin / 1e-3), round(t_suite / 1e-3)
    return {
        "spin sweep, fixed cup": (CUP.format(t_end=t_spin) + sweep, 32, n_spin),
        "spin sweep, harmonic cup": (CUP.format(t_end=t_spin) + harmonic + sweep, 32, n_spin),
        "spin sweep, rolling resist.": (resisting + sweep, 32, n_spin),
        "15 cases, fixed cup": (CUP.format(t_end=t_suite) + suite_fixed, 15, n_suite),
        "record suite, 15 cases": (CUP.format(t_end=t_suite) + "&excitation kind = 'record' /\n" + records + scales,
                                   15, n_suite),
    }


def cpu_time(exe, namelist, folder):
    """The run's processor time (user + system): on a machine shared with other
    work, wall time measures the others too."""
    env = dict(os.environ, OMP_NUM_THREADS="1")
    before = resource.getrusage(resource.RUSAGE_CHILDREN)
    subprocess.run([str(exe), "run", str(namelist), "--threads", "1", "--overwrite", "-o", str(folder / "out.h5")],
                   check=True, capture_output=True, env=env, cwd=folder)
    after = resource.getrusage(resource.RUSAGE_CHILDREN)
    return (after.ru_utime - before.ru_utime) + (after.ru_stime - before.ru_stime)


ROW = re.compile(r"^\s*(\S.*?)\s+([0-9.]+)\.?\s+([0-9.]+)\s+([0-9.]+)x$")


def bench_rows(binary, repeats):
    """path: ns/step of a bench binary's table (bench_throughput, bench_scene_cost)."""
    out = subprocess.run([str(binary), str(repeats)], check=True, capture_output=True, text=True).stdout
    rows = {}
    for line in out.splitlines():
        m = ROW.match(line)
        if m:
            rows[m.group(1)] = float(m.group(3))
        else:
            m = re.match(r"^(\S.*?)\s+([0-9.]+)\s+([0-9.]+)x$", line)      # bench_scene_cost: name, ns, ratio
            if m:
                rows[m.group(1)] = float(m.group(2))
    return rows


KERNEL_RATIOS = [
    ("batch summary / integrate", "batch of 8, summary only", "batch of 8, integrate only", "<= 1.3x"),
    ("one case summary / integrate", "ellroll, summary only", "ellroll, integrate only", "<= 1.2x"),
    ("batch of 1 / one case", "batch of 1, summary only", "ellroll, summary only", "<= 1.0x"),
    ("one case full / summary", "ellroll, full output 100 Hz", "ellroll, summary only", ""),
    ("batch full / summary", "batch of 8, full output", "batch of 8, summary only", ""),
    ("record / fixed cup", "record", "fixed cup", "<= 1.1x"),
    ("record, uneven / fixed cup", "record, uneven times", "fixed cup", "<= 1.1x"),
    ("harmonic / fixed cup", "harmonic", "fixed cup", "<= 1.1x"),
    ("rolling resistance / fixed", "rolling resistance", "fixed cup", "<= 1.1x"),
]


def build_revision(revision, workdir):
    """REV's Release build of ellroll and the benches, in a worktree under workdir."""
    tree = workdir / "tree"
    subprocess.run(["git", "-C", str(ROOT), "worktree", "add", "--detach", str(tree), revision],
                   check=True, capture_output=True)
    subprocess.run(["cmake", "-S", str(tree), "-B", str(tree / "build"), "-DCMAKE_BUILD_TYPE=Release"],
                   check=True, capture_output=True)
    subprocess.run(["cmake", "--build", str(tree / "build"), "-j2", "--target", "ellroll", "bench_throughput",
                    "bench_scene_cost"], check=True, capture_output=True)
    return tree


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--exe", action="append", required=True, help="an ellroll binary (repeat to compare)")
    parser.add_argument("--revision", help="a git revision to build and compare with")
    parser.add_argument("--revision-build", help="that revision's build folder, already built")
    parser.add_argument("--rounds", type=int, default=3)
    parser.add_argument("--quick", action="store_true", default=os.environ.get("ELLROLL_BENCH_QUICK") == "1")
    args = parser.parse_args()
    args.exe = [str(pathlib.Path(exe).resolve()) for exe in args.exe]     # (the runs' folder is a temporary one)
    workdir = pathlib.Path(tempfile.mkdtemp())
    tree = None
    labels = {exe: "this tree" if pathlib.Path(exe).resolve().is_relative_to(ROOT)
              else pathlib.Path(exe).resolve().parent.parent.name[:14] for exe in args.exe}
    try:
        if args.revision and not args.quick:
            if args.revision_build:
                build = pathlib.Path(args.revision_build)
            else:
                tree = build_revision(args.revision, workdir)
                build = tree / "build"
            args.exe.insert(0, str(build / "ellroll"))
            labels[args.exe[0]] = args.revision[:14]
        measure(args, labels)
    finally:
        if tree is not None:
            subprocess.run(["git", "-C", str(ROOT), "worktree", "remove", "--force", str(tree)], capture_output=True)
        shutil.rmtree(workdir, ignore_errors=True)


def measure(args, labels):
    runs = campaigns(args.quick)
    best = {(exe, name): float("inf") for exe in args.exe for name in runs}
    kernels = {exe: [] for exe in args.exe}
    repeats = 1 if args.quick else 5
    with tempfile.TemporaryDirectory() as tmp:
        folder = pathlib.Path(tmp)
        for name, (text, _, _) in runs.items():
            (folder / (name.replace(" ", "_").replace(",", "") + ".nml")).write_text(text)
        for _ in range(1 if args.quick else args.rounds):
            for exe in args.exe:
                rows = {}
                for binary in ("bench_throughput", "bench_scene_cost"):
                    rows.update(bench_rows(pathlib.Path(exe).parent / binary, repeats))
                kernels[exe].append(rows)
                for name in runs:
                    namelist = folder / (name.replace(" ", "_").replace(",", "") + ".nml")
                    best[exe, name] = min(best[exe, name], cpu_time(exe, namelist, folder))
    rounds = 1 if args.quick else args.rounds
    builds = ", ".join(f"build {k + 1}: {labels[e]}" for k, e in enumerate(args.exe))
    names = " ".join(f"{'build ' + str(k + 1):>14}" for k in range(len(args.exe)))
    print(f"Kernels (bench_throughput, bench_scene_cost: RK4, 30 s at dt = 1e-3), median of {rounds} rounds; {builds}")
    print(f"{'ratio of ns/step':>33} " + names + "   target")
    for label, top, bottom, target in KERNEL_RATIOS:
        print(f"{label:>33} " + " ".join(f"{statistics.median(r[top] / r[bottom] for r in kernels[e]):13.2f}x"
                                         for e in args.exe)
              + f"   {target}")
    print(f"Campaigns (RK4 at dt = 1e-3, summary only, one thread): ns per case-step, process CPU time, best of "
          f"{rounds} rounds")
    print(f"{'campaign':>26} {'cases':>6} " + names)
    for name, (_, cases, steps) in runs.items():
        print(f"{name:>26} {cases:6d} " + " ".join(f"{1e9 * best[e, name] / (cases * steps):14.1f}" for e in args.exe))
    for label, moving, fixed in [("harmonic / fixed cup", "spin sweep, harmonic cup", "spin sweep, fixed cup"),
                                 ("rolling resist. / fixed cup", "spin sweep, rolling resist.", "spin sweep, fixed cup"),
                                 ("record suite / fixed cup", "record suite, 15 cases", "15 cases, fixed cup")]:
        ratios = [best[e, moving] / runs[moving][1] / runs[moving][2] / (best[e, fixed] / runs[fixed][1] / runs[fixed][2])
                  for e in args.exe]
        print(f"{label:>26} {'':6} " + " ".join(f"{r:13.2f}x" for r in ratios) + "   (target <= 1.3x)")


if __name__ == "__main__":
    main()
