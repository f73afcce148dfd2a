"""Statistics of a record suite that know failure.

A stripe is the set of cases that share every varied design input (the
record's scale, and any other sweep, e.g. rolling_resistance): one case per
record. Per stripe:

- counts: the cases (n_cases), those that reached t_end (n_completed), those
  that ended at a model limit (n_limit: rim, no_fit, slip, liftoff; one
  column per limit, n_rim, ...) and those with no physical outcome
  (n_unresolved: never run, invalid or pending, or stopped by a numerical
  failure: nonfinite, constraint, unstable);
- fraction_limit = n_limit / (n_completed + n_limit): the fraction of the
  cases with a physical outcome that exceeded the isolator's capacity. The
  unresolved cases are left out of both counts: their outcome is unknown;
- for each user limit state (an 'exceeded' column per case, see
  limit_state_columns), n_NAME the cases that exceeded it, n_undefined_NAME
  the completed cases whose figure is undefined (NaN: residual_displacement
  while the ball still moves, transmissibility of a record run; /limit_state
  flag -1), and fraction_NAME = n_NAME over the cases with a physical
  outcome less the undefined ones: those have no outcome for this limit
  state. A case that ended at a model limit counts as exceeding every limit
  state (the isolator's capacity is gone);
- for each response figure (displacement_max, ...), its median and 16th and
  84th percentiles (FIGURE_p50, FIGURE_p16, FIGURE_p84) over the completed
  cases only, with the number of finite values used (FIGURE_n). A peak of a
  case that met a model limit is taken on the singular approach to it: it is
  never mixed in.

The percentiles are numpy's default ('linear': Hyndman and Fan's type 7,
interpolated between order statistics), or, with percentiles='lognormal',
those of a lognormal fitted to the values: exp(mean of ln y) for the median,
exp(mean -/+ standard deviation of ln y, n - 1 in its denominator) for the
16th and 84th (all three NaN where a value is <= 0 or none remains; the 16th
and 84th NaN where one remains, the median its value)."""
import io
import json
import math
import re
import warnings

import h5py
import numpy as np
import pandas as pd

# How a case ended, by the name in /summary/status's flag_meanings.
COMPLETED = "completed"
MODEL_LIMITS = ("rim", "no_fit", "slip", "liftoff", "lift_off")
# Figures of /summary that are the isolator's response, in this order when the file has them.
RESPONSE_FIGURES = ("displacement_max", "absolute_acceleration_max", "horizontal_force_max",
                    "residual_displacement", "rest_time", "theta_max", "reaction_normal_max",
                    "friction_needed_max")
# Inputs that vary between the cases without being a stripe: the record and its own factor.
RECORD_INPUTS = ("record", "record_factor")
PERCENTILES = ("linear", "lognormal")


def stripe_inputs(run):
    """The varied inputs that define the stripes of a suite, in the file's
    order (scale, rolling_resistance, ...): every varied input but the
    record and its factor."""
    return [n for n in run.varied_inputs() if n not in RECORD_INPUTS]


def limit_state_columns(run):
    """{name: per-case flag (float: 1 exceeded, 0 not, NaN undefined)} of
    the user limit states a file holds: each 1-D dataset of a /limit_state
    group (its name the limit state's; its flag -1, a figure undefined for
    the case, is NaN), and each /summary dataset named exceeded_NAME or
    NAME_exceeded (NaN undefined, any other nonzero value exceeded). Empty
    for a file without limit states."""
    columns = {}
    with h5py.File(run.path, "r") as f:
        group = f.get("limit_state")
        if isinstance(group, h5py.Group):
            # the group's case scale and coordinates (scale, record, ...) are not limit states
            coordinates = {c for item in group.values() for c in _text(item.attrs.get("coordinates", "")).split()}
            for name, item in group.items():
                if isinstance(item, h5py.Dataset) and item.shape == (run.n_cases,) and name not in coordinates \
                        and _text(item.attrs.get("CLASS", "")) != "DIMENSION_SCALE":
                    columns[name] = limit_state_flags(item[()])
        for name, item in f["summary"].items():
            if not isinstance(item, h5py.Dataset) or item.shape != (run.n_cases,):
                continue
            if name.startswith("exceeded_"):
                columns[name[len("exceeded_"):]] = limit_state_flags(item[()])
            elif name.endswith("_exceeded"):
                columns[name[:-len("_exceeded")]] = limit_state_flags(item[()])
    return columns


