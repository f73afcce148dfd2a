#!/usr/bin/env python3
"""What `&ball slip = 'slide'` costs a case that never slides: the same
cases with a mu that rolling never reaches (mu = 10, the friction needed
peaks at 0.17), run with slip = 'end' and with slip = 'slide', side by side
in one run, per case-step. The paper's cup and ball shaken harmonically (0.1
m/s^2 along x and y, 0.5 Hz), RK4 at dt = 1e-3, summary only, one thread:
  one case      1000 s (1,000,000 steps)
  spin sweep    32 spins omega_z = 5..36 rad/s over 60 s, in SIMD batches
                (a case that may slide rolls in its lane as with slip = 'end'
                and is run again alone only where it slips)
Every case must complete its t_end without sliding (exit 1 if not: the
figures per case-step would be of other work). The runs take turns
(--rounds times, best processor time of each). Printed:
ns per case-step and the ratio slide / end of each, then whether the
outputs are the same bits, every dataset but wall_time: one case (30 s,
every field) and the sweep (3 s, every field) must be (exit 1 if not).

    python bench/slide_cost.py --exe build/ellroll [--rounds 5] [--quick]

--quick (or ELLROLL_BENCH_QUICK=1): 3 s cases, one round (a smoke test).
"""
import argparse
import os
import pathlib
import resource
import subprocess
import sys
import tempfile

import h5py
import numpy as np

CASE = """&geometry a = 1.0, b = 0.4, c = 0.2 /
&ball radius = 0.2, weight = 2620.0, mu = 10.0, slip = '{slip}' /
&initial x = 0.05, y = 0.02, omega = -2.0, 2.0, 20.0 /
&integration method = 'rk4', dt = 1.0e-3, t_end = {t_end} /
&excitation kind = 'harmonic', amplitude = 0.1, 0.1, 0.0, frequency = 0.5 /
&output file = 'out.h5', interval = 0.01, fields = {fields} /
"""
SWEEP = "&sweep name = 'omega_z', values = " + ", ".join(str(5 + k) for k in range(32)) + " /\n"


def cpu_time(exe, namelist, folder, output):
    """The run's processor time (user + system)."""
    env = dict(os.environ, OMP_NUM_THREADS="1")
    before = resource.getrusage(resource.RUSAGE_CHILDREN)
    subprocess.run([str(exe), "run", str(namelist), "--threads", "1", "--overwrite", "-o", str(output)],
                   check=True, capture_output=True, env=env, cwd=folder)
    after = resource.getrusage(resource.RUSAGE_CHILDREN)
    return (after.ru_utime - before.ru_utime) + (after.ru_stime - before.ru_stime)


def check_rolled(exe, folder, stem):
    """Exit 1 unless every case of the run completed without sliding."""
    cpu_time(exe, folder / f"{stem}.nml", folder, folder / f"{stem}.h5")
    with h5py.File(folder / f"{stem}.h5", "r") as f:
        status, episodes = f["summary/status"][()], f["summary/slip_episodes"][()]
    if not (np.all(status == 1) and not np.any(episodes)):
        sys.exit(f"{stem}: a case did not roll to its t_end (status {sorted(set(status))}, slip episodes "
                 f"{int(np.sum(episodes))}): its cost per planned step says nothing")


def datasets(path):
    found = {}
    with h5py.File(path, "r") as f:
        f.visititems(lambda name, item: found.__setitem__(name, item[()]) if isinstance(item, h5py.Dataset) else None)
    return found


def differing(first, second):
    """The datasets of two files that are not the same bits (wall_time left
    out, and the /switches group of a file whose cases never switched: only a
    file with slip = 'slide' has it)."""
    a, b = datasets(first), datasets(second)
    names = sorted(set(a) | set(b))
    out = []
    for name in names:
        if name.endswith("wall_time"):
            continue
        if name.startswith("switches/") and not np.any(a.get("switches/count", b.get("switches/count"))):
            continue
        if name not in a or name not in b:
            out.append(name)
            continue
        x, y = np.asarray(a[name]), np.asarray(b[name])
        same = (x.shape == y.shape and x.dtype == y.dtype and
                (np.array_equal(x.view(np.uint8), y.view(np.uint8)) if x.dtype.kind in "fiu"
                 else np.array_equal(x, y)))
        if not same:
            out.append(name)
    return out


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--exe", required=True)
    parser.add_argument("--rounds", type=int, default=5)
    parser.add_argument("--quick", action="store_true", default=os.environ.get("ELLROLL_BENCH_QUICK") == "1")
    args = parser.parse_args()
    exe = pathlib.Path(args.exe).resolve()
    t_one, t_sweep = (3.0, 3.0) if args.quick else (1000.0, 60.0)
    rounds = 1 if args.quick else args.rounds
    runs = {"one case": ("", 1, round(t_one / 1e-3), t_one),
            "spin sweep, 32 cases": (SWEEP, 32, round(t_sweep / 1e-3), t_sweep)}
    best = {}
    with tempfile.TemporaryDirectory() as tmp:
        folder = pathlib.Path(tmp)
        for name, (extra, _, _, t_end) in runs.items():
            for slip in ("end", "slide"):
                stem = f"{name.split(',')[0].replace(' ', '_')}_{slip}"
                (folder / f"{stem}.nml").write_text(CASE.format(slip=slip, t_end=t_end, fields="'none'") + extra)
                best[name, slip] = float("inf")
        for name in runs:
            for slip in ("end", "slide"):
                stem = f"{name.split(',')[0].replace(' ', '_')}_{slip}"
                check_rolled(exe, folder, stem)
        for _ in range(rounds):
            for name in runs:
                for slip in ("end", "slide"):
                    stem = f"{name.split(',')[0].replace(' ', '_')}_{slip}"
                    best[name, slip] = min(best[name, slip],
                                           cpu_time(exe, folder / f"{stem}.nml", folder, folder / f"{stem}.h5"))
        print(f"A case that never slides (mu = 10), slip = 'end' and 'slide' (RK4 at dt = 1e-3, harmonic cup, "
              f"summary only, one thread): ns per case-step, process CPU time, best of {rounds} rounds")
        print(f"{'campaign':>22} {'cases':>6} {'end':>9} {'slide':>9}  slide / end")
        for name, (_, cases, steps, _) in runs.items():
            end, slide = (1e9 * best[name, s] / (cases * steps) for s in ("end", "slide"))
            print(f"{name:>22} {cases:6d} {end:9.1f} {slide:9.1f}  {slide / end:10.2f}x")
        outputs = {}
        for label, extra, t_end in (("one", "", 3.0 if args.quick else 30.0), ("sweep", SWEEP, 3.0)):
            for slip in ("end", "slide"):
                (folder / f"bits_{label}_{slip}.nml").write_text(
                    CASE.format(slip=slip, t_end=t_end, fields="'all'") + extra)
                cpu_time(exe, folder / f"bits_{label}_{slip}.nml", folder, folder / f"bits_{label}_{slip}.h5")
                outputs[label, slip] = folder / f"bits_{label}_{slip}.h5"
        different = False
        for label, what in (("one", "one case"), ("sweep", "spin sweep, 3 s")):
            names = differing(outputs[label, "end"], outputs[label, "slide"])
            print(f"{what}, every field: " + ("the same bits" if not names else "DIFFERENT: " + ", ".join(names)))
            different = different or bool(names)
    if different:
        sys.exit(1)


if __name__ == "__main__":
    main()
