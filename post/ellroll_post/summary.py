"""The summary table of an ellroll file as text, CSV or JSON."""
import csv
import io
import json

import numpy as np

COLUMNS = ["status", "t_final", "theta_max", "nutation_period", "reaction_normal_max", "friction_needed_max",
           "energy_drift", "error_contact", "displacement_max", "displacement_max_time", "residual_displacement",
           "absolute_acceleration_max", "absolute_acceleration_max_time", "transmissibility", "n_steps",
           "wall_time"]


def summary_rows(run):
    """One dict per case: its index, swept inputs and summary values."""
    swept = run.swept_inputs()
    columns = {name: run.input_column(name) for name in swept}
    status = run.status_names()
    present = [c for c in COLUMNS[1:] if c in run.summary_names]
    values = {c: run.summary(c) for c in present}
    index = run.summary("case")
    records = run.record_names()
    rows = []
    for i in range(run.n_cases):
        row = {"case": int(index[i])}
        if records[i]:
            row["record"] = records[i]
        row.update({name: float(columns[name][i]) for name in swept})
        row["status"] = status[i]
        row.update({c: (int(values[c][i]) if np.issubdtype(values[c].dtype, np.integer) else float(values[c][i]))
                    for c in present})
        rows.append(row)
    return rows


def format_summary(run, fmt="text"):
    rows = summary_rows(run)
    if fmt == "json":        # strict JSON: NaN (not applicable, not reached) is null
        rows = [{k: (None if isinstance(v, float) and v != v else v) for k, v in row.items()} for row in rows]
        return json.dumps({"file": run.path, "cases": rows}, indent=1, allow_nan=False)
    keys = list(rows[0].keys()) if rows else []
    if fmt == "csv":
        out = io.StringIO()
        writer = csv.DictWriter(out, fieldnames=keys)
        writer.writeheader()
        writer.writerows(rows)
        return out.getvalue()
    widths = {k: max(len(k), *(len(_fmt(r[k])) for r in rows)) for k in keys}
    lines = ["  ".join(k.rjust(widths[k]) for k in keys)]
    lines += ["  ".join(_fmt(r[k]).rjust(widths[k]) for k in keys) for r in rows]
    return "\n".join(lines) + "\n"


def _fmt(value):
    if isinstance(value, float):
        return f"{value:.6g}"
    return str(value)
