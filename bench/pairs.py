#!/usr/bin/env python3
"""vern9 against dop853, side by side in one run: a work-precision table at
rtol 1e-6 to 1e-13 (atol = rtol / 100), for one case and for batches, with
the RHS evaluations, the integration time and the endpoint error; then the
tight-tolerance check of the two pairs at rtol 1e-12, atol 1e-14.

The cases: the paper's cup and ball (Legeza 1990), 16 spins omega_z = 5 to
50 rad/s, 30 s each, output at the end only (every RHS call integrates;
the maxima of Theta are still located on the dense output). "batch" runs the
16 as one campaign (two SIMD batches of 8, the time per case their share);
"one case" runs a campaign of 7 copies of one spin (below the batch size,
so each case runs alone), for each of the 16 spins. Times are the integration
times each case records (/summary/wall_time), one thread, best of --repeat
runs, the two pairs alternating so that the host's load falls on both.

The endpoint error is the largest distance, over the 16 cases, of the
contact point at 30 s from dop853 at rtol 1e-14, atol 1e-16; beside it,
vern9 at that tolerance against the same reference: how far the reference
itself can be trusted.

    .venv/bin/python bench/pairs.py [--exe build/ellroll] [--repeat 5] [--quick]

--quick (or ELLROLL_BENCH_QUICK=1): rtol 1e-6, 1e-8 and 1e-12, one round (a
smoke test).
"""
import argparse
import pathlib
import subprocess
import sys
import tempfile

import h5py
import numpy as np

sys.path.insert(0, str(pathlib.Path(__file__).resolve().parent))
from common import executable, quick  # noqa: E402
from workprecision import calls_at  # noqa: E402

ROOT = pathlib.Path(__file__).resolve().parents[1]
SPINS = [5.0 + 3.0 * k for k in range(16)]
CAMPAIGN = """&geometry a = 1.0, b = 0.4, c = 0.2 /
&ball radius = 0.2, weight = 2620.0 /
&initial x = 0.0, y = 0.0, omega = -2.0, 2.0, 20.0 /
&integration method = '{method}', rtol = {rtol!r}, atol = {atol!r}, t_end = 30.0 /
&output file = 'pairs.h5', interval = 30.0, fields = 'contact' /
&sweep name = 'omega_z', values = {values} /
"""
PAIRS = ("dop853", "vern9")


def run(exe, folder, method, rtol, atol, values):
    """(contact at 30 s per case, integration seconds per case, RHS evaluations per case)."""
    text = CAMPAIGN.format(method=method, rtol=rtol, atol=atol, values=", ".join(map(repr, values)))
    (folder / "pairs.nml").write_text(text)
    subprocess.run([exe, "run", "pairs.nml", "-q", "--overwrite", "--threads", "1"], cwd=folder, check=True,
                   stdout=subprocess.DEVNULL)
    with h5py.File(folder / "pairs.h5", "r") as f:
        assert all(f["summary/status"][:] == 1), "a case did not complete"
        return f["trajectory/contact"][:, -1, :], f["summary/wall_time"][:], f["summary/n_rhs"][:]


def measure(exe, folder, rtol, atol, repeat, batch):
    """Per pair: (endpoint contact of the 16 cases, best time per case, RHS per case), both pairs
    measured in alternation."""
    best = {m: None for m in PAIRS}
    for _ in range(repeat):
        for method in PAIRS:
            if batch:
                contact, seconds, n_rhs = run(exe, folder, method, rtol, atol, SPINS)
            else:
                rows = [run(exe, folder, method, rtol, atol, [spin] * 7) for spin in SPINS]
                contact = np.array([r[0][0] for r in rows])
                seconds = np.array([np.min(r[1]) for r in rows])
                n_rhs = np.array([r[2][0] for r in rows])
            if best[method] is None:
                best[method] = (contact, seconds, n_rhs)
            else:
                best[method] = (contact, np.minimum(best[method][1], seconds), n_rhs)
    return best


def main():
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--exe", default=str(ROOT / "build" / "ellroll"))
    parser.add_argument("--repeat", type=int, default=5)
    parser.add_argument("--quick", action="store_true", help="fewer tolerances, one round (a smoke test)")
    args = parser.parse_args()
    args.exe = executable(args.exe)
    args.quick = quick(args.quick)
    tolerances = [1e-6, 1e-8, 1e-12] if args.quick else [10.0**-k for k in range(6, 14)]
    repeat = 1 if args.quick else args.repeat
    with tempfile.TemporaryDirectory() as tmp:
        folder = pathlib.Path(tmp)
        reference = run(args.exe, folder, "dop853", 1e-14, 1e-16, SPINS)[0]
        check = run(args.exe, folder, "vern9", 1e-14, 1e-16, SPINS)[0]
        print("reference: dop853 rtol 1e-14, atol 1e-16; vern9 at that tolerance differs from it by "
              f"{np.linalg.norm(check - reference, axis=1).max():.1e} m")
        print("per case: RHS evaluations, integration time (best of the runs), endpoint error (max over 16 cases)")
        print(f"{'path':8} {'rtol':>7} | {'dop853 RHS':>10} {'time s':>9} {'error m':>9} | "
              f"{'vern9 RHS':>10} {'time s':>9} {'error m':>9} | {'RHS ratio':>9} {'time ratio':>10}")
        results = {}
        for batch in (False, True):
            for rtol in tolerances:
                best = measure(args.exe, folder, rtol, rtol / 100, repeat, batch)
                row = {}
                for method in PAIRS:
                    contact, seconds, n_rhs = best[method]
                    row[method] = (float(np.mean(n_rhs)), float(np.sum(seconds)) / len(SPINS),
                                   float(np.linalg.norm(contact - reference, axis=1).max()))
                results[batch, rtol] = row
                d, v = row["dop853"], row["vern9"]
                print(f"{'batch' if batch else 'one case':8} {rtol:7.0e} | {d[0]:10.0f} {d[1]:9.2e} {d[2]:9.2e} | "
                      f"{v[0]:10.0f} {v[1]:9.2e} {v[2]:9.2e} | {d[0] / v[0]:9.2f} {d[1] / v[1]:10.2f}")
    print("\nat rtol 1e-12, atol 1e-14 (the 16 cases over 30 s): vern9 against dop853 at the same tolerance,")
    print("and at the same endpoint error (vern9's cost interpolated, log-log, at dop853's error)")
    for batch in (False, True):
        d, v = results[batch, 1e-12]["dop853"], results[batch, 1e-12]["vern9"]
        points = [results[batch, rtol]["vern9"] for rtol in tolerances]
        v_rhs, v_time = (calls_at(d[2], [(p[2], p[column]) for p in points]) for column in (0, 1))
        print(f"  {'batch' if batch else 'one case':8}: endpoint error {v[2]:.2e} m against {d[2]:.2e} m "
              f"({'at most' if v[2] <= d[2] else 'ABOVE'} dop853's); the same tolerance: {d[1] / v[1]:.2f}x faster, "
              f"{d[0] / v[0]:.2f}x fewer RHS evaluations; the same error: {d[1] / v_time:.2f}x faster, "
              f"{d[0] / v_rhs:.2f}x fewer")


if __name__ == "__main__":
    main()
