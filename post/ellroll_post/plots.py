"""Figures of ellroll files, each drawn on given matplotlib Axes (or a Figure)."""
import os
import pathlib
import re

import numpy as np

from .geometry import energy_bound, surface_residual
from .reader import NotAnEllrollFile
from .suite import MODEL_LIMIT_STATE, MODEL_LIMITS, PERCENTILE_TEXT, check_limit_state, intensity, \
    limit_state_flags, suite_fragility, suite_statistics

# figure -> trajectory fields it cannot be drawn without
FIELD_NEEDS = {"trace": ("contact",), "nutation": ("nutation",), "reaction": ("reaction", "normal"),
               "energy": ("energy",), "spectrum": ("reaction", "base_acceleration")}
FIELD_NOTES = {"base_acceleration": "stored only when the cup moves: an &excitation"}
ISOLATOR_FIELDS = ("center", "base_acceleration")


def missing_fields(run, names):
    return [n for n in names if n not in run.fields]


def require(run, figure, case=None):
    """Raise NotAnEllrollFile with one line saying what `figure` lacks in
    this file and what to do: the trajectory fields to add to &output
    fields, or a case that has no samples (never run)."""
    missing = missing_fields(run, FIELD_NEEDS.get(figure, ()))
    if missing:
        notes = "".join(f"; {n} is {FIELD_NOTES[n]}" for n in missing if n in FIELD_NOTES)
        stored = ", ".join(run.fields) or "none"
        raise NotAnEllrollFile(
            f"{run.path}: the {figure} figure needs the trajectory field{_s(missing)} {', '.join(missing)}, "
            f"not stored in this file (it stores: {stored}){notes}; add "
            f"{', '.join(repr(n) for n in missing)} to &output fields (or fields = 'all') and run it again")
    if case is not None:
        require_samples(run, case, FIELD_NEEDS.get(figure, ())[:1])


def require_samples(run, case, fields=()):
    """A case that was never run (invalid, pending) or has no finite sample
    of `fields` has nothing to draw: say so, with what to do."""
    case = run.case_index(case)
    status = run.status_name(case)
    if status == "invalid":
        raise NotAnEllrollFile(f"{run.path}: case {case} was never run (status invalid: its inputs were rejected; "
                               "`ellroll check` on the input says why): no samples to draw; choose another --case")
    if status == "pending":
        raise NotAnEllrollFile(f"{run.path}: case {case} was never run (status pending: an unfinished file; "
                               "`ellroll run --resume` finishes it): no samples to draw")
    for field in fields:
        values = run.trajectory(field, case)
        if not np.any(np.isfinite(values)):
            raise NotAnEllrollFile(f"{run.path}: case {case} ({status}) has no finite sample of {field}")


def has_samples(run, case, fields=()):
    try:
        require_samples(run, case, fields)
    except NotAnEllrollFile:
        return False
    return True


def _s(items):
    return "s" if len(items) != 1 else ""


def cup_moves(run, case=None):
    """Whether the cup of a case is shaken (&excitation kind other than 'none')."""
    try:
        kind = run.case_input("excitation_kind", case)
    except NotAnEllrollFile:
        return "base_acceleration" in run.fields
    return str(kind).strip() not in ("", "none")


def _note(ax, text):
    """A legend entry without a symbol: what the figure leaves out, and why."""
    ax.plot([], [], " ", label=text)


def _case_label(run, case):
    return f"case {run.case_index(case)}: {run.status_name(case)}"


def name_text(name):
    """A file or record name as text: bytes that are not UTF-8 (a name
    from an old archive) shown as \\xNN."""
    return os.fsencode(name).decode("utf-8", "backslashreplace")


def _drawn_as_is(text):
    """Text that matplotlib draws as it is: a '$' starts no mathtext."""
    return text.replace("$", r"\$")


def _file_label(run):
    return _drawn_as_is(name_text(pathlib.Path(run.path).name))


def energy_bound_level(run, case=None):
    """Centre height the energy integral allows when the spin about the normal
    keeps its initial value: m g z_C = E0 - J (omega0 . n0)^2 / 2."""
    m, g, radius = run.case_input("mass", case), run.case_input("g", case), run.case_input("radius", case)
    k = run.case_input("inertia_factor", case)
    omega0 = run.trajectory("omega", case)[0]
    n0 = run.trajectory("normal", case)[0]
    energy0 = run.trajectory("energy", case)[0]
    return (energy0 - 0.5 * k * m * radius**2 * (omega0 @ n0)**2) / (m * g)