def check_limit_state(run, name):
    """NotAnEllrollFile where the file has no limit state `name` (the
    model's limits, MODEL_LIMIT_STATE, or one of limit_state_columns)."""
    known = [MODEL_LIMIT_STATE, *limit_state_columns(run)]
    if name not in known:
        from .reader import NotAnEllrollFile
        raise NotAnEllrollFile(f"{run.path}: no limit state {name} (known: {', '.join(sorted(known))})")


def _text(value):
    return value.decode() if isinstance(value, bytes) else str(value)


# /limit_state's flag of a case whose figure is undefined (its flag_values -1 0 1)
UNDEFINED_FLAG = -1


def limit_state_flags(values):
    """Per-case flags as floats: 1 exceeded, 0 not, NaN undefined (a
    float NaN, an integer UNDEFINED_FLAG); booleans as 1 and 0."""
    values = np.asarray(values)
    if values.dtype.kind == "f":
        return np.where(np.isnan(values), np.nan, (values != 0).astype(float))
    if values.dtype.kind in "iu":
        return np.where(values == UNDEFINED_FLAG, np.nan, (values != 0).astype(float))
    return values.astype(bool).astype(float)


def response_figures(run):
    """The response figures of RESPONSE_FIGURES the file holds, one value per case."""
    present = set(run.summary_figures)
    return [n for n in RESPONSE_FIGURES if n in present and run.summary(n).ndim == 1]


class PartOfTheCampaign(UserWarning):
    """Suite statistics or fragilities of a file that holds only part of its
    campaign's cases (a shard's file, an unfinished run's): over those only."""


def part_of_the_campaign(run):
    """A line saying that the file holds only part of its campaign's cases
    (a shard, or cases not run yet), or None for a whole campaign."""
    total = run.attrs.get("n_cases_total")
    total = int(np.ravel(total)[0]) if total is not None and np.size(total) else run.n_cases
    finished = int(np.sum(np.array(run.status_names()) != "pending"))
    if finished >= total:
        return None
    shard = str(run.attrs.get("shard", "0/1"))
    why = (f"shard {shard} (merge the shards first: ellroll merge)" if shard != "0/1" else
           "an unfinished run (finish it: ellroll run --resume)")
    return f"{run.path}: over {finished} of the campaign's {total} cases only: {why}"


def _warn_part(run):
    note = part_of_the_campaign(run)
    if note:
        warnings.warn(note, PartOfTheCampaign, stacklevel=3)


def suite_statistics(run, figures=None, exceeded=None, percentiles="linear"):
    """The per-stripe statistics of an ellroll file (see the module's text)
    as a DataFrame, one row per stripe, sorted by the stripe inputs.
    `figures`: the response figures (default: response_figures(run));
    `exceeded`: {name: per-case bool, or float with NaN where undefined}
    user limit states added to those in
    the file (limit_state_columns). df.attrs holds 'units' (per column),
    'percentiles' (the definition) and 'stripe_inputs'."""
    _warn_part(run)
    figures = response_figures(run) if figures is None else list(figures)
    names = stripe_inputs(run)
    inputs = {n: run.input_column(n).astype(float) for n in names}
    states = limit_state_columns(run)
    states.update(exceeded or {})
    table = stripe_statistics(inputs, run.status_names(), {f: run.summary(f).astype(float) for f in figures},
                              states, percentiles)
    units = {n: run.input_units(n) for n in names}
    units.update({f"{f}_{q}": run.units(f"summary/{f}") for f in figures for q in ("p16", "p50", "p84")})
    table.attrs["units"] = {c: units.get(c, "1") for c in table.columns}
    return table


