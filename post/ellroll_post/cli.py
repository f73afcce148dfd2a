"""ellroll-plot: figures, reports and summaries of ellroll HDF5 files."""
import argparse
import csv
import errno
import functools
import io
import math
import os
import pathlib
import signal
import sys
import warnings

import numpy as np

from .reader import NotAnEllrollFile, damaged, from_h5py, not_regular, open as open_run
from . import plots
from .report import REPORT_ROWS, LeftBehind, build_report
from .safe_write import (Interrupted, OutputExists, check_target, forget_stop_requests, output_folder, request_stop,
                         save_figure, write_text)
from .summary import format_summary
from .suite import MODEL_LIMIT_STATE, NoIntensityMeasure, NoStripes, PartOfTheCampaign, check_limit_state, \
    format_fragility, format_suite, suite_statistics

FILE_STEMS = {"trace": "fig2_trace", "nutation": "fig3_nutation", "reaction": "reaction", "energy": "energy",
              "transmissibility": "transmissibility", "suite": "suite", "spectrum": "spectrum"}


# the most bootstrap resamples of `fragility` (each a fit: 10^5 take minutes)
MAX_BOOTSTRAP = 100_000


def draw(name, run, out, case=0, fmt="png", x_names=None, y_names=None, overwrite=False):
    """Draw figure `name` of `run` into folder `out`; return the file written,
    named after the ellroll file and the figure (FILE_fig2_trace.png), so that
    the figures of several files can share a folder. case: a per-case
    figure's case, its global index (FILE_fig3_nutation_case4.png)."""
    import matplotlib.pyplot as plt
    stem = figure_stem(run, "sweep_" + "_".join(x_names) if name == "sweep" else
                       FILE_STEMS[name] + (f"_case{case}" if case and name != "suite" else ""))
    path = pathlib.Path(out) / f"{stem}.{fmt}"
    check_target(path, overwrite)
    if name in plots.FIELD_NEEDS:               # before a figure is made: a clear error, no empty file
        plots.require(run, name, case)
    if name == "sweep":
        fig = plt.figure(figsize=(7.5, 3.2 * len(y_names) + 0.6), layout="constrained")
        plots.plot_sweep(fig, run, x_names, y_names)
    else:
        if name == "reaction":
            fig, axes = plt.subplots(3, 1, figsize=(9, 7.5), sharex=True, layout="constrained")
            plots.plot_reaction(axes, run, case)
        elif name == "suite":
            fig, axes = plt.subplots(1, 2, figsize=(11, 4.5), layout="constrained")
            plots.plot_suite(axes, run)
        else:
            size = {"trace": (8, 4.6), "nutation": (8, 4), "energy": (8, 4), "transmissibility": (10, 5),
                    "spectrum": (10, 4.5)}[name]
            fig, ax = plt.subplots(figsize=size, layout="constrained")
            if name == "transmissibility":
                plots.plot_transmissibility(ax, run)
            else:
                getattr(plots, f"plot_{name}")(ax, run, case)
    try:
        return save_figure(fig, path, overwrite, fmt)
    finally:
        plt.close(fig)


def figure_stem(run, figure):
    return f"{pathlib.Path(run.path).stem}_{figure}"


def workprecision_points(paths):
    """{method: [(error, seconds, rhs), ...]} from ellroll files run with
    error_estimate = 'reference', or from bench/workprecision.py's CSV."""
    points = {}
    for path in paths:
        if str(path).endswith(".csv"):
            for method, point in bench_table(path):
                points.setdefault(method, []).append(point)
            continue
        with open_run(path) as run:
            errors = run.summary("error_contact")
            times, rhs = run.summary("wall_time"), run.summary("n_rhs")
            methods = list(run._dataset("case/method").asstr()[:])
            if not any(e == e for e in errors):
                raise NotAnEllrollFile(f"{path}: no error figures; run it with &integration error_estimate = 'reference'")
            for method, e, t, r in zip(methods, errors, times, rhs):
                points.setdefault(method, []).append((e, t, r))
    return points


# bench/workprecision.py's CSV: the columns read from it
BENCH_COLUMNS = ("method", "error_m", "time_s", "rhs_evaluations")


