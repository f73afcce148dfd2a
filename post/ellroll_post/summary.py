"""The summary table of an ellroll file as text, CSV or JSON: the columns of
`ellroll summary --format csv|json`, and its CSV text, character for
character (numbers written as ellroll writes them: number_text)."""
import csv
import io
import json
import math

import numpy as np

def summary_table(run):
    """{column: (units, values)}: the case index, the varied inputs, the
    status by name, then every figure of /summary (a value per mode: one
    column per mode, NAME_1, NAME_2; a count at its _FillValue, -1, undefined
    for the case, as NaN, as `ellroll summary` writes it)."""
    table = {"case": ("1", run.summary("case").tolist())}
    for name in run.varied_inputs():
        if name == "record":
            table[name] = ("1", run.record_names())
        else:
            table[name] = (run.input_units(name), run.input_column(name).astype(float).tolist())
    table["status"] = ("1", run.status_names())
    for name in run.summary_figures:
        values, units = run.summary(name), run.units(f"summary/{name}")
        fill = run._h5[f"summary/{name}"].attrs.get("_FillValue")
        if values.ndim == 1 and values.dtype.kind in "iu" and fill is not None:
            missing = np.asarray(fill).ravel()[0]
            table[name] = (units, [math.nan if v == missing else v for v in values.tolist()])
        elif values.ndim == 1:
            table[name] = (units, values.tolist())
        else:
            for m in range(values.shape[1]):
                table[f"{name}_{m + 1}"] = (units, values[:, m].tolist())
    return table


def summary_rows(run, first=None):
    """One dict per case (the first `first` cases): summary_table's columns."""
    columns = {name: values[:first] for name, (_, values) in summary_table(run).items()}
    return [dict(zip(columns, row)) for row in zip(*columns.values())]


def format_summary(run, fmt="table"):
    table = summary_table(run)
    keys = list(table)
    columns = [values for _, values in table.values()]
    if fmt == "json":        # strict JSON: NaN (not applicable, not reached) is null
        rows = [{k: (None if isinstance(v, float) and v != v else v) for k, v in zip(keys, row)}
                for row in zip(*columns)]
        return json.dumps({"file": run.path, "units": {k: units for k, (units, _) in table.items()},
                           "cases": rows}, indent=1, allow_nan=False)
    if fmt == "csv":
        out = io.StringIO()
        writer = csv.writer(out, lineterminator="\n")
        writer.writerow([column_header(k, units) for k, (units, _) in table.items()])
        writer.writerows([number_text(v) if isinstance(v, float) else v for v in row] for row in zip(*columns))
        return out.getvalue()
    cells = [[_fmt(v) for v in values] for values in columns]
    widths = [max(len(k), *(len(c) for c in column)) if column else len(k) for k, column in zip(keys, cells)]
    lines = ["  ".join(k.rjust(w) for k, w in zip(keys, widths))]
    lines += ["  ".join(c.rjust(w) for c, w in zip(row, widths)) for row in zip(*cells)]
    return "\n".join(lines) + "\n"


def _fmt(value):
    if isinstance(value, float):
        return f"{value:.6g}"
    return str(value)


def column_header(name, units):
    """A CSV column's header: `name [units]`, or the bare name for a
    dimensionless column or one of text (units '1' or none)."""
    return name if units in ("", "1") else f"{name} [{units}]"


_NEAR_HUGE = 1.7976931348623157e308 * (1 - 1.0e-14)


def number_text(x):
    """x as ellroll writes it (format_real, src/core/strings.f90): the
    shortest of 15, 16 or 17 significant digits that reads back as x, trailing
    zeros dropped; fixed point from 1e-4 to below 1e10 ('30', '0.2'), else
    'MANTISSAe+XX' ('1e-06'); 'NaN', 'Infinity', '-Infinity'; '0' for zero."""
    if math.isnan(x):
        return "NaN"
    if math.isinf(x):
        return "Infinity" if x > 0 else "-Infinity"
    if x == 0:
        return "0"
    for digits in ((17,) if abs(x) >= _NEAR_HUGE else (15, 16, 17)):
        work = f"{x:.{digits - 1}e}"
        if float(work) == x:
            break
    mantissa = work.split("e")[0].rstrip("0").rstrip(".")
    digits = sum(c.isdigit() for c in mantissa)
    # the exponent of the digits written (rounding may carry into the next power of ten)
    exponent10 = int(work.split("e")[1])
    if -4 <= exponent10 < 10:
        return f"{x:.{max(0, digits - 1 - exponent10)}f}"
    return f"{mantissa}e{'-' if exponent10 < 0 else '+'}{abs(exponent10):02d}"