def plot_trace(ax, run, case=None):
    """Fig. 2: the contact point's trace in the XY plane (coloured by regime,
    rolling or sliding, when the field regime is stored), the cup's rim, the
    energy bound (the curve the ball does not cross; on a fixed cup, with
    the fields energy, omega and normal stored: otherwise a note says why
    it is left out), start and end."""
    case = run.case_index(case)              # (None: the file's first case)
    require(run, "trace", case)
    contact = run.trajectory("contact", case)
    valid = np.isfinite(contact[:, 0])
    x, y = contact[valid, 0], contact[valid, 1]
    a, b, c = (run.case_input(n, case) for n in "abc")
    phi = np.linspace(0, 2 * np.pi, 400)
    ax.plot(a * np.cos(phi), b * np.sin(phi), color="0.6", lw=1, label="rim of the cup (z = c)")
    bound_needs = missing_fields(run, ("energy", "omega", "normal"))
    if cup_moves(run, case):
        _note(ax, "no energy bound: the cup moves (its work changes the energy)")
    elif bound_needs:
        _note(ax, f"no energy bound: needs the field{_s(bound_needs)} {', '.join(bound_needs)}")
    else:
        bx, by = energy_bound(a, b, c, run.case_input("radius", case), energy_bound_level(run, case))
        if np.any(np.isfinite(bx)):
            ax.plot(bx, by, color="C1", lw=1, ls="--", label="energy bound (spin about n kept)")
        else:
            _note(ax, "no energy bound: the energy reaches the rim")
    if "regime" in run.fields:
        _plot_by_regime(ax, x, y, run.trajectory("regime", case)[valid])
    else:
        ax.plot(x, y, lw=0.7, color="C0", label="contact point")
    ax.plot(x[:1], y[:1], "o", color="C2", label="start")
    ax.plot(x[-1:], y[-1:], "s", color="C3", label=f"end S, t = {run.time[valid][-1]:g} s")
    ax.set_aspect("equal")
    ax.set_xlabel("X, m")
    ax.set_ylabel("Y, m")
    ax.set_title(f"Contact point trace ({_case_label(run, case)})")
    ax.legend(loc="upper center", bbox_to_anchor=(0.5, -0.18), ncol=3, fontsize="small", frameon=False)
    return ax


REGIME_COLOURS = {0: ("C0", "contact point, rolling"), 1: ("C4", "contact point, sliding")}


def _plot_by_regime(ax, x, y, regime):
    """The trace in one colour per regime (the field regime: 0 rolling, 1
    sliding); each piece runs on to the first sample of the next, so that
    the path stays whole where the regime turns."""
    for value, (colour, label) in REGIME_COLOURS.items():
        inside = regime == value
        inside[1:] |= inside[:-1]
        if np.any(regime == value):
            ax.plot(np.ma.masked_where(~inside, x), np.ma.masked_where(~inside, y), lw=0.7, color=colour,
                    label=label)


def plot_nutation(ax, run, case=None):
    """Fig. 3: the nutation angle Theta against time, theta_max and the
    measured nutation period annotated."""
    case = run.case_index(case)              # (None: the file's first case)
    require(run, "nutation", case)
    theta = run.trajectory("nutation", case)
    t = run.time
    ax.plot(t, theta, lw=0.8, color="C0")
    ax.set_xlabel("t, s")
    ax.set_ylabel(r"$\Theta$, rad")
    theta_max = run.summary("theta_max", case)
    period = run.summary("nutation_period", case) if "nutation_period" in run.summary_names else np.nan
    ax.axhline(theta_max, color="0.6", lw=0.8, ls="--")
    text = rf"$\Theta_{{max}}$ = {theta_max:.4f} rad ({np.degrees(theta_max):.2f}$^\circ$)"
    if np.isfinite(period):
        text += f", nutation period {period:.4f} s"
    ax.annotate(text, xy=(0.01, 0.98), xycoords="axes fraction", va="top", fontsize="small",
                bbox=dict(boxstyle="round", fc="white", ec="0.8"))
    ax.set_ylim(0, theta_max * 1.25 if theta_max > 0 else None)
    secondary = ax.secondary_yaxis("right", functions=(np.degrees, np.radians))
    secondary.set_ylabel(r"$\Theta$, deg")
    ax.set_title(f"Nutation angle ({_case_label(run, case)})")
    return ax


def reaction_parts(run, case=None):
    """Normal force N = F . n, friction |F - N n| and the friction coefficient needed."""
    force = run.trajectory("reaction", case)
    normal = run.trajectory("normal", case)
    n_force = np.sum(force * normal, axis=1)
    tangential = np.linalg.norm(force - n_force[:, None] * normal, axis=1)
    return n_force, tangential, tangential / n_force


def plot_reaction(axes, run, case=None):
    """Normal force F_n (the weight m g as a reference), friction force |F_t|
    and the friction coefficient needed |F_t| / F_n against time, each on its
    own axis (three Axes: the two forces differ by orders of magnitude);
    legends beside."""
    case = run.case_index(case)              # (None: the file's first case)
    require(run, "reaction", case)
    t = run.time
    n_force, tangential, mu = reaction_parts(run, case)
    weight = run.case_input("mass", case) * run.case_input("g", case)
    axes[0].plot(t, n_force, lw=0.8, label=r"normal force $F_n = \mathbf{F} \cdot \mathbf{n}$")
    axes[0].axhline(weight, color="0.5", ls="--", lw=0.8, label=f"weight $m g$ = {weight:g} N")
    axes[0].set_ylabel(r"$F_n$, N")
    axes[0].set_title(f"Force of the cup on the ball, {_file_label(run)} ({_case_label(run, case)})")
    axes[1].plot(t, tangential, lw=0.8, color="C1", label=r"friction force $|F_t|$")
    axes[1].set_ylabel(r"$|F_t|$, N")
    axes[2].plot(t, mu, lw=0.8, color="C2", label=r"friction coefficient needed $|F_t| / F_n$")
    mu_limit = run.case_input("mu", case)
    if np.isfinite(mu_limit):
        axes[2].axhline(mu_limit, color="C3", ls="--", lw=0.8, label=rf"friction limit $\mu$ = {mu_limit:g}")
    axes[2].set_ylabel(r"$|F_t| / F_n$, 1")
    axes[2].set_xlabel(r"$t$, s")
    for ax in axes:
        ax.legend(fontsize="small", loc="upper left", bbox_to_anchor=(1.01, 1.0), frameon=False)
    return axes


