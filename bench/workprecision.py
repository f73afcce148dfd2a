#!/usr/bin/env python3
"""Work-precision of the paper's case (30 s): achieved error of the contact
point (max over the output times, every 0.1 s) against wall time and RHS
evaluations, for every ellroll method and for SciPy's solve_ivp DOP853 on
the NumPy implementation of the same equations (bench/ball_numpy.py).

The reference is ellroll's dop853 at rtol 1e-13, checked against gauss4 at
dt = 2.5e-5 s (a second method). Wall times are warm and best-of: SciPy's
the best of three calls in one Python process; ellroll's the best of the
integration times it records itself (/summary/wall_time) for the same case
run seven times in one file (a sweep over one repeated value), in three
processes (its runs are short, and a burst of the host's other load can
cover all seven in one), so neither side pays for a cold start (ellroll's first case in a process takes about
0.2 ms more: page faults and first calls into the libraries). Seven cases
are below the batch size: these are one-case figures. "rk4 batch",
"dop853 batch" and "vern9 batch" are the method in a campaign of 16 copies
of the case (SIMD batches of 8), per case: the cost of one case when many
are run. (bench/pairs.py sets vern9 against dop853 on 16 different cases.)

    .venv/bin/python bench/workprecision.py [--exe build/ellroll] [--out DIR] [--quick]
writes a table on stdout, workprecision.png and workprecision.csv in --out
(default: the current folder). The figure and CSV of docs/accuracy.md are
docs/workprecision.*: bench/report.py puts them there (by hand: --out docs).
--quick (or ELLROLL_BENCH_QUICK=1): a few points, one process each (a smoke
test).
"""
import argparse
import os
import pathlib
import subprocess
import sys
import tempfile
import time

import h5py
import numpy as np

sys.path.insert(0, str(pathlib.Path(__file__).resolve().parent))
from ball_numpy import RollingBall  # noqa: E402
from common import executable, quick  # noqa: E402

ROOT = pathlib.Path(__file__).resolve().parents[1]
T_END, INTERVAL = 30.0, 0.1
CASE = """&geometry a = 1.0, b = 0.4, c = 0.2 /
&ball radius = 0.2, weight = 2620.0 /
&initial x = 0.0, y = 0.0, omega = -2.0, 2.0, 20.0 /
&integration {integration}, t_end = 30.0 /
&output file = 'wp.h5', interval = 0.1, fields = 'contact' /
&sweep name = 'omega_z', values = {repeats}*20.0 /
"""