def unique_keys(keys):
    """The distinct rows of a table of stripe keys in np.unique's order,
    all NaN in one place taken as one value (np.unique keeps each NaN row)."""
    seen = {tuple(None if np.isnan(v) else float(v) for v in row) for row in keys}
    ordered = sorted(seen, key=lambda row: tuple((v is None, 0.0 if v is None else v) for v in row))
    return [np.array([np.nan if v is None else v for v in row], dtype=float) for row in ordered]


def stripe_statistics(inputs, status, figures, exceeded=None, percentiles="linear"):
    """The per-stripe statistics of a table of cases: `inputs` {name:
    per-case value} (the stripe inputs), `status` per-case names, `figures`
    {name: per-case value}, `exceeded` {name: per-case bool, or 1/0/NaN
    (NaN: the figure undefined for the case)}. Returns the
    DataFrame of suite_statistics (without units)."""
    if percentiles not in PERCENTILES:
        raise ValueError(f"percentiles must be one of {', '.join(PERCENTILES)}, not {percentiles!r}")
    status = np.asarray(status, dtype=str)
    n = status.size
    exceeded = {k: limit_state_flags(v) for k, v in (exceeded or {}).items()}
    figures = {k: np.asarray(v, dtype=float) for k, v in figures.items()}
    for what, columns in (("input", inputs), ("figure", figures), ("limit state", exceeded)):
        for name, column in columns.items():
            if np.shape(column) != (n,):
                raise ValueError(f"{what} {name}: {np.shape(column)} values for {n} cases")
    completed = status == COMPLETED
    limit = np.isin(status, MODEL_LIMITS)
    keys = np.stack([np.asarray(v, dtype=float) for v in inputs.values()], axis=1) if inputs else np.zeros((n, 0))
    rows = []
    for key in unique_keys(keys):
        mask = np.all((keys == key) | (np.isnan(keys) & np.isnan(key)), axis=1)
        inside, beyond = mask & completed, mask & limit
        known = inside.sum() + beyond.sum()
        row = dict(zip(inputs, (float(v) for v in key)))
        row.update(n_cases=int(mask.sum()), n_completed=int(inside.sum()), n_limit=int(beyond.sum()))
        for name in MODEL_LIMITS:
            if name in status:
                row[f"n_{name}"] = int(np.sum(mask & (status == name)))
        row["n_unresolved"] = int(mask.sum() - known)
        row["fraction_limit"] = beyond.sum() / known if known else math.nan
        for name, flags in exceeded.items():
            hit = int(np.sum(inside & (flags == 1)) + beyond.sum())
            undefined = int(np.sum(inside & np.isnan(flags)))
            row[f"n_{name}"] = hit
            row[f"n_undefined_{name}"] = undefined
            row[f"fraction_{name}"] = hit / (known - undefined) if known > undefined else math.nan
        for name, values in figures.items():
            chosen = values[inside]
            chosen = chosen[np.isfinite(chosen)]
            row[f"{name}_n"] = int(chosen.size)
            row[f"{name}_p16"], row[f"{name}_p50"], row[f"{name}_p84"] = _percentiles(chosen, percentiles)
        rows.append(row)
    columns = list(inputs) + ["n_cases", "n_completed", "n_limit"]
    table = pd.DataFrame(rows, columns=list(dict.fromkeys(columns + [c for r in rows for c in r])))
    table.attrs["percentiles"] = percentiles
    table.attrs["stripe_inputs"] = list(inputs)
    return table