def cup_work(run, case=None):
    """The work W(t) done on the ball in the cup's frame by the moving cup
    (the inertial force -m a_base on the centre), W = -m int a_base . dC,
    by the trapezoid rule over the stored samples (its error is of the
    order of the output interval squared); None without the fields center
    and base_acceleration. On a cup without rolling resistance E - E0 = W."""
    if missing_fields(run, ISOLATOR_FIELDS):
        return None
    center = run.trajectory("center", case)
    base = run.trajectory("base_acceleration", case)
    steps = -run.case_input("mass", case) * np.sum((base[1:] + base[:-1]) / 2 * np.diff(center, axis=0), axis=1)
    return np.concatenate([[0.0], np.cumsum(steps)])


def plot_energy(ax, run, case=None):
    """On a fixed cup: the relative energy error and the largest constraint
    error so far against time (log). On a moving cup the energy changes by
    the cup's work, which is no error: the energy change E - E0 and, with
    the fields center and base_acceleration, the cup's work W against time
    (linear), the largest constraint error and |E - E0 - W| noted."""
    case = run.case_index(case)              # (None: the file's first case)
    require(run, "energy", case)
    t = run.time
    tiny = 1e-18
    energy = run.trajectory("energy", case)
    residual = None
    if "contact" in run.fields:
        a, b, c = (run.case_input(n, case) for n in "abc")
        residual = surface_residual(a, b, c, run.trajectory("contact", case))
    resistance = run.case_input("rolling_resistance", case)
    if cup_moves(run, case):
        work = cup_work(run, case)
        ax.plot(t, energy - energy[0], lw=0.9, label=r"energy change $E - E_0$")
        drawn = "Energy change"
        if work is not None:
            ax.plot(t, work, lw=0.9, ls="--", color="C1",
                    label=r"work of the moving cup $W = -m \int \mathbf{a}_\mathrm{base} \cdot d\mathbf{C}$")
            drawn = "Energy change and the moving cup's work"
            if not resistance > 0:
                balance = np.nanmax(np.abs(energy - energy[0] - work)) / abs(energy[0])
                _note(ax, rf"largest $|E - E_0 - W| / |E_0|$ = {balance:.2g} (trapezoid rule over the samples)")
            else:
                _note(ax, r"$E - E_0 - W$: the rolling resistance's work")
        else:
            _note(ax, "the cup's work needs the fields " + ", ".join(missing_fields(run, ISOLATOR_FIELDS)))
        if residual is not None:
            _note(ax, f"largest constraint error {np.nanmax(residual):.2g}")
        ax.set_ylabel(r"$E - E_0$, J")
    else:
        change = np.maximum(np.abs(energy / energy[0] - 1), tiny)
        if resistance > 0:
            ax.semilogy(t, change, lw=0.8, label=r"energy change $|E - E_0| / E_0$ (the rolling resistance's work)")
            drawn = "Energy change (rolling resistance)"
        else:
            ax.semilogy(t, change, lw=0.8, label=r"energy error $|E - E_0| / E_0$")
            drawn = "Energy error"
        if residual is not None:
            # round-off that changes sign every sample would fill the plot as a
            # block: its running maximum is the line to read
            valid = np.isfinite(residual)
            envelope = np.full_like(residual, np.nan)
            envelope[valid] = np.maximum.accumulate(np.maximum(residual[valid], tiny))
            ax.semilogy(t, envelope, lw=0.8,
                        label=r"constraint error $|(x/a)^2+(y/b)^2+((z-c)/c)^2-1|$, largest so far")
            drawn += " and constraint error"
        else:
            _note(ax, "no constraint error: needs the field contact")
        ax.set_ylabel("relative error, 1 (zero shown as 1e-18)")
    ax.set_xlabel(r"$t$, s")
    ax.set_title(f"{drawn}, {_file_label(run)} ({_case_label(run, case)})")
    ax.legend(fontsize="small", loc="upper left", bbox_to_anchor=(0.0, -0.15), frameon=False)
    return ax


MAX_LINES = 12          # lines in a sweep plot, one per value of the other inputs; more: points


