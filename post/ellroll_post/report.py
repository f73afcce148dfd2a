"""A report folder: every figure that applies to the file and an index.html
that shows them beside the summary table."""
import html
import math
import os
import pathlib
import shutil
import tempfile
import urllib.parse
import warnings

import numpy as np

from .plots import FIELD_NEEDS, cup_moves, has_samples, name_text
from .safe_write import MARK, CannotWrite, _umask, check_target, stop_point, sync_to_disk, write_text
from .summary import format_summary, summary_table

# the per-case figures, drawn for the report's case where the file has their fields
CASE_FIGURES = ("trace", "nutation", "reaction", "energy")
REPORT_ROWS = 50        # rows of the per-case table shown unless every case is asked for (--cases)
# summary figures of a moving cup: left out of a report whose cups all stay at rest
ISOLATOR_COLUMNS = ("displacement_max", "displacement_max_time", "residual_displacement", "horizontal_force_max",
                    "absolute_acceleration_max", "absolute_acceleration_max_time", "transmissibility")
# file stem (its first part) -> caption
CAPTIONS = {"fig2_trace": "Fig. 2: the contact point's trace in the XY plane, the cup's rim and the energy bound",
            "fig3_nutation": "Fig. 3: the nutation angle against time",
            "reaction": "The force of the cup on the ball: normal force, friction, friction coefficient needed",
            "energy": "Energy error (a fixed cup) or energy change and the cup's work (a moving cup), constraint error",
            "sweep": "Summary quantities against the varied inputs",
            "transmissibility": "Transmissibility against the excitation frequency, linear resonances marked",
            "suite": "Record suite: peak displacement and peak absolute acceleration per scale",
            "spectrum": "Spectra of the transmitted and the ground acceleration"}




class LeftBehind(UserWarning):
    """A report in place whose own work folder, or the old report's files
    kept aside, could not be removed after: named, to be removed by hand."""


def _remove_left(folder, what):
    """Remove one of the report's own work folders; LeftBehind where it
    stays (an I/O error)."""
    try:
        shutil.rmtree(folder)
    except FileNotFoundError:
        pass
    except OSError as exc:
        warnings.warn(f"the report is in place, but {what} {folder} could not be removed "
                      f"({exc.strerror or exc}); remove it by hand", LeftBehind, stacklevel=2)


def build_report(run, out, draw, case=None, fmt="png", overwrite=False, all_cases=False):
    """Draw what applies into out/, write out/index.html; return the paths.
    all_cases: the per-case table lists every case (else the first REPORT_ROWS);
    case: the per-case figures' case, its global index (None: the file's first).
    The report is made whole in a new folder (beside out, or in an out that
    exists) and moved into place at its end, each file checked first: a
    report that fails leaves nothing, and a file without a case makes nothing."""
    case = run.case_index(case)
    out = pathlib.Path(out)
    for page in ("index.html", "summary.csv"):
        check_target(out / page, overwrite)
    there = out.is_dir()
    try:
        staging = pathlib.Path(tempfile.mkdtemp(prefix=f".{out.name}.", dir=out if there else out.parent))
    except OSError as exc:
        raise CannotWrite(f"{out}: cannot write the report in folder {out if there else out.parent} "
                          f"({exc.strerror or exc})") from None
    try:
        made = _draw_report(run, staging, draw, case, fmt, all_cases)
        stop_point()
        names = [path.name for path in made] + ["summary.csv", "index.html"]
        if there:
            for name in names:
                check_target(out / name, overwrite)
            _move_in(staging, out, names)
        else:
            os.chmod(staging, 0o777 & ~_umask())        # as a folder made the usual way would be
            os.rename(staging, out)
    except CannotWrite as exc:
        shutil.rmtree(staging, ignore_errors=True)
        raise CannotWrite(str(exc).replace(str(staging), str(out))) from None     # (the name the user gave)
    except OSError as exc:
        shutil.rmtree(staging, ignore_errors=True)
        raise CannotWrite(f"{out}: cannot move the report into place ({exc.strerror or exc})") from None
    except BaseException:
        shutil.rmtree(staging, ignore_errors=True)
        raise
    if there:
        _remove_left(staging, "its emptied work folder")
    sync_to_disk(out if there else out.parent, out)
    return [out / path.name for path in made]