def bench_table(path):
    """[(method, (error, seconds, rhs)), ...] of bench/workprecision.py's CSV;
    NotAnEllrollFile (one line naming the file, and the row and column where
    a value is bad) for a file that is not such a table or holds no row."""
    what = f"not a work-precision table (bench/workprecision.py's CSV, columns {', '.join(BENCH_COLUMNS)})"
    kind = not_regular(path)
    if kind:
        raise NotAnEllrollFile(f"{path}: {kind}, {what}")
    try:
        with open(path, "rb") as handle:
            data = handle.read()
    except FileNotFoundError:
        raise NotAnEllrollFile(f"{path}: no such file") from None
    except OSError as exc:
        raise NotAnEllrollFile(f"{path}: cannot read it ({exc.strerror or exc})") from None
    try:
        text = data.decode("utf-8-sig")
    except UnicodeDecodeError:
        raise NotAnEllrollFile(f"{path}: not text (not UTF-8), {what}") from None
    if "\0" in text:
        raise NotAnEllrollFile(f"{path}: not text (it holds NUL bytes), {what}")
    reader = csv.DictReader(io.StringIO(text, newline=""))
    try:
        header = reader.fieldnames
        if not header:
            raise NotAnEllrollFile(f"{path}: an empty file, {what}")
        missing = [c for c in BENCH_COLUMNS if c not in header]
        if missing:
            raise NotAnEllrollFile(f"{path}: missing columns {', '.join(missing)}; {what}")
        rows = []
        for row in reader:
            where = f"{path}:{reader.line_num}"
            values = []
            for column in BENCH_COLUMNS:
                value = row.get(column)
                if value is None:
                    raise NotAnEllrollFile(f"{where}: no {column} (the row has fewer fields than the header)")
                if column == "method":
                    if not value.strip():
                        raise NotAnEllrollFile(f"{where}: method is empty")
                    continue
                try:
                    values.append(float(value))
                except ValueError:
                    raise NotAnEllrollFile(f"{where}: {column} = {value!r} is not a number") from None
            rows.append((row["method"], tuple(values)))
    except csv.Error as exc:
        raise NotAnEllrollFile(f"{path}:{reader.line_num}: not a CSV row ({exc})") from None
    if not rows:
        raise NotAnEllrollFile(f"{path}: no rows (a header and no points)")
    return rows


def check_suite(run, path):
    """A record suite's figures need two or more records among the cases run. A
    partial file's pending cases hold no record yet: where its finished ones
    hold fewer than two, say so (the input may well be a suite)."""
    names = run.record_names()
    finished = [n for n, status in zip(names, run.status_names()) if status != "pending"]
    held = sorted(set(finished) - {""})
    if len(held) >= 2:
        return
    if len(finished) < len(names):
        which = f"one record ({held[0]})" if held else "no record"
        raise NotAnEllrollFile(f"{path}: its {len(finished)} finished cases of {len(names)} hold {which}; a suite's "
                               "figures need two or more (finish the run: ellroll run --resume)")
    raise NotAnEllrollFile(f"{path}: not a record suite (give two or more &record groups)")


class Parser(argparse.ArgumentParser):
    """Bad arguments: one line, exit 2 (argparse's own: a usage block first)."""

    def error(self, message):
        self.exit(2, f"{self.prog}: error: {' '.join(message.split())} (see '{self.prog} --help')\n")

    def _print_message(self, message, file=None):
        """--help and --version on standard output as any output is written
        there: one that cannot be written is an error (exit 2), not lost."""
        if message and (file is None or file is sys.stdout):
            try:
                _stdout(message)
            except StandardOutputLost as exc:
                self.exit(2, f"{self.prog}: error: cannot write the standard output: {exc}\n")
        else:
            super()._print_message(message, file)


def _count(minimum, maximum=None):
    """An argparse type: an integer from minimum (to maximum)."""
    def count(text):
        try:
            value = int(text)
        except ValueError:
            raise argparse.ArgumentTypeError(f"needs an integer, not {text!r}") from None
        if value < minimum or (maximum is not None and value > maximum):
            bounds = f"from {minimum} to {maximum}" if maximum is not None else f"{minimum} or more"
            raise argparse.ArgumentTypeError(f"needs an integer {bounds}, not {text}")
        return value
    return count


def _case(text):
    """An argparse type: a global case index (whether the file holds it is
    checked once it is open)."""
    try:
        return int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"needs a case index (an integer), not {text!r}") from None


def main(argv=None):
    """ellroll-plot; a suite's statistics of part of a campaign (suite.PartOfTheCampaign)
    say so in one warning line on standard error. SIGTERM and SIGINT end it
    in one line, with 128 + the signal's number, nothing half written left."""
    previous = {}
    forget_stop_requests()
    try:
        for number in (signal.SIGTERM, signal.SIGINT):
            previous[number] = signal.signal(number, request_stop)
    except ValueError:                  # (a thread other than the main one: signals are left alone)
        pass
    try:
        return _main_warned(argv)
    except Interrupted as stop:
        print(f"ellroll-plot: stopped by {signal.Signals(stop.signum).name}; nothing half written is left",
              file=sys.stderr)
        return 128 + stop.signum
    finally:
        for number, handler in previous.items():
            signal.signal(number, handler)


