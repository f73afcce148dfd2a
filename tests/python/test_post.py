"""post/: the figures carry exactly the file's data; bad files give clear errors."""
import subprocess
import sys

import h5py
import numpy as np
import pytest

matplotlib = pytest.importorskip("matplotlib")
matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402

import ellroll_post  # noqa: E402


def plot_cli(*args):
    return subprocess.run([sys.executable, "-m", "ellroll_post.cli", *map(str, args)],
                          capture_output=True, text=True)


def test_trace_plots_the_contact_points_and_rim(paper_file):
    with ellroll_post.open(paper_file) as run, h5py.File(paper_file, "r") as f:
        fig, ax = plt.subplots()
        ellroll_post.plot_trace(ax, run)
        lines = {line.get_label(): line for line in ax.get_lines()}
        contact = f["trajectory/contact"][0]
        np.testing.assert_array_equal(lines["contact point"].get_xdata(), contact[:, 0])
        np.testing.assert_array_equal(lines["contact point"].get_ydata(), contact[:, 1])
        rim = lines["rim of the cup (z = c)"]
        np.testing.assert_allclose((rim.get_xdata() / 1.0) ** 2 + (rim.get_ydata() / 0.4) ** 2, 1, rtol=1e-12)
        assert ax.get_aspect() == 1.0
        plt.close(fig)


def test_nutation_plots_theta_against_time(paper_file):
    with ellroll_post.open(paper_file) as run, h5py.File(paper_file, "r") as f:
        fig, ax = plt.subplots()
        ellroll_post.plot_nutation(ax, run)
        line = ax.get_lines()[0]
        np.testing.assert_array_equal(line.get_xdata(), f["time"][:])
        np.testing.assert_array_equal(line.get_ydata(), f["trajectory/nutation"][0])
        assert "rad" in ax.get_ylabel() and "s" in ax.get_xlabel()
        plt.close(fig)


@pytest.mark.parametrize("figure,stem", [("trace", "fig2_trace"), ("nutation", "fig3_nutation")])
def test_cli_writes_images(paper_file, tmp_path, figure, stem):
    result = plot_cli(figure, paper_file, "--out", tmp_path)
    assert result.returncode == 0, result.stderr
    png = tmp_path / f"{stem}.png"
    assert png.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n" and png.stat().st_size > 10000


def test_clear_errors(paper_file, tmp_path):
    not_hdf5 = tmp_path / "notes.txt"
    not_hdf5.write_text("hello")
    result = plot_cli("trace", not_hdf5)
    assert result.returncode == 2 and "cannot open as HDF5" in result.stderr and "Traceback" not in result.stderr
    other = tmp_path / "other.h5"
    with h5py.File(other, "w") as f:
        f["x"] = 1
    result = plot_cli("trace", other)
    assert result.returncode == 2 and "not an ellroll file" in result.stderr
    result = plot_cli("nutation", paper_file, "--case", 5)
    assert result.returncode == 2 and "case 5 out of range" in result.stderr
