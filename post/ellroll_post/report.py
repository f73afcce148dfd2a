"""A report folder: every figure that applies to the file and an index.html
that shows them beside the summary table."""
import html
import pathlib

from .safe_write import MARK, check_target, write_text
from .summary import format_summary, summary_table

# figure name -> trajectory fields it needs
CASE_FIGURES = {"trace": {"contact"}, "nutation": {"nutation"}, "reaction": {"reaction", "normal"},
                "energy": {"energy"}}
# file stem (its first part) -> caption
CAPTIONS = {"fig2_trace": "Fig. 2: the contact point's trace in the XY plane, the cup's rim and the energy bound",
            "fig3_nutation": "Fig. 3: the nutation angle against time",
            "reaction": "The force of the cup on the ball: normal force, friction, friction coefficient needed",
            "energy": "Energy error and constraint error against time",
            "sweep": "Summary quantities against the varied inputs",
            "transmissibility": "Transmissibility against the excitation frequency, linear resonances marked",
            "suite": "Record suite: peak displacement and peak absolute acceleration per scale",
            "spectrum": "Spectra of the transmitted and the ground acceleration"}




def build_report(run, out, draw, case=0, fmt="png", overwrite=False):
    """Draw what applies into out/, write out/index.html; return the paths."""
    out = pathlib.Path(out)
    out.mkdir(parents=True, exist_ok=True)
    for page in ("index.html", "summary.csv"):
        check_target(out / page, overwrite)
    made = []
    swept = run.swept_inputs()
    if swept:
        y_names = [n for n in ("theta_max", "nutation_period") if n in run.summary_names]
        for x in swept[:2]:
            made.append(draw("sweep", run, out, case, fmt, x_names=[x], y_names=y_names))
        if len(swept) == 2:
            made.append(draw("sweep", run, out, case, fmt, x_names=swept, y_names=y_names[:1]))
    if "excitation_frequency" in swept:
        made.append(draw("transmissibility", run, out, case, fmt))
    if len(set(run.record_names()) - {""}) > 1:
        made.append(draw("suite", run, out, case, fmt))
    if {"reaction", "base_acceleration"} <= set(run.fields):
        made.append(draw("spectrum", run, out, case, fmt))
    for name, needs in CASE_FIGURES.items():
        if needs <= set(run.fields):
            made.append(draw(name, run, out, case, fmt))
    write_text(out / "summary.csv", overwrite, format_summary(run, "csv"))
    write_text(out / "index.html", overwrite, _index_html(run, made, case))
    return made


def _index_html(run, figures, case, shown=200):
    attrs = run.attrs
    table = summary_table(run)
    keys = list(table)
    head = "<tr>" + "".join(f"<th>{html.escape(_heading(k, table[k][0]))}</th>" for k in keys) + "</tr>\n"
    rows = zip(*(values[:shown] for _, values in table.values()))
    body = "".join("<tr>" + "".join(f"<td>{html.escape(_cell(v))}</td>" for v in row) + "</tr>\n" for row in rows)
    more = f"<p>{run.n_cases - shown} more cases in summary.csv</p>" if run.n_cases > shown else ""
    prefix = pathlib.Path(run.path).stem + "_"
    images = "\n".join(f'<figure><img src="{p.name}" alt="{p.stem}"><figcaption>'
                       f'{html.escape(_caption(p.stem.removeprefix(prefix)))}</figcaption></figure>' for p in figures)
    return f"""<!DOCTYPE html>
<html><head><meta charset="utf-8"><meta name="generator" content="{MARK}"><title>ellroll report: {html.escape(run.path)}</title>
<style>body{{font-family:sans-serif;margin:2em}} img{{max-width:100%}} figure{{margin:1em 0}}
table{{border-collapse:collapse;font-size:small}} td,th{{border:1px solid #ccc;padding:2px 6px;text-align:right}}</style>
</head><body>
<h1>ellroll report</h1>
<p>File <code>{html.escape(run.path)}</code>, {run.n_cases} cases; written by ellroll {html.escape(str(attrs.get('version', '')))}
on {html.escape(str(attrs.get('created', '')))} from <code>{html.escape(str(attrs.get('input_file', '')))}</code>.
Per-case figures show case {case}.</p>
<h2>Summary</h2>
<table>
{head}{body}</table>
{more}
<h2>Figures</h2>
{images}
<h2>Input</h2>
<pre>{html.escape(str(attrs.get('input_namelist', '')))}</pre>
</body></html>
"""


def _caption(stem):
    for key, text in CAPTIONS.items():
        if stem.startswith(key):
            return f"{text} ({stem})"
    return stem


def _heading(key, units):
    return f"{key}, {units}" if units and units != "1" else key


def _cell(value):
    return f"{value:.6g}" if isinstance(value, float) else str(value)