def _move_in(staging, out, names):
    """The report's files moved from staging into the folder out that
    exists, each file there first kept aside: where a move fails, the
    files already moved are taken back out and the kept ones put back, so
    that the folder is as it was. An old file that cannot be put back stays
    in the folder it was kept in, which the error names, and the new one at
    its name is removed (no report of two runs' files), or named."""
    kept = pathlib.Path(tempfile.mkdtemp(prefix=f".{out.name}.kept.", dir=out))
    moved = []
    stranded = []
    mixed = []
    try:
        for name in names:
            had = os.path.lexists(out / name)
            if had:
                os.rename(out / name, kept / name)
            moved.append((name, had))
            os.replace(staging / name, out / name)
    except BaseException as exc:
        for name, had in reversed(moved):
            try:
                if had:
                    os.replace(kept / name, out / name)
                elif os.path.lexists(out / name) and not os.path.lexists(staging / name):
                    os.remove(out / name)
            except OSError:
                stranded.append(name)
                if had and not os.path.lexists(staging / name):
                    try:
                        os.remove(out / name)           # the new file where the old one could not go back
                    except OSError:
                        mixed.append(name)
        if stranded and isinstance(exc, OSError):
            left = (f"; the folder still holds the new {', '.join(sorted(mixed))} beside the old report's other files"
                    if mixed else "")
            raise CannotWrite(f"{out}: cannot move the report into place ({exc.strerror or exc}), nor put the old "
                              f"one back: {', '.join(sorted(stranded))} of it are in {kept}{left}") from None
        shutil.rmtree(kept, ignore_errors=True)      # (emptied: the error says what failed)
        raise
    _remove_left(kept, "the old report's files, kept aside in")


def _draw_report(run, out, draw, case, fmt, all_cases):
    """The report's figures and pages drawn into the folder out (new, empty)."""
    overwrite = False
    made = []
    swept = run.swept_inputs()
    if swept:
        y_names = [n for n in ("theta_max", "nutation_period") if n in run.summary_names]
        for x in swept[:2]:
            made.append(draw("sweep", run, out, case, fmt, x_names=[x], y_names=y_names))
        if len(swept) == 2:
            made.append(draw("sweep", run, out, case, fmt, x_names=swept, y_names=y_names[:1]))
    if "excitation_frequency" in swept and np.any(np.isfinite(run.summary("transmissibility"))):
        made.append(draw("transmissibility", run, out, case, fmt))
    if len(set(run.record_names()) - {""}) > 1:
        made.append(draw("suite", run, out, case, fmt))
    notes = []
    if has_samples(run, case):
        for name in ("spectrum", *CASE_FIGURES):
            if all(field in run.fields for field in FIELD_NEEDS[name]):
                made.append(draw(name, run, out, case, fmt))
    else:
        notes.append(f"Case {case} was never run ({run.status_name(case)}): no per-case figures; "
                     "give --case for another.")
    write_text(out / "summary.csv", overwrite, format_summary(run, "csv"))
    write_text(out / "index.html", overwrite, _index_html(run, made, case, REPORT_ROWS if not all_cases else None,
                                                          notes))
    return made


def report_columns(run):
    """summary_table's columns that say something: without those NaN in
    every case, and without a moving cup's figures where every cup is at rest."""
    table = summary_table(run)
    at_rest = not any(cup_moves(run, c) for c in _distinct_excitations(run))
    keep = {}
    for key, (units, values) in table.items():
        if at_rest and key in ISOLATOR_COLUMNS:
            continue
        if values and all(isinstance(v, float) and math.isnan(v) for v in values):
            continue
        keep[key] = (units, values)
    return keep


def _distinct_excitations(run):
    """One case of each excitation kind (reading the kinds once), by global index."""
    try:
        kinds = [str(k).strip() for k in run.input_column("excitation_kind")]
    except Exception:       # a file without the input: every case decides for itself
        return run.cases
    first = {}
    for index, kind in enumerate(kinds):
        first.setdefault(kind, index)
    return [int(run.cases[row]) for row in sorted(first.values())]


def campaign_summary(run, columns):
    """{figure: (units, min, median, max, n)} over the completed cases, for
    every real figure of /summary with a finite value among them."""
    done = np.array(run.status_names()) == "completed"
    figures = {}
    for key, (units, values) in columns.items():
        if key in ("case", "status") or key in run.varied_inputs():
            continue
        array = np.asarray(values, dtype=object)
        if not all(isinstance(v, (int, float)) and not isinstance(v, bool) for v in array):
            continue
        chosen = np.asarray(array[done], dtype=float)
        chosen = chosen[np.isfinite(chosen)]
        if chosen.size:
            figures[key] = (units, chosen.min(), np.median(chosen), chosen.max(), chosen.size)
    return figures


def status_counts(run):
    names, counts = np.unique(run.status_names(), return_counts=True)
    order = sorted(zip(names, counts), key=lambda item: (item[0] != "completed", -item[1], item[0]))
    return [(str(n), int(c)) for n, c in order]


