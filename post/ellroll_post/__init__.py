"""Read and plot ellroll files.

>>> import ellroll_post
>>> run = ellroll_post.open("legeza1990.h5")
>>> t, theta = run.time, run.trajectory("nutation", case=0)
"""
from importlib.metadata import PackageNotFoundError, version as _version

try:
    __version__ = _version("ellroll-post")
except PackageNotFoundError:        # run from the source folder, not installed
    __version__ = "unknown"

from .reader import EllrollFile, NotAnEllrollFile, open  # noqa: F401
from .plots import (plot_trace, plot_nutation, plot_reaction, plot_energy, plot_sweep,  # noqa: F401
                    plot_workprecision, plot_transmissibility, linear_transmissibility, reaction_parts,
                    energy_bound_level, plot_suite, plot_fragility, plot_spectrum, acceleration_spectra)
from .geometry import energy_bound, center_height  # noqa: F401
from .summary import format_summary, summary_rows, summary_table  # noqa: F401
from .frame import summary_frame  # noqa: F401
from .suite import suite_statistics, format_suite, suite_fragility, format_fragility  # noqa: F401

__all__ = ["open", "EllrollFile", "NotAnEllrollFile", "plot_trace", "plot_nutation", "plot_reaction",
           "plot_energy", "plot_sweep", "plot_workprecision", "plot_transmissibility", "linear_transmissibility", "reaction_parts", "energy_bound_level",
           "energy_bound", "center_height", "format_summary", "summary_rows", "summary_table",
           "summary_frame", "plot_suite", "plot_fragility", "suite_statistics", "format_suite", "suite_fragility",
           "format_fragility"]