def _percentiles(values, definition):
    """16th, 50th and 84th percentiles of values (NaN where there are none)."""
    if definition == "linear":
        if values.size == 0:
            return math.nan, math.nan, math.nan
        return tuple(float(q) for q in np.percentile(values, [16, 50, 84]))
    if values.size == 0 or np.any(values <= 0):
        return math.nan, math.nan, math.nan
    logs = np.log(values)
    mean = logs.mean()
    if values.size == 1:          # the sample's spread is undefined, its median not
        return math.nan, math.exp(mean), math.nan
    spread = logs.std(ddof=1)
    return math.exp(mean - spread), math.exp(mean), math.exp(mean + spread)


PERCENTILE_TEXT = {"linear": "numpy's linear percentiles (Hyndman-Fan type 7)",
                   "lognormal": "a lognormal fitted to the values: exp(mean ln y -/+ sd ln y)"}


def format_suite(table, fmt="table", path=""):
    """suite_statistics's table as text (the counts, then a column per
    figure: median [16th, 84th] (values used); units below the names), CSV (one header row) or JSON ({file, percentiles, units,
    stripes}, NaN as null)."""
    units = table.attrs.get("units", {})
    if fmt == "json":
        stripes = [{k: _json_value(v) for k, v in row.items()} for row in table.to_dict(orient="records")]
        return json.dumps({"file": str(path), "percentiles": table.attrs.get("percentiles", "linear"),
                           "stripe_inputs": table.attrs.get("stripe_inputs", []),
                           "units": {c: units.get(c, "1") for c in table.columns}, "stripes": stripes},
                          indent=1, allow_nan=False)
    if fmt == "csv":
        out = io.StringIO()
        table.to_csv(out, index=False, lineterminator="\n", na_rep="NaN")     # as the per-case CSV (docs/output.md)
        return out.getvalue()
    if fmt != "table":
        raise ValueError(f"format must be table, csv or json, not {fmt!r}")
    figures = [c[:-4] for c in table.columns if c.endswith("_p50")]
    per_figure = {c for f in figures for c in (f"{f}_n", f"{f}_p16", f"{f}_p50", f"{f}_p84")}
    keys = [c for c in table.columns if c not in per_figure]
    cells = [[_fmt(v) for v in table[k]] for k in keys]
    heads = [[k, units.get(k, "1")] for k in keys]
    for f in figures:           # one column a figure: median [16th, 84th] (values used)
        cells.append([f"{_fmt(m)} [{_fmt(lo)}, {_fmt(hi)}] ({n})" for m, lo, hi, n in
                      zip(table[f"{f}_p50"], table[f"{f}_p16"], table[f"{f}_p84"], table[f"{f}_n"])])
        heads.append([f, units.get(f"{f}_p50", "1")])
    widths = [max(len(h[0]), len(h[1]), *(len(c) for c in column)) for h, column in zip(heads, cells)]
    lines = ["  ".join(h[i].rjust(w) for h, w in zip(heads, widths)) for i in (0, 1)]
    lines += ["  ".join(c.rjust(w) for c, w in zip(row, widths)) for row in zip(*cells)]
    definition = PERCENTILE_TEXT[table.attrs.get("percentiles", "linear")]
    notes = [f"each figure: median [16th, 84th percentile] (values used), {definition}, over the completed "
             "cases only;",
             "fraction_limit = n_limit / (n_completed + n_limit): cases that ended at a model limit "
             "(rim, no_fit, slip, liftoff); n_unresolved (never run or a numerical failure) left out;",
             "fraction_NAME = n_NAME / (n_completed + n_limit - n_undefined_NAME): a case whose figure is "
             "undefined has no outcome for the limit state"]
    return "\n".join(lines + [""] + notes) + "\n"


def _json_value(value):
    if isinstance(value, (np.integer,)):
        return int(value)
    if isinstance(value, (float, np.floating)):
        return None if value != value else float(value)
    return value


def _fmt(value):
    if isinstance(value, (float, np.floating)):
        return f"{value:.6g}"
    return str(value)


# ---------------------------------------------------------------- fragility
MODEL_LIMIT_STATE = "model_limit"


class NoIntensityMeasure(ValueError):
    """The file holds no intensity measure of the name asked for."""


