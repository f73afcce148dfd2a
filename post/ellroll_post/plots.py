"""Figures of ellroll files, each drawn on given matplotlib Axes (or a Figure)."""
import numpy as np

from .geometry import energy_bound, surface_residual


def _case_label(run, case):
    return f"case {case}: {run.status_name(case)}"


def energy_bound_level(run, case=0):
    """Centre height the energy integral allows when the spin about the normal
    keeps its initial value: m g z_C = E0 - J (omega0 . n0)^2 / 2."""
    m, g, radius = run.case_input("mass", case), run.case_input("g", case), run.case_input("radius", case)
    k = run.case_input("inertia_factor", case)
    omega0 = run.trajectory("omega", case)[0]
    n0 = run.trajectory("normal", case)[0]
    energy0 = run.trajectory("energy", case)[0]
    return (energy0 - 0.5 * k * m * radius**2 * (omega0 @ n0)**2) / (m * g)


def plot_trace(ax, run, case=0):
    """Fig. 2: the contact point's trace in the XY plane, the cup's rim, the
    energy bound (the curve the ball does not cross), start and end."""
    contact = run.trajectory("contact", case)
    valid = np.isfinite(contact[:, 0])
    x, y = contact[valid, 0], contact[valid, 1]
    a, b, c = (run.case_input(n, case) for n in "abc")
    phi = np.linspace(0, 2 * np.pi, 400)
    ax.plot(a * np.cos(phi), b * np.sin(phi), color="0.6", lw=1, label="rim of the cup (z = c)")
    if {"energy", "omega", "normal"} <= set(run.fields):
        bx, by = energy_bound(a, b, c, run.case_input("radius", case), energy_bound_level(run, case))
        if np.any(np.isfinite(bx)):
            ax.plot(bx, by, color="C1", lw=1, ls="--", label="energy bound (spin about n kept)")
    ax.plot(x, y, lw=0.7, color="C0", label="contact point")
    ax.plot(x[:1], y[:1], "o", color="C2", label="start")
    ax.plot(x[-1:], y[-1:], "s", color="C3", label=f"end S, t = {run.time[valid][-1]:g} s")
    ax.set_aspect("equal")
    ax.set_xlabel("X, m")
    ax.set_ylabel("Y, m")
    ax.set_title(f"Contact point trace ({_case_label(run, case)})")
    ax.legend(loc="upper center", bbox_to_anchor=(0.5, -0.18), ncol=3, fontsize="small", frameon=False)
    return ax


def plot_nutation(ax, run, case=0):
    """Fig. 3: the nutation angle Theta against time, theta_max and the
    measured nutation period annotated."""
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


def reaction_parts(run, case=0):
    """Normal force N = F . n, friction |F - N n| and the friction coefficient needed."""
    force = run.trajectory("reaction", case)
    normal = run.trajectory("normal", case)
    n_force = np.sum(force * normal, axis=1)
    tangential = np.linalg.norm(force - n_force[:, None] * normal, axis=1)
    return n_force, tangential, tangential / n_force


def plot_reaction(axes, run, case=0):
    """Normal force (the weight m g as a reference), friction force and the
    friction coefficient needed against time, each on its own axis (three
    Axes: the two forces differ by orders of magnitude); legends beside."""
    t = run.time
    n_force, tangential, mu = reaction_parts(run, case)
    weight = run.case_input("mass", case) * run.case_input("g", case)
    axes[0].plot(t, n_force, lw=0.8, label="normal force N")
    axes[0].axhline(weight, color="0.5", ls="--", lw=0.8, label=f"weight m g = {weight:g} N")
    axes[0].set_ylabel("N, N")
    axes[0].set_title(f"Force of the cup on the ball ({_case_label(run, case)})")
    axes[1].plot(t, tangential, lw=0.8, color="C1", label="friction force |F_t|")
    axes[1].set_ylabel("|F_t|, N")
    axes[2].plot(t, mu, lw=0.8, color="C2", label=r"friction coefficient needed $|F_t|/N$")
    mu_limit = run.case_input("mu", case)
    if np.isfinite(mu_limit):
        axes[2].axhline(mu_limit, color="C3", ls="--", lw=0.8, label=f"mu = {mu_limit:g}")
    axes[2].set_ylabel(r"$|F_t| / N$")
    axes[2].set_xlabel("t, s")
    for ax in axes:
        ax.legend(fontsize="small", loc="upper left", bbox_to_anchor=(1.01, 1.0), frameon=False)
    return axes