def plot_sweep(fig, run, x_names, y_names):
    """Summary quantities against one swept input (lines, one per value of
    any other swept input) or two (heat map); cases that ended early marked."""
    status = np.array(run.status_names())
    early = status != "completed"
    axes = fig.subplots(len(y_names), 1, squeeze=False)[:, 0]
    for ax, y_name in zip(axes, y_names):
        y = run.summary(y_name).astype(float)
        if y.ndim > 1:
            y = y[:, 0]
        units = run.units(f"summary/{y_name}")
        if len(x_names) == 1:
            x = run.input_column(x_names[0])
            others = [n for n in run.swept_inputs() if n not in x_names]
            groups = {(): np.ones(len(x), bool)}
            if others:
                keys = np.stack([run.input_column(n) for n in others], axis=1)
                distinct = np.unique(keys, axis=0)
                if len(distinct) <= MAX_LINES:
                    groups = {tuple(k): np.all(keys == k, axis=1) for k in distinct}
            sampled = len(groups) == 1 and bool(others)
            if sampled:                           # sampled, or too many lines: every case a point
                done = ~early
                ax.plot(x[done], y[done], "o", ms=2, alpha=max(0.05, min(0.6, 1000 / len(x))), mew=0, color="C0",
                        label=f"{_count(done.sum(), 'completed case')} ({', '.join(others)} vary too)")
                _quantile_band(ax, x[done], y[done])
            else:
                for key, mask in groups.items():
                    order = np.argsort(x[mask])
                    label = ", ".join(f"{n} = {v:g}" for n, v in zip(others, key)) or None
                    ax.plot(x[mask][order], y[mask][order], marker="o", ms=3, lw=1, label=label)
            _mark_early(ax, x, y, status)
            ax.set_xlabel(f"{x_names[0]}, {run.input_units(x_names[0])}")
            if len(groups) > 1 or np.any(early) or sampled:
                _legend_beside(ax)
        else:
            xa, xb = run.input_column(x_names[0]), run.input_column(x_names[1])
            ua, ub = np.unique(xa), np.unique(xb)
            if len(ua) * len(ub) <= 4 * len(y):       # a grid of the two inputs: a heat map
                grid = np.full((len(ub), len(ua)), np.nan)
                grid[np.searchsorted(ub, xb), np.searchsorted(ua, xa)] = y
                mesh = ax.pcolormesh(ua, ub, grid, shading="nearest")
            else:                                      # sampled: each completed case a coloured point
                done = ~early
                mesh = ax.scatter(xa[done], xb[done], c=y[done], s=8, linewidths=0)
            fig.colorbar(mesh, ax=ax, label=f"{y_name}, {units}")
            _mark_early(ax, xa, xb, status)
            if np.any(early):
                _legend_beside(ax, title="status")
            ax.set_xlabel(f"{x_names[0]}, {run.input_units(x_names[0])}")
            ax.set_ylabel(f"{x_names[1]}, {run.input_units(x_names[1])}")
        if len(x_names) == 1:
            ax.set_ylabel(f"{y_name}, {units}")
        ax.grid(alpha=0.3)
    axes[0].set_title(f"{', '.join(y_names)} ({run.n_cases} cases)", fontsize="medium")
    return axes


BAND_MIN_CASES = 80     # completed cases for a median and 10-90 % band (5 bins of 16)