class NoStripes(ValueError):
    """No group of cases with the same design inputs spans two intensities:
    nothing to fit a fragility to."""


def intensity_measures(run):
    """{name: (per-case value, units)} of the intensity measures a file
    holds besides the scale: /case datasets named pga, pgv, pgd or sa_*
    (one value per case: the case's own, scaled motion), the columns of
    /summary/sa_linear_periods (sa_linear_periods_1, _2: Sa at the case's
    own periods), and /records
    datasets of those names (one value per record, named by /records/name
    or /records/record: the unscaled record's, so times the case's
    record_factor and scale, as PGA and Sa scale with the motion)."""
    found = {}
    with h5py.File(run.path, "r") as f:
        case = f.get("case")
        for name, item in (case.items() if isinstance(case, h5py.Group) else []):
            if _is_im(name) and isinstance(item, h5py.Dataset) and item.shape == (run.n_cases,):
                found[name] = (item[()].astype(float), _units(item))
        # Sa at each case's own small-oscillation periods: one column per mode
        item = f.get("summary/sa_linear_periods")
        if isinstance(item, h5py.Dataset) and item.shape == (run.n_cases, 2):
            for mode in range(2):
                found[f"sa_linear_periods_{mode + 1}"] = (item[:, mode].astype(float), _units(item))
        group = f.get("records")
        if isinstance(group, h5py.Group):
            key = next((k for k in ("name", "record") if k in group), None)
            if key is not None:
                names = [n.decode().strip() if isinstance(n, bytes) else str(n).strip() for n in group[key][()]]
                where = {n: i for i, n in enumerate(names)}
                records = run.record_names()
                factor = np.ones(run.n_cases)
                for name in ("record_factor", "scale"):
                    if name in run.inputs or f"case/{name}" in f:
                        factor = factor * run.input_column(name).astype(float)
                rows = np.array([where.get(r, -1) for r in records])
                for name, item in group.items():
                    if _is_im(name) and name not in found and isinstance(item, h5py.Dataset) \
                            and item.shape == (len(names),):
                        values = np.where(rows >= 0, item[()].astype(float)[np.maximum(rows, 0)], np.nan)
                        found[name] = (values * factor, _units(item))
    return found


def _is_im(name):
    name = name.lower()
    return name in ("pga", "pgv", "pgd") or name.startswith("sa_") or name.startswith("sa(")


def _units(item):
    units = item.attrs.get("units", "")
    return units.decode() if isinstance(units, bytes) else str(units)


def intensity(run, im="scale"):
    """(name, per-case value, units) of the intensity measure `im`: 'scale'
    (the record scale factor), or one the file holds by its name (pga,
    sa_1.0; any case), 'PGA', 'Sa(T)' (Sa at the case's own first period,
    sa_linear_periods_1, where the file has it; else the file's one Sa),
    'Sa(T2)' (at its second) or 'Sa(1.0)' (the Sa whose name or 'period'
    attribute gives that period). Raises
    NoIntensityMeasure naming what the file has."""
    if im.lower() == "scale":
        if "scale" not in run.inputs:
            raise NoIntensityMeasure(f"{run.path}: no scale in /case")
        return "scale", run.input_column("scale").astype(float), "1"
    found = intensity_measures(run)
    lower = {n.lower(): n for n in found}
    wanted = im.lower().replace(" ", "")
    name = lower.get(wanted)
    spelled = re.fullmatch(r"sa(?:\((t\d?|[^()]+)\)|_([^()]+))", wanted)
    if name is None and wanted.startswith("sa") and spelled is None:
        raise NoIntensityMeasure(f"{run.path}: {im} is not an intensity measure's name: Sa is spelled Sa(T), "
                                 "Sa(T2), Sa(1.0) or sa_1")
    if name is None and spelled is not None:
        sa = [n for n in found if n.lower().startswith("sa")]
        period = spelled[1] or spelled[2]
        own = {"": "sa_linear_periods_1", "t": "sa_linear_periods_1", "t1": "sa_linear_periods_1",
               "t2": "sa_linear_periods_2"}
        if period in own and own[period] in found:
            name = own[period]
        elif period in ("", "t"):
            name = sa[0] if len(sa) == 1 else None
        else:
            name = next((n for n in sa if _period(run, n) == _number(period)
                         or _number(n.lower()[3:].rstrip(")")) == _number(period)), None)
    if name is None:
        have = ", ".join(["scale"] + sorted(found))
        raise NoIntensityMeasure(
            f"{run.path}: no intensity measure {im} in this file (it has: {have}); intensity measures are read "
            "from /case or /records datasets named pga, pgv, pgd or sa_*; use --im scale")
    values, units = found[name]
    return name, values, units