def plot_energy(ax, run, case=0):
    """Relative energy error and constraint error against time (log)."""
    t = run.time
    tiny = 1e-18
    if "energy" in run.fields:
        energy = run.trajectory("energy", case)
        ax.semilogy(t, np.maximum(np.abs(energy / energy[0] - 1), tiny), lw=0.8, label=r"$|E - E_0| / E_0$")
    if "contact" in run.fields:
        a, b, c = (run.case_input(n, case) for n in "abc")
        residual = surface_residual(a, b, c, run.trajectory("contact", case))
        # round-off that changes sign every sample would fill the plot as a
        # block: its running maximum is the line to read
        valid = np.isfinite(residual)
        envelope = np.full_like(residual, np.nan)
        envelope[valid] = np.maximum.accumulate(np.maximum(residual[valid], tiny))
        ax.semilogy(t, envelope, lw=0.8,
                    label=r"constraint error $|(x/a)^2+(y/b)^2+((z-c)/c)^2-1|$, largest so far")
    ax.set_xlabel("t, s")
    ax.set_ylabel("error (zero shown as 1e-18)")
    ax.set_title(f"Energy and constraint errors ({_case_label(run, case)})")
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
            if len(groups) == 1 and others:       # sampled, or too many lines: every case a point
                ax.plot(x, y, "o", ms=2, alpha=max(0.05, min(0.5, 1000 / len(x))), mew=0,
                        label=f"{run.n_cases} cases ({', '.join(others)} vary too)")
                _quantile_band(ax, x[~early], y[~early])
            else:
                for key, mask in groups.items():
                    order = np.argsort(x[mask])
                    label = ", ".join(f"{n} = {v:g}" for n, v in zip(others, key)) or None
                    ax.plot(x[mask][order], y[mask][order], marker="o", ms=3, lw=1, label=label)
            _mark_early(ax, x, y, status, color="C3")
            ax.set_xlabel(f"{x_names[0]}, {run.input_units(x_names[0])}")
            if len(groups) > 1 or np.any(early):
                _legend_beside(ax)
        else:
            xa, xb = run.input_column(x_names[0]), run.input_column(x_names[1])
            ua, ub = np.unique(xa), np.unique(xb)
            if len(ua) * len(ub) <= 4 * len(y):       # a grid of the two inputs: a heat map
                grid = np.full((len(ub), len(ua)), np.nan)
                grid[np.searchsorted(ub, xb), np.searchsorted(ua, xa)] = y
                mesh = ax.pcolormesh(ua, ub, grid, shading="nearest")
            else:                                      # sampled: each case a coloured point
                mesh = ax.scatter(xa, xb, c=y, s=6)
            fig.colorbar(mesh, ax=ax, label=f"{y_name}, {units}")
            _mark_early(ax, xa, xb, status, color="C3")
            if np.any(early):
                _legend_beside(ax, title="status")
            ax.set_xlabel(f"{x_names[0]}, {run.input_units(x_names[0])}")
            ax.set_ylabel(f"{x_names[1]}, {run.input_units(x_names[1])}")
        if len(x_names) == 1:
            ax.set_ylabel(f"{y_name}, {units}")
        ax.grid(alpha=0.3)
    axes[0].set_title(f"{', '.join(y_names)} ({run.n_cases} cases)", fontsize="medium")
    return axes


def _quantile_band(ax, x, y, bins=30):
    """Median and 10-90 % band of y in bins of x: the trend a cloud of many
    sampled cases hides."""
    finite = np.isfinite(x) & np.isfinite(y)
    x, y = x[finite], y[finite]
    if len(x) < 20 * bins:
        return
    edges = np.linspace(x.min(), x.max(), bins + 1)
    which = np.clip(np.searchsorted(edges, x, side="right") - 1, 0, bins - 1)
    centres = (edges[:-1] + edges[1:]) / 2
    q = np.array([np.percentile(y[which == b], [10, 50, 90]) if np.any(which == b) else [np.nan] * 3
                  for b in range(bins)])
    ax.fill_between(centres, q[:, 0], q[:, 2], color="k", alpha=0.15, lw=0, label="10-90 % of completed cases")
    ax.plot(centres, q[:, 1], color="k", lw=1.5, label="median of completed cases")


def _mark_early(ax, x, y, status, color):
    """Each way a case ended early, its own marker and legend entry (names
    beside every point would bury a campaign's figure)."""
    for marker, name in zip("xs^vDP*", sorted(set(status[status != "completed"]))):
        ended = status == name
        ax.plot(x[ended], y[ended], marker, mfc="none", mec=color, mew=1.2, ms=6, ls="none",
                label=f"ended: {name}")


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
        ax.legend(fontsize="small")
    return axes


def linear_transmissibility(ratio, inertia_factor=0.4):
    """Transmissibility of the linearised rolling ball along a principal
    axis: |1 + k - k r^2| / ((1 + k) |1 - r^2|), r = f / f_n (docs/model.md);
    1 at low frequency, 0 at r^2 = (1 + k) / k, k / (1 + k) at high frequency."""
    ratio = np.asarray(ratio, float)
    k = inertia_factor
    return np.abs(1 + k - k * ratio**2) / ((1 + k) * np.abs(1 - ratio**2))


