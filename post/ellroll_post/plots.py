"""Figures of the source paper, each drawn on a given matplotlib Axes."""
import numpy as np


def plot_trace(ax, run, case=0):
    """Fig. 2: the contact point's trace in the XY plane, with the cup's rim."""
    contact = run.trajectory("contact", case)
    valid = np.isfinite(contact[:, 0])
    x, y = contact[valid, 0], contact[valid, 1]
    a, b = run.case_input("a", case), run.case_input("b", case)
    phi = np.linspace(0, 2 * np.pi, 400)
    ax.plot(a * np.cos(phi), b * np.sin(phi), color="0.6", lw=1, label="rim of the cup (z = c)")
    ax.plot(x, y, lw=0.8, color="C0", label="contact point")
    ax.plot(x[:1], y[:1], "o", color="C2", label="start")
    ax.plot(x[-1:], y[-1:], "s", color="C3", label=f"end, t = {run.time[valid][-1]:g} s (S)")
    ax.set_aspect("equal")
    ax.set_xlabel("X, m")
    ax.set_ylabel("Y, m")
    ax.set_title(f"Contact point trace (case {case}: {run.status_name(case)})")
    ax.legend(loc="upper right", fontsize="small")
    return ax


def plot_nutation(ax, run, case=0):
    """Fig. 3: the nutation angle Theta (rad) against time (s)."""
    theta = run.trajectory("nutation", case)
    t = run.time
    ax.plot(t, theta, lw=0.8, color="C0")
    ax.set_xlabel("t, s")
    ax.set_ylabel(r"$\Theta$, rad")
    theta_max = np.nanmax(theta)
    ax.axhline(theta_max, color="0.6", lw=0.8, ls="--")
    ax.annotate(rf"$\Theta_{{max}}$ = {theta_max:.4f} rad ({np.degrees(theta_max):.2f}$^\circ$)",
                xy=(t[0], theta_max), xytext=(4, 4), textcoords="offset points", fontsize="small")
    secondary = ax.secondary_yaxis("right", functions=(np.degrees, np.radians))
    secondary.set_ylabel(r"$\Theta$, deg")
    ax.set_title(f"Nutation angle (case {case}: {run.status_name(case)})")
    return ax