def _index_html(run, figures, case, shown=REPORT_ROWS, notes=()):
    attrs = run.attrs
    columns = report_columns(run)
    keys = list(columns)
    head = "<tr>" + "".join(f"<th>{html.escape(_heading(k, columns[k][0]))}</th>" for k in keys) + "</tr>\n"
    rows = zip(*(values[:shown] for _, values in columns.values()))
    body = "".join("<tr>" + "".join(f"<td>{html.escape(_cell(v))}</td>" for v in row) + "</tr>\n" for row in rows)
    hidden = run.n_cases - shown if shown is not None and run.n_cases > shown else 0
    more = (f"<p>The first {shown} of {_count(run.n_cases, 'case')}: the other {_count(hidden, 'case')} in "
            f"<a href=\"summary.csv\">summary.csv</a>; <code>ellroll-plot report --cases</code> lists all here.</p>"
            if hidden else "")
    dropped = [k for k in summary_table(run) if k not in columns]
    dropped_note = (f"<p>Left out: {html.escape(', '.join(dropped))} (NaN in every case, or a moving cup's "
                    "figures where every cup is at rest).</p>" if dropped else "")
    counts = ", ".join(f"{count} {html.escape(name)}" for name, count in status_counts(run))
    stats = campaign_summary(run, columns)
    completed = dict(status_counts(run)).get("completed", 0)
    stats_rows = "".join(f"<tr><th>{html.escape(_heading(k, u))}</th><td>{_cell(lo)}</td><td>{_cell(mid)}</td>"
                         f"<td>{_cell(hi)}</td><td>{n}</td></tr>\n" for k, (u, lo, mid, hi, n) in stats.items())
    campaign = (f"<h2>Campaign summary</h2>\n<p>Over the {_count(completed, 'completed case')}.</p>\n<div class=\"wide\">"
                f"<table class=\"stats\">\n<tr><th>figure</th><th>min</th><th>median</th><th>max</th><th>cases</th></tr>\n"
                f"{stats_rows}</table></div>" if stats and run.n_cases > 1 else "")
    prefix = pathlib.Path(run.path).stem + "_"
    # (a file's name is text: quoted in the link, escaped in the attribute)
    # (its bytes, as the file system has them, in the link: a name need not be UTF-8)
    images = "\n".join(f'<figure><img src="{html.escape(urllib.parse.quote(os.fsencode(p.name)))}" '
                       f'alt="{html.escape(p.stem)}"><figcaption>'
                       f'{html.escape(_caption(p.stem.removeprefix(prefix)))}</figcaption></figure>'
                       for p in figures)
    remarks = "".join(f"<p>{html.escape(n)}</p>\n" for n in notes)
    # (a name that is not UTF-8 shown with its bytes as \xNN)
    return name_text(f"""<!DOCTYPE html>
<html><head><meta charset="utf-8"><meta name="generator" content="{MARK}"><title>ellroll report: {html.escape(run.path)}</title>
<style>body{{font-family:sans-serif;margin:2em;max-width:80em}} img{{max-width:100%}} figure{{margin:1em 0}}
div.wide{{overflow-x:auto;max-width:100%}}
table{{border-collapse:collapse;font-size:small}} td,th{{border:1px solid #ccc;padding:2px 6px;text-align:right}}
th{{white-space:normal;overflow-wrap:anywhere;max-width:7em;vertical-align:bottom}}
table.stats th{{text-align:left;max-width:none}}</style>
</head><body>
<h1>ellroll report</h1>
<p class="counts"><strong>{_count(run.n_cases, 'case')}: {counts}.</strong></p>
<p>File <code>{html.escape(run.path)}</code>; written by ellroll {html.escape(str(attrs.get('version', '')))}
on {html.escape(str(attrs.get('created', '')))} from <code>{html.escape(str(attrs.get('input_file', '')))}</code>.
Per-case figures show case {case}.</p>
{remarks}{campaign}
<h2>Cases</h2>
<div class="wide"><table>
{head}{body}</table></div>
{more}{dropped_note}
<h2>Figures</h2>
{images}
<h2>Input</h2>
<pre>{html.escape(str(attrs.get('input_namelist', '')))}</pre>
</body></html>
""")


def _count(n, noun):
    return f"{n} {noun}" + ("" if n == 1 else "s")


def _caption(stem):
    for key, text in CAPTIONS.items():
        if stem.startswith(key):
            return f"{text} ({stem})"
    return stem


def _heading(key, units):
    return f"{key}, {units}" if units and units != "1" else key


def _cell(value):
    return f"{value:.6g}" if isinstance(value, float) else str(value)