def plot_transmissibility(ax, run):
    """Transmissibility against the excitation frequency (log-log), with the
    linear resonance frequencies (/summary/linear_periods) marked and the
    linear prediction for each."""
    frequency = run.input_column("excitation_frequency")
    transmissibility = run.summary("transmissibility")
    order = np.argsort(frequency)
    ax.loglog(frequency[order], transmissibility[order], "o-", ms=3, lw=1, label="ellroll (measured)")
    periods = run.summary("linear_periods", 0)
    k = run.case_input("inertia_factor", 0)
    grid = np.geomspace(frequency.min(), frequency.max(), 400)
    for mode, period in enumerate(periods):
        if np.isfinite(period):
            ax.axvline(1 / period, color=f"C{mode + 1}", ls="--", lw=0.8,
                       label=f"linear resonance, mode {mode + 1}: {1 / period:.4g} Hz")
            ax.loglog(grid, linear_transmissibility(grid * period, k), color=f"C{mode + 1}", lw=0.7, alpha=0.6,
                      label=f"linear prediction, mode {mode + 1}")
    ax.axhline(1, color="0.6", lw=0.6)
    ax.set_xlabel("excitation frequency, Hz")
    ax.set_ylabel("transmissibility |a_ball| / |a_base|")
    ax.set_title(f"Transmissibility ({run.n_cases} frequencies)")
    ax.grid(True, which="both", alpha=0.3)
    ax.legend(fontsize="x-small")
    return ax


SUITE_QUANTITIES = ("displacement_max", "absolute_acceleration_max")


def suite_statistics(run, quantity):
    """Per design point of a record suite (the swept inputs other than the
    record, e.g. scale): the records, each one's value of the summary
    `quantity`, and their median and 84th percentile (numpy's, linear)."""
    records = np.array(run.record_names())
    values = run.summary(quantity).astype(float)
    others = run.swept_inputs()
    keys = np.stack([run.input_column(n) for n in others], axis=1) if others else np.zeros((run.n_cases, 0))
    points = []
    for key in np.unique(keys, axis=0):
        mask = np.all(keys == key, axis=1)
        chosen = values[mask]
        points.append(dict(inputs=dict(zip(others, key)), records=list(records[mask]), values=chosen,
                           median=float(np.median(chosen)), p84=float(np.percentile(chosen, 84))))
    return points


def plot_suite(axes, run):
    """Peak displacement and peak absolute acceleration over a record suite
    against the scale (or the first other swept input): every record's
    value faint, the median and the 84th percentile over the records."""
    records = sorted(set(run.record_names()))
    for ax, quantity in zip(axes, SUITE_QUANTITIES):
        points = suite_statistics(run, quantity)
        x_name = "scale" if "scale" in run.swept_inputs() else (run.swept_inputs() or [None])[0]
        x = np.array([p["inputs"].get(x_name, 1.0) for p in points]) if x_name else np.ones(len(points))
        order = np.argsort(x)
        for p, xi in zip(points, x):
            ax.plot(np.full(len(p["values"]), xi), p["values"], "o", ms=3, color="0.55", alpha=0.35)
        ax.plot([], [], "o", ms=3, color="0.55", alpha=0.5, label=f"each record ({len(records)})")
        ax.plot(x[order], np.array([p["median"] for p in points])[order], "o-", color="C0", lw=1.5,
                label="median")
        ax.plot(x[order], np.array([p["p84"] for p in points])[order], "s--", color="C3", lw=1.2,
                label="84th percentile")
        ax.set_xlabel(f"{x_name}, {run.input_units(x_name)}" if x_name else "")
        ax.set_ylabel(f"{quantity}, {run.units(f'summary/{quantity}')}")
        ax.grid(alpha=0.3)
        ax.legend(fontsize="small", loc="upper left")
    axes[0].set_title(f"Record suite: {len(records)} records, {run.n_cases} cases")
    return axes


def acceleration_spectra(run, case=0):
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


def plot_spectrum(ax, run, case=0):
    """The transmitted acceleration's spectrum against the ground's (log)."""
    frequency, ground, transmitted = acceleration_spectra(run, case)
    ax.loglog(frequency[1:], ground[1:], lw=0.8, color="0.4", label="ground (cup) acceleration")
    ax.loglog(frequency[1:], transmitted[1:], lw=0.8, color="C0", label="transmitted (ball, absolute)")
    for mode, period in enumerate(run.summary("linear_periods", case)):
        if np.isfinite(period):
            ax.axvline(1 / period, color=f"C{mode + 1}", ls="--", lw=0.8, label=f"linear mode {mode + 1}")
    ax.set_xlabel("frequency, Hz")
    ax.set_ylabel("horizontal amplitude, m/s^2")
    ax.set_title(f"Acceleration spectra ({_case_label(run, case)})")
    ax.grid(True, which="both", alpha=0.3)
    ax.legend(fontsize="small", loc="lower left")
    return ax