def _number(text):
    try:
        return float(text.replace("p", "."))
    except ValueError:
        return math.nan


def _period(run, name):
    with h5py.File(run.path, "r") as f:
        for group in ("case", "records"):
            item = f.get(f"{group}/{name}")
            if item is not None and "period" in item.attrs:
                return float(np.asarray(item.attrs["period"]).ravel()[0])
    return math.nan


def fragility_points(im_values, status, exceeded=None):
    """The binomial points of a fragility fit from per-case arrays: the
    distinct positive intensities x, the cases with a physical outcome at
    each (n: completed or at a model limit) and how many of them exceeded
    (z: ended at a model limit, or flagged in `exceeded`). Unresolved cases
    (never run, numerical failure), completed cases whose figure is
    undefined (NaN in `exceeded`) and NaN intensities are left out."""
    x = np.asarray(im_values, dtype=float)
    status = np.asarray(status, dtype=str)
    limit = np.isin(status, MODEL_LIMITS)
    flags = limit_state_flags(exceeded) if exceeded is not None else np.zeros(x.shape)
    known = (limit | ((status == COMPLETED) & ~np.isnan(flags))) & np.isfinite(x) & (x > 0)
    hit = limit | (flags == 1)
    levels = np.unique(x[known])
    n = np.array([np.sum(known & (x == v)) for v in levels])
    z = np.array([np.sum(known & hit & (x == v)) for v in levels])
    return levels, n, z


