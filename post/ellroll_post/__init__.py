"""Read and plot ellroll HDF5 files.

>>> import ellroll_post
>>> run = ellroll_post.open("legeza1990.h5")
>>> t, theta = run.time, run.trajectory("nutation", case=0)
"""
from .reader import EllrollFile, NotAnEllrollFile, open  # noqa: F401
from .plots import plot_trace, plot_nutation  # noqa: F401

__all__ = ["open", "EllrollFile", "NotAnEllrollFile", "plot_trace", "plot_nutation"]