def band_bins(n):
    """Bins of the median and band over n completed cases: about 20 cases a
    bin, 5 to 30 bins."""
    return int(min(max(n // 20, 5), 30))


def _quantile_band(ax, x, y):
    """Median and 10-90 % band of y in bins of x: the trend a cloud of many
    sampled cases hides; with fewer than BAND_MIN_CASES finite cases a note
    says why there is none."""
    finite = np.isfinite(x) & np.isfinite(y)
    x, y = x[finite], y[finite]
    if len(x) < BAND_MIN_CASES:
        _note(ax, f"no median or 10-90 % band: {_count(len(x), 'completed case')}, "
                  f"{BAND_MIN_CASES} needed")
        return
    bins = band_bins(len(x))
    edges = np.linspace(x.min(), x.max(), bins + 1)
    which = np.clip(np.searchsorted(edges, x, side="right") - 1, 0, bins - 1)
    centres = (edges[:-1] + edges[1:]) / 2
    # a bin of fewer than 5 cases has no 10th or 90th percentile worth drawing
    q = np.array([np.percentile(y[which == b], [10, 50, 90]) if np.sum(which == b) >= 5 else [np.nan] * 3
                  for b in range(bins)])
    ax.fill_between(centres, q[:, 0], q[:, 2], color="k", alpha=0.15, lw=0,
                    label=f"10-90 % of completed cases ({bins} bins)")
    ax.plot(centres, q[:, 1], color="k", lw=1.5, label="median of completed cases")


def _count(n, noun):
    """'1 case', '2 cases'."""
    return f"{n} {noun}" + ("" if n == 1 else "s")


def _mark_early(ax, x, y, status):
    """Each way a case ended early, its own grey marker and legend entry
    (names beside every point would bury a campaign's figure; grey, thin
    and open, they leave the completed cases' colours readable)."""
    for marker, name in zip("xs^vDP*", sorted(set(status[status != "completed"]))):
        ended = status == name
        label = f"not run yet: {ended.sum()}" if name == "pending" else f"ended: {name}"
        ax.plot(x[ended], y[ended], marker, mfc="none", mec="0.45", mew=0.8, ms=4, ls="none", label=label)


def _legend_beside(ax, **options):
    """A legend right of the axes: never over the data, and no search for a
    free place among 10^5 points."""
    ax.legend(fontsize="x-small", title_fontsize="x-small", loc="upper left", bbox_to_anchor=(1.01, 1.0),
              frameon=False, **options)


def plot_workprecision(axes, points):
    """Error against wall time and against RHS evaluations, per method.
    points: {method: [(error, seconds, rhs_evaluations), ...]}"""
    for method, rows in sorted(points.items()):
        rows = np.array(sorted(rows, key=lambda r: r[1]), dtype=float)
        for ax, column in zip(axes, (1, 2)):
            ax.loglog(rows[:, column], rows[:, 0], marker="o", ms=4, label=method)
    axes[0].set_xlabel("wall time, s")
    axes[1].set_xlabel("right-hand side evaluations")
    for ax in axes:
        ax.set_ylabel("error of the contact point, m")
        ax.grid(True, which="both", alpha=0.3)
    # one legend for both panels (the same methods), outside them: never over a curve
    handles, labels = axes[0].get_legend_handles_labels()
    axes[0].figure.legend(handles, labels, loc="outside right upper", fontsize="small", frameon=False,
                          title="method")
    return axes


def linear_transmissibility(ratio, inertia_factor=0.4):
    """Transmissibility of the linearised rolling ball along a principal
    axis: |1 + k - k r^2| / ((1 + k) |1 - r^2|), r = f / f_n (docs/model.md);
    1 at low frequency, 0 at r^2 = (1 + k) / k, k / (1 + k) at high frequency."""
    ratio = np.asarray(ratio, float)
    k = inertia_factor
    return np.abs(1 + k - k * ratio**2) / ((1 + k) * np.abs(1 - ratio**2))


def mode_axes(run, case=None):
    """For each linear mode of /summary/linear_periods, the horizontal axes
    (0: x, 1: y) it moves the ball along: about the bottom of a cup without
    spin the modes lie along the principal axes, of periods
    2 pi sqrt((1 + k) (rho - R) / g) with rho = a^2/c or b^2/c (docs/model.md);
    each mode is matched to the nearer one. With an initial spin the modes
    couple both axes; so does a round cup (a = b)."""
    periods = run.summary("linear_periods", case)
    a, b, c = (run.case_input(n, case) for n in "abc")
    radius, k, g = (run.case_input(n, case) for n in ("radius", "inertia_factor", "g"))
    spin = np.asarray(run.case_input("omega", case), float)
    with np.errstate(invalid="ignore"):
        along = 2 * np.pi * np.sqrt((1 + k) * (np.array([a * a, b * b]) / c - radius) / g)
    if np.any(spin != 0) or a == b or not np.all(np.isfinite(along)):
        return [(0, 1)] * len(periods)
    return [(int(np.argmin(np.abs(along - period))),) for period in periods]


def excited_axes(run, case=None):
    """The horizontal axes (0: x, 1: y) along which a harmonic excitation shakes the cup."""
    amplitude = np.asarray(run.case_input("excitation_amplitude", case), float)
    return {i for i in (0, 1) if amplitude[i] != 0}


def log_frequency_axis(ax, low, high):
    """A log frequency axis labelled in plain numbers at every decade in
    [low, high], also at 2 and 5 times each decade where the span is three
    decades or less, and at every minor tick where it is under one (else
    one or no label would show)."""
    from matplotlib.ticker import FuncFormatter, LogLocator, NullFormatter
    ax.set_xscale("log")
    ax.set_xlim(low / 1.15, high * 1.15)
    decades = np.log10(high / low)
    ax.xaxis.set_major_locator(LogLocator(base=10, subs=(1.0,)))
    ax.xaxis.set_minor_locator(LogLocator(base=10, subs=np.arange(2, 10)))
    plain = FuncFormatter(lambda value, _: f"{value:g}")
    ax.xaxis.set_major_formatter(plain)
    if decades < 1:
        ax.xaxis.set_minor_formatter(plain)
    elif decades <= 3:
        ax.xaxis.set_minor_formatter(FuncFormatter(
            lambda value, _: f"{value:g}" if round(value / 10 ** np.floor(np.log10(value) + 1e-9)) in (2, 5) else ""))
    else:
        ax.xaxis.set_minor_formatter(NullFormatter())
    ax.tick_params(axis="x", which="minor", labelsize="small")


def require_transmissibility(run):
    """NotAnEllrollFile (one line naming the file) where its cases do not
    sweep the excitation frequency or hold no transmissibility."""
    if "excitation_frequency" not in run.swept_inputs():
        raise NotAnEllrollFile(f"{run.path}: needs a sweep of excitation_frequency "
                               "(&sweep name = 'excitation_frequency')")
    if not np.any(np.isfinite(run.summary("transmissibility"))):
        raise NotAnEllrollFile(f"{run.path}: no transmissibility in /summary (every case NaN): the "
                               "cup is not shaken harmonically (&excitation kind = 'harmonic')")


def plot_transmissibility(ax, run):
    """Transmissibility against the excitation frequency (log-log), with the
    linear resonance frequencies (/summary/linear_periods) of the modes the
    shaking excites marked, and the linear prediction for each.
    NotAnEllrollFile where the file has no such sweep (require_transmissibility)."""
    require_transmissibility(run)
    frequency = run.input_column("excitation_frequency")
    transmissibility = run.summary("transmissibility")
    order = np.argsort(frequency)
    ax.loglog(frequency[order], transmissibility[order], "o-", ms=3, lw=1, label="ellroll (measured)")
    periods = run.summary("linear_periods", 0)
    k = run.case_input("inertia_factor", 0)
    grid = np.geomspace(frequency.min(), frequency.max(), 400)
    shaken = excited_axes(run, 0)
    for mode, (period, axes_of_mode) in enumerate(zip(periods, mode_axes(run, 0))):
        if np.isfinite(period) and shaken & set(axes_of_mode):
            along = " and ".join("xy"[i] for i in axes_of_mode)
            ax.axvline(1 / period, color=f"C{mode + 1}", ls="--", lw=0.8,
                       label=f"linear resonance, mode {mode + 1} (along {along}): {1 / period:.4g} Hz")
            ax.loglog(grid, linear_transmissibility(grid * period, k), color=f"C{mode + 1}", lw=0.7, alpha=0.6,
                      label=f"linear prediction, mode {mode + 1}")
    ax.axhline(1, color="0.6", lw=0.6)
    log_frequency_axis(ax, frequency.min(), frequency.max())
    ax.set_xlabel("excitation frequency, Hz")
    ax.set_ylabel(r"transmissibility $|a_\mathrm{ball}| / |a_\mathrm{base}|$, 1")
    ax.set_title(f"Transmissibility, {_file_label(run)} ({run.n_cases} frequencies, shaken along "
                 f"{' and '.join('xy'[i] for i in sorted(shaken)) or 'no axis'})")
    ax.grid(True, which="both", alpha=0.3)
    ax.legend(fontsize="x-small", loc="upper left", bbox_to_anchor=(1.01, 1.0), frameon=False)
    return ax


SUITE_QUANTITIES = ("displacement_max", "absolute_acceleration_max")
LIMIT_COLOUR = "C3"


def tex_units(units):
    """A unit as mathtext where it needs it: m/s^2 -> m/s$^{2}$."""
    return re.sub(r"\^(-?\d+)", r"$^{\1}$", str(units))


def input_label(run, name):
    """An axis label for an input: its name and unit; the dimensionless
    scale of a suite is 'record scale factor'."""
    if name == "scale":
        return "record scale factor"
    units = run.input_units(name)
    return name if units in ("", "1") else f"{name}, {tex_units(units)}"


def input_value_label(run, name, value):
    """name = value unit, for a legend."""
    units = run.input_units(name)
    return f"{name} = {value:g}" + ("" if units in ("", "1") else f" {tex_units(units)}")


def spans_decades(values):
    """Whether positive values span more than a decade: a log axis then."""
    values = np.asarray(values, dtype=float)
    values = values[np.isfinite(values)]
    return values.size > 1 and values.min() > 0 and values.max() > 10 * values.min()


def suite_groups(run, table):
    """The stripe input along the x axis (scale if swept, else the first;
    None for a suite of one stripe), the other stripe inputs, and the groups
    of the table's rows: {tuple of their values: row mask}."""
    names = table.attrs["stripe_inputs"]
    x_name = "scale" if "scale" in names else (names[0] if names else None)
    others = [n for n in names if n != x_name]
    keys = table[others].to_numpy(dtype=float) if others else np.zeros((len(table), 0))
    groups = {tuple(k): np.all(keys == k, axis=1) for k in np.unique(keys, axis=0)} if len(table) else {}
    return x_name, others, groups


def plot_suite(axes, run, quantities=SUITE_QUANTITIES):
    """A record suite's response per stripe (suite.suite_statistics), one
    panel per figure in `quantities`: against the scale (or the first other
    stripe input), one colour per value of the other swept design inputs
    (labelled name = value unit): each completed record's value faint, the
    median and the 16-84 % band over the completed records only; per stripe
    the count of completed records over the cases (bottom), and where cases
    ended at a model limit a red x at the top with their count."""
    table = suite_statistics(run, figures=quantities)
    x_name, others, groups = suite_groups(run, table)
    status = np.array(run.status_names())
    completed = status == "completed"
    case_x = run.input_column(x_name).astype(float) if x_name else np.ones(run.n_cases)
    case_keys = (np.stack([run.input_column(n).astype(float) for n in others], axis=1) if others
                 else np.zeros((run.n_cases, 0)))
    x_all = table[x_name].to_numpy(dtype=float) if x_name else np.ones(len(table))
    records = sorted(set(run.record_names()) - {""})
    for ax, quantity in zip(axes, quantities):
        values = run.summary(quantity).astype(float)
        for g, (key, rows) in enumerate(groups.items()):
            colour = f"C{g % 10}" if len(groups) > 1 else "C0"
            if colour == LIMIT_COLOUR:
                colour = "C9"
            label = ", ".join(input_value_label(run, n, v) for n, v in zip(others, key))
            cases = completed & np.all(case_keys == np.array(key), axis=1)
            ax.plot(case_x[cases], values[cases], "o", ms=3, color=colour, alpha=0.3, mew=0)
            part = table[rows].sort_values(x_name) if x_name else table[rows]
            x = part[x_name].to_numpy(dtype=float) if x_name else np.ones(len(part))
            ax.plot(x, part[f"{quantity}_p50"], "o-", color=colour, lw=1.5, ms=4,
                    label=(f"{label}: " if label else "") + "median")
            ax.fill_between(x, part[f"{quantity}_p16"], part[f"{quantity}_p84"], color=colour, alpha=0.15, lw=0,
                            label=(f"{label}: " if label else "") + "16-84 %")
            _stripe_counts(ax, x, part, g, len(groups), colour)
        ax.plot([], [], "o", ms=3, color="0.5", alpha=0.5, mew=0, label="each completed record")
        limits = bool(table["n_limit"].any())
        if limits:
            ax.plot([], [], "x", color=LIMIT_COLOUR, mew=1.5, ls="none",
                    label="ended at a model limit (n of the stripe's cases); peak left out")
        _note(ax, "n/N at the foot: completed records / cases")
        if not table[f"{quantity}_n"].any():
            _note(ax, "no completed record: no median")
        if x_name:
            ax.set_xlabel(input_label(run, x_name))
            if spans_decades(x_all):
                ax.set_xscale("log")
        else:
            ax.set_xticks([1.0], ["all records"])
        finite = values[completed & np.isfinite(values)]
        if spans_decades(finite):
            ax.set_yscale("log")
        elif finite.size == 0:
            ax.set_ylim(0, 1)
        # room at the foot for the counts and at the top for the limit marks, one row a group
        _make_room(ax, 0.05 * len(groups) + 0.01, (0.06 * len(groups) + 0.02) if limits else 0.02)
        units = run.units(f"summary/{quantity}")
        ax.set_ylabel(quantity if units in ("", "1") else f"{quantity}, {tex_units(units)}")
        ax.grid(alpha=0.3, which="both" if ax.get_yscale() == "log" else "major")
        if ax is axes[-1]:
            _legend_beside(ax)
    axes[0].set_title(f"Record suite: {len(records)} records, {run.n_cases} cases; median and 16-84 % of the "
                      f"completed records ({PERCENTILE_TEXT[table.attrs['percentiles']].split(' (')[0]})",
                      fontsize="medium", loc="left")
    return axes


def _stripe_counts(ax, x, part, g, n_groups, colour):
    """Per stripe: completed / cases at the foot of the axes; where cases
    ended at a model limit, a red x at the top and their count below it,
    one row per group (in its colour)."""
    transform = ax.get_xaxis_transform()
    foot, top = 0.01 + 0.05 * (n_groups - 1 - g), 0.98 - 0.06 * g
    for xi, completed, cases, limit in zip(x, part["n_completed"], part["n_cases"], part["n_limit"]):
        ax.text(xi, foot, f"{completed}/{cases}", transform=transform, color=colour, fontsize="x-small",
                ha="center", va="bottom", gid="suite-count")
        if limit:
            ax.plot([xi], [top], "x", color=LIMIT_COLOUR, mew=1.5, ms=5, transform=transform, gid="suite-limit")
            ax.text(xi, top - 0.015, f"{limit}/{cases}", transform=transform, color=colour, fontsize="xx-small",
                    ha="center", va="top", gid="suite-limit-count")


def _make_room(ax, foot, top):
    """Widen the y limits so the data keep clear of the bottom `foot` and
    the top `top` fractions of the axes."""
    log = ax.get_yscale() == "log"
    low, high = (np.log10(v) for v in ax.get_ylim()) if log else ax.get_ylim()
    span = (high - low) / (1 - foot - top)
    low, high = low - foot * span, high + top * span
    ax.set_ylim(*((10**low, 10**high) if log else (low, high)))


def plot_fragility(ax, run, im="scale", bootstrap=200, seed=0, limit_state=MODEL_LIMIT_STATE):
    """The lognormal fragility of a suite (suite.suite_fragility) for one
    limit state, one colour per value of the swept design inputs other than
    the scale: the fitted curve, its 5-95 % bootstrap band, and the observed
    fraction per stripe with its count (exceeded / cases with a physical
    outcome) beside it; theta and beta with their intervals in the legend.
    With an intensity measure other than the scale the cases of a stripe
    have their own intensities: the fraction is drawn at their geometric
    mean. Returns the fit table."""
    check_limit_state(run, limit_state)
    table, details = suite_fragility(run, im, bootstrap, seed)
    details = [d for d in details if d["row"]["limit_state"] == limit_state]
    if not details:
        states = ", ".join(sorted(set(table["limit_state"])))
        raise NotAnEllrollFile(f"{run.path}: no limit state {limit_state} (known: {states})")
    names, units = table.attrs["design_inputs"], table.attrs["units"]
    im_name = table.attrs["im"]
    status = np.array(run.status_names())
    known = np.isin(status, ("completed",) + MODEL_LIMITS)
    hit = np.isin(status, MODEL_LIMITS)
    x_case = intensity(run, im)[1]
    stripe = run.input_column("scale").astype(float) if "scale" in run.inputs else x_case
    everywhere = np.concatenate([d["x"] for d in details])
    for g, d in enumerate(details):
        colour = f"C{g % 10}" if len(details) > 1 else "C0"
        row, fit = d["row"], d["fit"]
        label = ", ".join(input_value_label(run, n, row[n]) for n in names)
        flags = limit_state_flags(d["exceeded"]) if d["exceeded"] is not None else np.zeros(status.shape)
        # a completed case whose figure is undefined (NaN) has no outcome for the limit state
        cases = d["cases"] & (hit | (known & ~np.isnan(flags))) & np.isfinite(x_case) & (x_case > 0)
        exceeded = hit | (flags == 1)
        px, pn, pz = [], [], []
        for level in np.unique(stripe[cases]):
            at = cases & (stripe == level)
            px.append(np.exp(np.mean(np.log(x_case[at]))))
            pn.append(int(at.sum()))
            pz.append(int(np.sum(at & exceeded)))
        px, pn, pz = np.array(px), np.array(pn), np.array(pz)
        ax.plot(px, pz / np.maximum(pn, 1), "o", color=colour, ms=5, mfc="none", mew=1.2, gid="fragility-points",
                label=(f"{label}: " if label else "") + "observed fraction (exceeded/cases)")
        for xi, zi, ni in zip(px, pz, pn):
            up = zi / max(ni, 1) <= 0.5         # counts inside the axes: above low points, below high ones
            ax.annotate(f"{zi}/{ni}", (xi, zi / max(ni, 1)), textcoords="offset points",
                        xytext=(4, 4 + 9 * g) if up else (4, -12 - 9 * g),
                        fontsize="x-small", color=colour, gid="fragility-count")
        if fit is None:
            _note(ax, (f"{label}: " if label else "") + row["note"])
            continue
        low, high = everywhere.min(), everywhere.max()
        curve_x = np.geomspace(min(low, fit.theta) / 1.5, max(high, fit.theta) * 1.5, 200)
        interval = ""
        if np.isfinite(row["theta_low"]):
            interval = f" [{row['theta_low']:.3g}, {row['theta_high']:.3g}]"
        beta_interval = f" [{row['beta_low']:.2f}, {row['beta_high']:.2f}]" if np.isfinite(row["beta_low"]) else ""
        unit = "" if units in ("", "1") else f" {tex_units(units)}"
        ax.plot(curve_x, fit.probability(curve_x), "-", color=colour, lw=1.6, gid="fragility-curve",
                label=(f"{label}: " if label else "") + rf"$\theta$ = {fit.theta:.3g}{interval}{unit}, "
                      rf"$\beta$ = {fit.beta:.2f}{beta_interval}")
        lo, hi = fit.band(curve_x)
        if np.any(np.isfinite(lo)):
            ax.fill_between(curve_x, lo, hi, color=colour, alpha=0.15, lw=0, gid="fragility-band",
                            label=f"5-95 % band ({len(fit.samples)} bootstrap fits)" if g == 0 else None)
        if row["note"]:
            _note(ax, row["note"])
    if spans_decades(everywhere) or im_name != "scale":
        ax.set_xscale("log")
    ax.set_xlabel(input_label(run, "scale") if im_name == "scale" else
                  im_name + ("" if units in ("", "1") else f", {tex_units(units)}"))
    what = ("reaching a model limit (" + ", ".join(m for m in MODEL_LIMITS if m != "lift_off") + ")"
            if limit_state == MODEL_LIMIT_STATE else f"exceeding {limit_state}")
    ax.set_ylabel(f"probability of {what}")
    ax.set_ylim(-0.03, 1.03)
    ax.grid(alpha=0.3, which="both")
    ax.set_title(f"Fragility, {_file_label(run)}: lognormal, maximum likelihood over the stripes", fontsize="medium")
    _legend_beside(ax)
    return table


def acceleration_spectra(run, case=None):
    """Amplitude spectra of the horizontal ground acceleration (the cup's)
    and of the transmitted one (|horizontal reaction| / m, the ball's
    absolute acceleration), from the stored samples: frequency (Hz) and the
    two one-sided amplitude spectra of the horizontal components (Hann window)."""
    t = run.time
    reaction = run.trajectory("reaction", case)
    valid = np.isfinite(reaction[:, 0])
    dt = t[1] - t[0]
    ground = run.trajectory("base_acceleration", case)[valid, :2]
    transmitted = reaction[valid, :2] / run.case_input("mass", case)
    frequency = np.fft.rfftfreq(int(valid.sum()), dt)

    window = np.hanning(int(valid.sum()))[:, None]     # leakage of the resonance peak kept low

    def amplitude(signal):
        return np.sqrt(np.sum(np.abs(np.fft.rfft(signal * window, axis=0))**2, axis=1)) * 2 / window.sum()
    return frequency, amplitude(ground), amplitude(transmitted)


def excitation_description(run, case=None):
    """What shakes the cup of a case, for a title: the record by its name
    (a suite's &record name) or file, its factor and scale; or the harmonic
    frequency and amplitude."""
    kind = str(run.case_input("excitation_kind", case)).strip()
    if kind == "record":
        name = run.record_names()[run.row(case)]
        files = [_drawn_as_is(name_text(f)) for f in _record_files(run, name)]
        name = _drawn_as_is(name_text(name))
        text = "record " + (f"{name} ({', '.join(files)})" if name and files else name or ", ".join(files) or "?")
        factor = run.case_input("record_factor", case) * run.case_input("scale", case)
        return text + (f", scaled by {factor:g}" if factor != 1 else "")
    if kind == "harmonic":
        amplitude = np.asarray(run.case_input("excitation_amplitude", case), float)
        along = ", ".join(f"{v:g} m/s$^2$ along {n}" for v, n in zip(amplitude, "xyz") if v != 0)
        return f"harmonic {run.case_input('excitation_frequency', case):g} Hz, {along}"
    return "cup at rest"


def _record_files(run, name):
    """The files of a record: those of its &record group (by name) in the
    input namelist, else every file the run read (the attribute input_files)."""
    attrs = run.attrs
    text = str(attrs.get("input_namelist", ""))
    if name:
        for group in re.findall(r"&record\b((?:'[^']*'|\"[^\"]*\"|[^'\"/])*)/", text, flags=re.I):
            if re.search(rf"name\s*=\s*['\"]{re.escape(name)}['\"]", group, flags=re.I):
                part = re.search(r"record_file\s*=\s*((?:['\"][^'\"]*['\"]\s*,?\s*)+)", group, flags=re.I)
                if part:
                    return [pathlib.PurePath(f).name for f in re.findall(r"['\"]([^'\"]*)['\"]", part.group(1))]
    files = [line.split(":")[0].strip() for line in str(attrs.get("input_files", "")).splitlines() if line.strip()]
    return [pathlib.PurePath(f).name for f in files]


def plot_spectrum(ax, run, case=None):
    """The transmitted acceleration's spectrum against the ground's (log);
    the title names the file, the case and the record (or the harmonic
    shaking); the legend beside the axes."""
    case = run.case_index(case)              # (None: the file's first case)
    require(run, "spectrum", case)
    frequency, ground, transmitted = acceleration_spectra(run, case)
    ax.loglog(frequency[1:], ground[1:], lw=0.8, color="0.4", label="ground (cup) acceleration")
    ax.loglog(frequency[1:], transmitted[1:], lw=0.8, color="C0", label="transmitted (ball, absolute)")
    for mode, period in enumerate(run.summary("linear_periods", case)):
        if np.isfinite(period):
            ax.axvline(1 / period, color=f"C{mode + 1}", ls="--", lw=0.8,
                       label=f"linear mode {mode + 1}: {1 / period:.3g} Hz")
    ax.set_xlabel("frequency, Hz")
    ax.set_ylabel(r"horizontal amplitude, m/s$^2$")
    ax.set_title(f"Acceleration spectra: {excitation_description(run, case)}\n{_file_label(run)}, "
                 f"{_case_label(run, case)}", fontsize="medium")
    ax.grid(True, which="both", alpha=0.3)
    ax.legend(fontsize="small", loc="upper left", bbox_to_anchor=(1.01, 1.0), frameon=False)
    return ax