def suite_fragility(run, im="scale", bootstrap=0, seed=0, exceeded=None):
    """Lognormal fragilities of a suite (fragility.fit_stripes: maximum
    likelihood of the binomial counts, parametric bootstrap for 5-95 %
    intervals): one per limit state (the model's limits, then each user
    limit state) and per value of the swept design inputs other than the
    scale. Returns (DataFrame, per-row details): the table has the design
    inputs, limit_state, im, units, theta and its interval, beta and its
    interval, n_points, n_known, n_exceeded, n_undefined (the completed
    cases whose figure is undefined, left out) and a note where no fit exists
    (every case exceeds, none does) or says the outcomes separate;
    the details hold the points (x, n, z), the fit (or None) and the
    per-case masks for drawing."""
    from .fragility import fit_stripes, separating_step
    _warn_part(run)
    im_name, x, units = intensity(run, im)
    names = [n for n in stripe_inputs(run) if n != "scale"]
    keys = np.stack([run.input_column(n).astype(float) for n in names], axis=1) if names else \
        np.zeros((run.n_cases, 0))
    status = np.array(run.status_names())
    states = {MODEL_LIMIT_STATE: None}
    states.update(limit_state_columns(run))
    states.update(exceeded or {})
    groups = np.unique(keys, axis=0)
    spans = [np.unique(x[np.all(keys == key, axis=1) & np.isfinite(x) & (x > 0)]).size for key in groups]
    if max(spans, default=0) < 2:
        raise NoStripes(
            f"{run.path}: no stripes to fit a fragility to: none of its {len(groups)} groups of cases with the "
            f"same design inputs ({', '.join(names) or 'none varied'}) spans two intensities ({im_name}); a "
            "fragility needs the same isolator at several intensities (a suite: &record groups and a sweep of "
            "scale, docs/isolator.md)")
    rows, details = [], []
    physical = np.isin(status, MODEL_LIMITS) | (status == COMPLETED)
    for state, flags in states.items():
        for key in groups:
            cases = np.all(keys == key, axis=1)
            levels, n, z = fragility_points(x[cases], status[cases], None if flags is None else flags[cases])
            undefined = 0 if flags is None else int(np.sum(
                cases & (status == COMPLETED) & np.isnan(limit_state_flags(flags)) & np.isfinite(x) & (x > 0)))
            row = dict(zip(names, (float(v) for v in key)))
            row.update(limit_state=state, im=im_name, units=units, theta=math.nan, theta_low=math.nan,
                       theta_high=math.nan, beta=math.nan, beta_low=math.nan, beta_high=math.nan,
                       n_points=int(levels.size), n_known=int(n.sum()), n_exceeded=int(z.sum()),
                       n_undefined=undefined, note="")
            fit = None
            if n.sum() == 0 and undefined:
                row["note"] = "no case with a defined figure"
            elif n.sum() == 0:
                row["note"] = "no case with a physical outcome"
            elif z.sum() == 0:
                row["note"] = "no case exceeds: no fit"
            elif z.sum() == n.sum():
                row["note"] = "every case exceeds: no fit"
            else:
                fit = fit_stripes(levels, n, z, bootstrap=bootstrap, seed=seed)
            if fit is not None and not math.isfinite(fit.theta):
                row["note"] = "no finite maximum: the exceedances do not grow with the intensity"
                fit = None
            if fit is not None:
                row.update(theta=fit.theta, beta=fit.beta, theta_low=fit.theta_interval[0],
                           theta_high=fit.theta_interval[1], beta_low=fit.beta_interval[0],
                           beta_high=fit.beta_interval[1])
                if separating_step(levels, n, z):
                    row["note"] = "the outcomes separate in the intensity: no finite maximum, beta -> 0"
            at_zero = int(np.sum(cases & physical & (x == 0)))
            if at_zero:
                # P(exceed | 0) = 0 in the lognormal model: no likelihood, so not in n_known
                zero_note = f"{at_zero} cases at intensity 0 left out (no likelihood)"
                row["note"] = f"{row['note']}; {zero_note}" if row["note"] else zero_note
            rows.append(row)
            details.append(dict(row=row, x=levels, n=n, z=z, fit=fit, cases=cases,
                                exceeded=None if flags is None else flags))
    table = pd.DataFrame(rows)
    table.attrs.update(im=im_name, units=units, design_inputs=names, bootstrap=bootstrap)
    return table, details


def format_fragility(table, fmt="table", path=""):
    """suite_fragility's table as text, CSV or JSON (NaN as null)."""
    if fmt == "json":
        fits = [{k: _json_value(v) for k, v in row.items()} for row in table.to_dict(orient="records")]
        return json.dumps({"file": str(path), "im": table.attrs.get("im"), "units": table.attrs.get("units"),
                           "bootstrap": table.attrs.get("bootstrap"), "interval": "5-95 %", "fits": fits},
                          indent=1, allow_nan=False)
    if fmt == "csv":
        out = io.StringIO()
        table.to_csv(out, index=False, lineterminator="\n", na_rep="nan")
        return out.getvalue()
    keys = list(table.columns)
    cells = [[_fmt(v) for v in table[k]] for k in keys]
    widths = [max(len(k), *(len(c) for c in column)) for k, column in zip(keys, cells)]
    lines = ["  ".join(k.rjust(w) for k, w in zip(keys, widths))]
    lines += ["  ".join(c.rjust(w) for c, w in zip(row, widths)) for row in zip(*cells)]
    notes = ["P(exceed | IM = x) = Phi(ln(x / theta) / beta), fitted by maximum likelihood to the binomial "
             "counts; intervals 5-95 % of a parametric bootstrap"]
    return "\n".join(lines + [""] + notes) + "\n"