def ellroll_run(exe, folder, integration, repeats=7, rounds=3):
    """(contact (nt, 3), best integration seconds, RHS evaluations): the best
    of repeats x rounds, rounds processes of repeats cases each."""
    (folder / "wp.nml").write_text(CASE.format(integration=integration, repeats=repeats))
    best = np.inf
    for _ in range(rounds):
        subprocess.run([str(exe), "run", "wp.nml", "-q", "--overwrite", "--threads", "1"], cwd=folder, check=True,
                       stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
        with h5py.File(folder / "wp.h5", "r") as f:
            contact = f["trajectory/contact"][0]
            assert np.array_equal(f["trajectory/contact"][-1], contact)
            best = min(best, float(np.min(f["summary/wall_time"][:])))
            n_rhs = int(f["summary/n_rhs"][0])
    return contact, best, n_rhs


def scipy_run(rtol, repeats=3):
    from scipy.integrate import solve_ivp
    ball = RollingBall(1.0, 0.4, 0.2, 0.2)
    y0 = ball.initial_state(0.0, 0.0, np.array([-2.0, 2.0, 20.0]))
    times = np.linspace(0, T_END, int(round(T_END / INTERVAL)) + 1)
    best = np.inf
    for _ in range(repeats):
        start = time.perf_counter()
        sol = solve_ivp(ball.rhs, (0, T_END), y0, method="DOP853", rtol=rtol, atol=rtol * 1e-3, t_eval=times)
        best = min(best, time.perf_counter() - start)
    return ball.contact(sol.y).T, best, sol.nfev


def scipy_endpoint(rtol):
    """SciPy's DOP853 state at T_END (contact point) and its RHS evaluations, no dense output."""
    from scipy.integrate import solve_ivp
    ball = RollingBall(1.0, 0.4, 0.2, 0.2)
    y0 = ball.initial_state(0.0, 0.0, np.array([-2.0, 2.0, 20.0]))
    sol = solve_ivp(ball.rhs, (0, T_END), y0, method="DOP853", rtol=rtol, atol=rtol * 1e-3)
    return ball.contact(sol.y[:, -1:]).T[-1], sol.nfev


def calls_at(level, points):
    """A cost (RHS evaluations, seconds) at an error level, log-log interpolated between (error, cost) points."""
    errors, calls = np.array(points).T
    order = np.argsort(errors)
    return float(np.exp(np.interp(np.log(level), np.log(errors[order]), np.log(calls[order]))))


def error(contact, reference):
    return float(np.max(np.linalg.norm(contact - reference, axis=1)))


def main():
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--exe", default=str(ROOT / "build" / "ellroll"))
    parser.add_argument("--out", default=".", help="folder of workprecision.png and .csv (default: current)")
    parser.add_argument("--quick", action="store_true", help="fewer points (for a smoke test)")
    args = parser.parse_args()
    args.exe = executable(args.exe)
    args.quick = quick(args.quick)
    rounds = 1 if args.quick else 3
    out = pathlib.Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    rows = []
    with tempfile.TemporaryDirectory() as tmp:
        folder = pathlib.Path(tmp)
        reference, _, _ = ellroll_run(args.exe, folder, "method = 'dop853', rtol = 1e-13, atol = 1e-15", 1, 1)
        check_dt = 1e-4 if args.quick else 2.5e-5
        check, _, _ = ellroll_run(args.exe, folder, f"method = 'gauss4', dt = {check_dt!r}", 1, 1)
        print(f"reference: dop853 rtol 1e-13; gauss4 dt {check_dt:g} differs by {error(check, reference):.1e} m")
        rk4_steps = [1e-1, 5e-2, 2e-2, 1e-2, 5e-3, 2e-3, 1e-3, 5e-4, 2e-4, 1e-4]
        gauss_steps = [5e-2, 2e-2, 1e-2, 5e-3, 2e-3, 1e-3, 5e-4]
        # rtol from 1e-2 to 1e-12, four a decade: in the stability-limited
        # range (errors above 1e-5 m) the error is not monotone in rtol, and
        # on a coarse grid the cheapest run reaching a level would be a
        # matter of where the grid falls (SciPy gets the same grid)
        tolerances = [10.0**(-k / 4) for k in range(8, 49)]
        if args.quick:
            rk4_steps, gauss_steps, tolerances = rk4_steps[3:6], gauss_steps[2:4], tolerances[12:17:2]
        for dt in rk4_steps:
            rows.append(("ellroll rk4", f"dt={dt:g}",
                         *ellroll_run(args.exe, folder, f"method = 'rk4', dt = {dt!r}", rounds=rounds)))
        for dt in rk4_steps:
            rows.append(("ellroll rk4 batch", f"dt={dt:g}",
                         *ellroll_run(args.exe, folder, f"method = 'rk4', dt = {dt!r}", repeats=16, rounds=rounds)))
        for dt in gauss_steps:
            rows.append(("ellroll gauss4", f"dt={dt:g}",
                         *ellroll_run(args.exe, folder, f"method = 'gauss4', dt = {dt!r}", rounds=rounds)))
        for pair in ("dop853", "vern9"):
            for rtol in tolerances:
                rows.append((f"ellroll {pair}", f"rtol={rtol:.3g}", *ellroll_run(
                    args.exe, folder, f"method = '{pair}', rtol = {rtol!r}, atol = {rtol * 1e-3!r}", rounds=rounds)))
            for rtol in tolerances:
                rows.append((f"ellroll {pair} batch", f"rtol={rtol:.3g}", *ellroll_run(
                    args.exe, folder, f"method = '{pair}', rtol = {rtol!r}, atol = {rtol * 1e-3!r}", repeats=16,
                    rounds=rounds)))
        for rtol in tolerances:
            rows.append(("scipy DOP853", f"rtol={rtol:.3g}", *scipy_run(rtol, repeats=rounds)))

    table = [(name, setting, error(contact, reference), seconds, n_rhs) for name, setting, contact, seconds, n_rhs in rows]
    print(f"{'method':18} {'setting':12} {'error m':>10} {'time s':>10} {'RHS evals':>10}")
    for name, setting, err, seconds, n_rhs in table:
        print(f"{name:18} {setting:12} {err:10.2e} {seconds:10.2e} {n_rhs:10d}")
    with open(out / "workprecision.csv", "w") as csv:
        csv.write("method,setting,error_m,time_s,rhs_evaluations\n")
        for row in table:
            csv.write(",".join(map(str, row)) + "\n")

    # speed at each error level: the cheapest run reaching it, per family
    def cheapest(family, level, column):
        costs = [row[column] for row in table if row[0] == family and row[2] <= level]
        return min(costs) if costs else np.nan
    print("\none case: the fastest ellroll method against SciPy; in a campaign: RK4, DOP853 and vern9 in")
    print("batches, per case, and the speed-up of the fastest")
    print(f"{'error level':>11} {'best ellroll':>14} {'time s':>10} {'scipy s':>10} {'speed-up':>9} "
          f"{'rk4 s':>9} {'dop853 s':>9} {'vern9 s':>9} {'rk4 batch':>9} {'853 batch':>9} {'v9 batch':>9} "
          f"{'campaign':>9}")
    for level in [1e-3, 1e-4, 1e-5, 1e-6, 1e-7, 1e-8, 1e-9, 1e-10, 1e-11]:
        ours = {f: cheapest(f, level, 3) for f in ("ellroll rk4", "ellroll gauss4", "ellroll dop853", "ellroll vern9")}
        if all(np.isnan(list(ours.values()))):
            continue    # no run reached this level (--quick)
        best_family = min(ours, key=lambda f: np.inf if np.isnan(ours[f]) else ours[f])
        peer = cheapest("scipy DOP853", level, 3)
        batches = [cheapest(f"ellroll {m} batch", level, 3) for m in ("rk4", "dop853", "vern9")]
        in_campaign = np.nanmin([*batches, ours[best_family]])
        print(f"{level:11.0e} {best_family[8:]:>14} {ours[best_family]:10.2e} {peer:10.2e} "
              f"{peer / ours[best_family]:9.0f} {ours['ellroll rk4']:9.2e} {ours['ellroll dop853']:9.2e} "
              f"{ours['ellroll vern9']:9.2e} {batches[0]:9.2e} {batches[1]:9.2e} {batches[2]:9.2e} "
              f"{peer / in_campaign:9.0f}")
    # endpoint efficiency: output at t_end only, so every RHS call integrates;
    # beside it SciPy's DOP853 on the same equations (no dense output): what
    # the method itself needs on this problem
    endpoint = []
    with tempfile.TemporaryDirectory() as tmp:
        folder = pathlib.Path(tmp)
        global CASE
        CASE = CASE.replace("interval = 0.1", "interval = 30.0")
        reference_end = ellroll_run(args.exe, folder, "method = 'dop853', rtol = 1e-13, atol = 1e-15", 1, 1)[0][-1]
        for rtol in [10.0**(-k / 2) for k in (range(10, 21, 4) if args.quick else range(10, 21))]:
            contact, _, n_rhs = ellroll_run(args.exe, folder,
                                            f"method = 'dop853', rtol = {rtol!r}, atol = {rtol * 1e-3!r}", 1, 1)
            peer_end, peer_rhs = scipy_endpoint(rtol)
            endpoint.append((rtol, float(np.linalg.norm(contact[-1] - reference_end)), n_rhs,
                             float(np.linalg.norm(peer_end - reference_end)), peer_rhs))
    print("\ndop853, endpoint error of the contact point at 30 s (output at the end only), ellroll and SciPy:")
    for rtol, err, n_rhs, peer_err, peer_rhs in endpoint:
        print(f"  rtol {rtol:8.1e}: ellroll {err:9.2e} m, {n_rhs:6d} RHS; SciPy {peer_err:9.2e} m, {peer_rhs:6d} RHS")
    ours = calls_at(3e-8, [(e, n) for _, e, n, _, _ in endpoint])
    peer = calls_at(3e-8, [(e, n) for _, _, _, e, n in endpoint])
    print(f"  at 3e-8: ellroll {ours:.0f} RHS evaluations (Theta's maxima included), SciPy's DOP853 {peer:.0f} "
          "(DOP853's published efficiency: about 3,900)")

    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    fig, axes = plt.subplots(1, 2, figsize=(11, 4.5), layout="constrained")
    for family, marker in [("ellroll rk4", "o"), ("ellroll rk4 batch", "v"), ("ellroll gauss4", "s"),
                           ("ellroll dop853", "^"), ("ellroll dop853 batch", "<"), ("ellroll vern9", "D"),
                           ("ellroll vern9 batch", "d"), ("scipy DOP853", "x")]:
        points = np.array([(r[2], r[3], r[4]) for r in table if r[0] == family])
        for ax, column in zip(axes, (1, 2)):
            ax.loglog(points[:, column], points[:, 0], marker=marker, label=family)
    axes[0].set_xlabel("wall time, s")
    axes[1].set_xlabel("right-hand side evaluations")
    for ax in axes:
        ax.set_ylabel("max error of the contact point, m")
        ax.grid(True, which="both", alpha=0.3)
        ax.legend()
    fig.suptitle("Work-precision, Legeza (1990) case, 30 s")
    fig.savefig(out / "workprecision.png", dpi=120)
    shown = pathlib.Path(os.path.relpath(out))
    print(f"wrote {shown / 'workprecision.png'} and {shown / 'workprecision.csv'}", file=sys.stderr)


if __name__ == "__main__":
    main()