def _main_warned(argv):
    said = (PartOfTheCampaign, LeftBehind)       # (one line each, as ellroll-plot's own)
    with warnings.catch_warnings(record=True) as caught:
        for category in said:
            warnings.simplefilter("always", category)
        code = _main(argv)
    for other in caught:
        if not issubclass(other.category, said):
            warnings.showwarning(other.message, other.category, other.filename, other.lineno)
    if code == 0:           # (an error is its one line)
        for note in dict.fromkeys(str(w.message) for w in caught if issubclass(w.category, said)):
            print(f"ellroll-plot: warning: {note}", file=sys.stderr)
    return code


def _main(argv=None):
    parser = Parser(prog="ellroll-plot", description=__doc__)
    sub = parser.add_subparsers(dest="command", required=True)
    common = argparse.ArgumentParser(add_help=False)
    common.add_argument("--out", default=".", help="output folder (default: current)")
    common.add_argument("--format", default="png", choices=["png", "pdf", "svg"])
    common.add_argument("--overwrite", action="store_true", help="replace figures already in the output folder")
    for name, text in [("trace", "Fig. 2: XY trace of the contact point"), ("nutation", "Fig. 3: Theta against t"),
                       ("reaction", "normal force, friction and the friction coefficient needed"),
                       ("energy", "energy and constraint errors"),
                       ("spectrum", "spectrum of the transmitted acceleration against the ground's")]:
        p = sub.add_parser(name, parents=[common], help=text)
        p.add_argument("file")
        p.add_argument("--case", type=_case, help="the case, by its global index (as `ellroll summary` lists "
                       "it; a shard's file holds every N-th); default: the file's first case")
    p = sub.add_parser("sweep", parents=[common], help="summary quantities against swept inputs")
    p.add_argument("file")
    p.add_argument("--x", help="one or two swept inputs, e.g. omega_z or omega_z,radius (default: the swept ones)")
    p.add_argument("--y", default="theta_max", help="summary quantities, e.g. theta_max,nutation_period")
    p = sub.add_parser("transmissibility", parents=[common],
                       help="transmissibility against an excitation_frequency sweep, linear resonances marked")
    p.add_argument("file")
    p = sub.add_parser("suite", parents=[common],
                       help="a record suite: peak displacement and acceleration per scale, median and 84th percentile")
    p.add_argument("file")
    p = sub.add_parser("fragility", help="a record suite: lognormal fragility of reaching a model limit (or a limit "
                       "state) against the scale or an intensity measure, with a bootstrap band")
    p.add_argument("file")
    p.add_argument("--im", default="scale",
                   help="intensity measure: scale (default), or one the file holds: PGA, PGV, PGD, Sa(T) (at the "
                        "isolator's first period; Sa(T2) its second), Sa(1.0), sa_1")
    p.add_argument("--bootstrap", type=_count(0, MAX_BOOTSTRAP), default=200,
                   help=f"bootstrap resamples for the intervals, 0 to {MAX_BOOTSTRAP} (default 200)")
    p.add_argument("--seed", type=_count(0), default=0, help="seed of the bootstrap, 0 or more (default 0)")
    p.add_argument("--limit-state",
                   help=f"the limit state drawn (default {MODEL_LIMIT_STATE}: rim, no_fit, slip, liftoff), or "
                        "printed (default: every one)")
    p.add_argument("--format", default="png", choices=["png", "pdf", "svg", "table", "csv", "json"],
                   help="a figure, or the fits (theta, beta, 5-95 %% intervals) printed as table, csv or json")
    p.add_argument("--out", default=".", help="output folder (default: current)")
    p.add_argument("-o", "--output", help="the figure's file (default: FILE_fragility.FORMAT in --out); with "
                   "--format table, csv or json the file the fits go in (default, or -: standard output)")
    p.add_argument("--overwrite", action="store_true", help="replace a figure (or a table) ellroll-plot made")
    p = sub.add_parser("workprecision", parents=[common], help="error against time and RHS evaluations")
    p.add_argument("files", nargs="+", help="ellroll files run with error_estimate = 'reference', or a bench CSV")
    p = sub.add_parser("report", parents=[common], help="every figure that applies, with index.html")
    p.add_argument("file")
    p.add_argument("--case", type=_case, help="the case of the per-case figures, by its global index "
                   "(default: the file's first case)")
    p.add_argument("--cases", action="store_true",
                   help=f"the table of every case in index.html (default: the first {REPORT_ROWS}, the rest in "
                        "summary.csv)")
    p = sub.add_parser("summary", help="the summary table")
    p.add_argument("file")
    p.add_argument("--format", default="table", choices=["table", "csv", "json"])
    p.add_argument("--suite", action="store_true",
                   help="per stripe of a record suite: counts, fraction at a model limit, median and 16-84 %% of "
                        "each response over the completed records")
    p.add_argument("--percentiles", choices=["linear", "lognormal"],
                   help="with --suite: numpy's linear percentiles (default) or those of a fitted lognormal")
    args, unknown = parser.parse_known_args(argv)
    if unknown:
        # said by the parser they were given to: after the subcommand, its own (its name, its --help)
        words = [str(word) for word in (sys.argv[1:] if argv is None else argv)]
        first = words.index(unknown[0]) if unknown[0] in words else len(words)
        given_to = sub.choices[args.command] if args.command in words[:first] else parser
        given_to.error(f"unrecognized arguments: {' '.join(unknown)}")
    for option in ("case", "bootstrap", "seed"):
        # (argparse hands `--seed=--` over as [] without its type's check)
        value = getattr(args, option, None)
        if value is not None and not isinstance(value, int):
            parser.error(f"argument --{option}: needs an integer, not {value!r}")
    if args.command == "sweep" and args.x is not None:
        names = args.x.split(",")
        if not all(names) or len(names) > 2:
            parser.error(f"argument --x: needs one or two swept inputs, e.g. omega_z or omega_z,radius, "
                         f"not {args.x!r}")
        if len(set(names)) < len(names):
            parser.error(f"argument --x: {names[0]} twice; give two different swept inputs, or one")
    if args.command == "summary":
        if args.percentiles is not None and not args.suite:
            parser.error("argument --percentiles: only with --suite (the percentiles of a record suite's stripes)")
        args.percentiles = args.percentiles or "linear"
    out_option = "--out"
    if args.command == "report" and args.out == ".":
        # FILE_report beside FILE ("." or "/" have no name: open_run refuses them, a folder)
        name = pathlib.Path(args.file)
        args.out = str(name.with_suffix("") if name.name else name) + "_report"
        out_option = "report folder"

    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    try:
        if args.command == "summary":
            with open_run(args.file) as run:
                if args.suite:
                    _stdout(format_suite(suite_statistics(run, percentiles=args.percentiles), args.format,
                                         args.file))
                else:
                    _stdout(format_summary(run, args.format))
            return 0
        if args.command == "fragility":
            if args.output == "":
                raise OutputExists("-o '': give a file name (or leave -o out: the table goes to standard output)")
            if args.output == "-" and args.format not in ("table", "csv", "json"):
                raise OutputExists(f"-o -: a {args.format} figure goes to a file; standard output takes --format "
                                   "table, csv or json")
            with open_run(args.file) as run:
                check_suite(run, args.file)
                plots.intensity(run, args.im)           # a clear error before anything is written
                if args.limit_state is not None:
                    check_limit_state(run, args.limit_state)
                if args.format in ("table", "csv", "json"):
                    table, _ = plots.suite_fragility(run, args.im, args.bootstrap, args.seed)
                    if args.limit_state is not None:
                        table = _rows_of(table, table["limit_state"] == args.limit_state)
                    text = format_fragility(table, args.format, args.file)
                    if args.output in (None, "-"):           # ('-': standard output, as the usual tools take it)
                        _stdout(text)
                        return 0
                    path = pathlib.Path(args.output)
                    output_folder(path.parent, "-o")
                    write_text(path, args.overwrite, text)
                    _stdout(f"{path}\n")
                    return 0
                path = pathlib.Path(args.output) if args.output else \
                    pathlib.Path(args.out) / f"{figure_stem(run, 'fragility')}.{args.format}"
                output_folder(path.parent, "-o" if args.output else "--out")
                check_target(path, args.overwrite)
                fig, ax = plt.subplots(figsize=(10, 4.8), layout="constrained")
                try:
                    plots.plot_fragility(ax, run, args.im, args.bootstrap, args.seed,
                                         args.limit_state or MODEL_LIMIT_STATE)
                    save_figure(fig, path, args.overwrite, args.format)
                finally:
                    plt.close(fig)
            _stdout(f"{path}\n")
            return 0
        out = pathlib.Path(args.out)
        if args.command == "workprecision":
            output_folder(out)
            written = [out / f"{pathlib.Path(args.files[0]).stem}_workprecision.{args.format}"]
            check_target(written[0], args.overwrite)
            points = workprecision_points(args.files)
            if not any(e > 0 and t > 0 and math.isfinite(e) and math.isfinite(t)
                       for rows in points.values() for e, t, _ in rows):
                raise NotAnEllrollFile(f"{', '.join(args.files)}: no point to draw (no positive, finite error "
                                       "and time)")
            fig, axes = plt.subplots(1, 2, figsize=(12, 4.5), layout="constrained")
            plots.plot_workprecision(axes, points)
            save_figure(fig, written[0], args.overwrite, args.format)
        else:
            with open_run(args.file) as run:
                # (once the file opened: no folder for a bad one)
                output_folder(out, out_option, make=args.command != "report", own=args.command == "report")
                if args.command == "report" or args.command in plots.FIELD_NEEDS:
                    args.case = run.case_index(args.case)       # the global index held (None: the file's first)
                if args.command == "report":
                    written = build_report(run, out, functools.partial(draw, overwrite=args.overwrite), args.case,
                                           args.format, args.overwrite, all_cases=args.cases) + [out / "index.html"]
                elif args.command == "transmissibility":
                    plots.require_transmissibility(run)
                    written = [draw("transmissibility", run, out, 0, args.format, overwrite=args.overwrite)]
                elif args.command == "suite":
                    check_suite(run, args.file)
                    written = [draw("suite", run, out, 0, args.format, overwrite=args.overwrite)]
                elif args.command == "sweep":
                    x_names = args.x.split(",") if args.x is not None else run.swept_inputs()[:2]
                    if not x_names:
                        raise NotAnEllrollFile(f"{args.file}: no input varies between its cases; nothing to sweep")
                    for name in x_names:
                        if name not in run.swept_inputs():
                            raise NotAnEllrollFile(f"{args.file}: {name} is not a swept input "
                                                   f"(swept: {', '.join(run.swept_inputs()) or 'none'})")
                    y_names = args.y.split(",")
                    for name in y_names:
                        if name not in run.summary_names:
                            raise NotAnEllrollFile(f"{args.file}: no summary quantity {name} "
                                                   f"(known: {', '.join(run.summary_names)})")
                    written = [draw("sweep", run, out, 0, args.format, x_names, y_names, args.overwrite)]
                else:
                    written = [draw(args.command, run, out, args.case, args.format, overwrite=args.overwrite)]
        _stdout("".join(f"{path}\n" for path in written))
    except StandardOutputLost as exc:
        print(f"ellroll-plot: error: cannot write the standard output: {exc}", file=sys.stderr)
        return 2
    except (NotAnEllrollFile, NoIntensityMeasure, NoStripes, OutputExists) as exc:
        print(f"ellroll-plot: error: {exc}", file=sys.stderr)
        return 2
    except Exception as exc:
        if from_h5py(exc):                      # a read the reader does not make (pandas, h5py in suite.py)
            files = getattr(args, "files", None) or [args.file]
            print(f"ellroll-plot: error: {damaged(', '.join(map(str, files)), exc)}", file=sys.stderr)
            return 2
        if isinstance(exc, OSError):
            print(f"ellroll-plot: error: {exc}", file=sys.stderr)
            return 2
        raise
    return 0


class StandardOutputLost(Exception):
    """Standard output cannot be written (a full disk, a closed pipe)."""


def _stdout(text):
    """Write text to standard output, now (flushed): StandardOutputLost,
    with the system's reason, where it cannot be written. Standard output is
    then pointed at os.devnull, so that Python's flush at exit finds nothing
    to write."""
    if sys.stdout is None:              # (Python's, where the process started with it closed)
        raise StandardOutputLost(os.strerror(errno.EBADF))
    try:
        sys.stdout.write(text)
        sys.stdout.flush()
    except OSError as exc:
        try:
            null = os.open(os.devnull, os.O_WRONLY)
            os.dup2(null, sys.stdout.fileno())
            os.close(null)
        except (OSError, ValueError, io.UnsupportedOperation):
            pass
        raise StandardOutputLost(exc.strerror or str(exc)) from None


def _rows_of(table, keep):
    """Rows of a fit table, its attributes kept."""
    rows = table[keep].reset_index(drop=True)
    rows.attrs.update(table.attrs)
    return rows


if __name__ == "__main__":
    sys.exit(main())
