"""The moving cup (&excitation): zero excitation is the fixed cup bitwise; a
constant horizontal acceleration tilts gravity; transmissibility follows the
linearised rolling ball; lift-off at the analytic time; bad records refused."""
import math

import h5py
import numpy as np
import pytest

from conftest import PAPER_INPUT, ROOT, run
from test_campaign import assert_same_datasets

G, K = 9.81, 0.4
RHO_X, RADIUS = 1.0**2 / 0.2, 0.2
F_N = 1 / (2 * math.pi * math.sqrt((1 + K) * (RHO_X - RADIUS) / G))      # x-z mode, 0.19230 Hz

CUP = """&geometry a = 1.0, b = 0.4, c = 0.2 /
&ball radius = 0.2, weight = 2620.0 /
&initial x = {x}, y = 0.0, omega = 0.0, 0.0, 0.0 /
&integration {integration}, t_end = {t_end} /
&excitation {excitation} /
&output file = 'out.h5', interval = {interval} /
"""


def write(folder, **values):
    defaults = dict(x=0.0, integration="method = 'rk4', dt = 1.0e-3", t_end=10.0, interval=0.01, excitation="")
    defaults.update(values)
    (folder / "cup.nml").write_text(CUP.format(**defaults))
    return "cup.nml"


def linear_transmissibility(r):
    return abs(1 + K - K * r**2) / ((1 + K) * abs(1 - r**2))


def test_zero_excitation_is_the_fixed_cup_bitwise(ellroll, tmp_path):
    text = PAPER_INPUT.read_text()
    (tmp_path / "fixed.nml").write_text(text)
    (tmp_path / "zero.nml").write_text(text.replace(
        "&output", "&excitation kind = 'harmonic', amplitude = 0.0, 0.0, 0.0, frequency = 0.7 /\n&output"))
    for name in ("fixed", "zero"):
        assert run(ellroll, "run", f"{name}.nml", "-q", "-o", f"{name}.h5", cwd=tmp_path).returncode == 0
    with h5py.File(tmp_path / "zero.h5", "r") as f:
        assert np.all(f["trajectory/base_acceleration"][()] == 0)
        for group in ("trajectory", "summary"):
            with h5py.File(tmp_path / "fixed.h5", "r") as g:
                for name in g[group]:
                    # (the checksum also covers the base_acceleration a moving cup stores)
                    if name not in ("wall_time", "checksum"):
                        assert g[group][name][()].tobytes() == f[group][name][()].tobytes(), name
    with h5py.File(tmp_path / "fixed.h5", "r") as g:
        assert "base_acceleration" not in g["trajectory"]          # a fixed cup stores nothing of it


def test_constant_horizontal_acceleration_tilts_gravity(ellroll, tmp_path):
    accel = 0.3          # small enough that a swing from the bottom stays far from no_fit
    # equilibrium: the normal along a_base - g_vec = (accel, 0, g); its contact point on the cup
    n = np.array([accel, 0.0, G]) / math.hypot(accel, G)
    s = math.sqrt(1.0 * n[0]**2 + 0.4**2 * n[1]**2 + 0.2**2 * n[2]**2)
    x_eq = float(-1.0 * n[0] / s)
    name = write(tmp_path, x=repr(x_eq), t_end=20.0,
                 excitation=f"kind = 'harmonic', amplitude = {accel}, 0.0, 0.0, frequency = 0.0, phase = {math.pi / 2!r}")
    assert run(ellroll, "run", name, "-q", cwd=tmp_path).returncode == 0
    with h5py.File(tmp_path / "out.h5", "r") as f:
        contact, normal = f["trajectory/contact"][0], f["trajectory/normal"][0]
        assert np.abs(contact[:, 0] - x_eq).max() < 1e-10        # stays at rest in the cup
        np.testing.assert_allclose(normal, np.tile(n, (len(normal), 1)), atol=1e-10)
        force = f["trajectory/reaction"][0]
        mass = f["case/mass"][0]
        np.testing.assert_allclose(force, np.tile(mass * np.array([accel, 0.0, G]), (len(force), 1)), rtol=1e-9)
    # started at the bottom instead, it swings about the tilted equilibrium;
    # a constant base acceleration is a conservative pseudo-force, so the
    # cup-frame energy plus its potential m a x_C (force -m a along x) is constant
    name = write(tmp_path, t_end=100.0, interval=0.01,
                 excitation=f"kind = 'harmonic', amplitude = {accel}, 0.0, 0.0, frequency = 0.0, phase = {math.pi / 2!r}")
    assert run(ellroll, "run", name, "-q", "--overwrite", cwd=tmp_path).returncode == 0
    with h5py.File(tmp_path / "out.h5", "r") as f:
        x_center = f["trajectory/center"][0, :, 0]
        mass = f["case/mass"][0]
        energy = f["trajectory/energy"][0] + mass * accel * x_center
        assert np.abs(energy / energy[0] - 1).max() < 1e-10
        assert x_center.min() < 1.5 * x_eq           # it does swing past the equilibrium


@pytest.mark.parametrize("method", ["dop853", "rk4"])
def test_transmissibility_follows_the_linear_model(ellroll, tmp_path, method):
    """Five frequencies away from resonance, below and above it, at an amplitude
    small enough for the linear model (0.7 mm at most): the fit of the steady
    state beside the free oscillation, which never decays, agrees with T(r) to
    2e-6 (a Fourier projection over whole forcing periods, which keeps a leak of
    the free oscillation, is off by 0.3, 0.6, 7.3, 0.3 and 0.002 %)."""
    ratios = [0.3, 0.6, 1.5, 2.5, 4.0]
    text = CUP.format(x=0.0, integration=f"method = '{method}', rtol = 1e-10, dt = 0.01", t_end=200.0, interval=0.1,
                      excitation="kind = 'harmonic', amplitude = 0.001, 0.0, 0.0, frequency = 0.2")
    text += f"&sweep name = 'excitation_frequency', values = {', '.join(repr(r * F_N) for r in ratios)} /\n"
    (tmp_path / "five.nml").write_text(text)
    assert run(ellroll, "run", "five.nml", "-q", "--threads", "1", cwd=tmp_path).returncode == 0
    assert run(ellroll, "run", "five.nml", "-q", "--threads", "2", "-o", "two.h5", cwd=tmp_path).returncode == 0
    with h5py.File(tmp_path / "out.h5", "r") as f, h5py.File(tmp_path / "two.h5", "r") as g:
        measured = f["summary/transmissibility"][:]
        assert g["summary/transmissibility"][:].tobytes() == measured.tobytes()     # each case's own sums
    linear = np.array([linear_transmissibility(r) for r in ratios])
    assert np.abs(measured / linear - 1).max() < 1e-5


def test_resonance_peak_at_the_linear_frequency(ellroll, tmp_path):
    text = CUP.format(x=0.0, integration="method = 'dop853', rtol = 1e-9", t_end=300.0, interval=0.1,
                      excitation="kind = 'harmonic', amplitude = 0.001, 0.0, 0.0, frequency = 0.2")
    text += f"&sweep name = 'excitation_frequency', start = {0.9 * F_N!r}, stop = {1.1 * F_N!r}, count = 21 /\n"
    (tmp_path / "sweep.nml").write_text(text)
    assert run(ellroll, "run", "sweep.nml", "-q", cwd=tmp_path).returncode == 0
    with h5py.File(tmp_path / "out.h5", "r") as f:
        frequency, transmissibility = f["case/excitation_frequency"][:], f["summary/transmissibility"][:]
        linear = 1 / f["summary/linear_periods"][0, 0]
    assert linear == pytest.approx(F_N, rel=1e-9)
    peak = frequency[np.argmax(transmissibility)]
    assert abs(peak / linear - 1) < 0.02
    assert transmissibility.max() > 5


def test_liftoff_at_the_analytic_time(ellroll, tmp_path):
    amplitude, frequency = 15.0, 2.0
    name = write(tmp_path, t_end=2.0,
                 excitation=f"kind = 'harmonic', amplitude = 0.0, 0.0, {amplitude}, frequency = {frequency}")
    assert run(ellroll, "run", name, "-q", cwd=tmp_path).returncode == 0
    with h5py.File(tmp_path / "out.h5", "r") as f:
        status = f["summary/status"]
        assert status.attrs["flag_meanings"].split()[status[0]] == "liftoff"
        # at rest at the bottom N = m (g + a_z): zero when sin(2 pi f t) = -g / A
        expected = (math.pi + math.asin(G / amplitude)) / (2 * math.pi * frequency)
        assert f["summary/t_final"][0] == pytest.approx(expected, abs=1e-9)


def test_record_equal_to_a_harmonic(ellroll, tmp_path):
    t = np.arange(0, 10.0 + 1e-9, 0.001)
    accel = 0.3 * np.sin(2 * np.pi * 0.5 * t)
    np.savetxt(tmp_path / "rec.csv", np.c_[t, accel, 0 * t], delimiter=",", header="t, ax, ay")
    name = write(tmp_path, excitation="kind = 'record', record_file = 'rec.csv'")
    assert run(ellroll, "run", name, "-q", "-o", "rec.h5", cwd=tmp_path).returncode == 0
    name = write(tmp_path, excitation="kind = 'harmonic', amplitude = 0.3, 0.0, 0.0, frequency = 0.5")
    assert run(ellroll, "run", name, "-q", "-o", "harm.h5", cwd=tmp_path).returncode == 0
    with h5py.File(tmp_path / "rec.h5", "r") as a, h5py.File(tmp_path / "harm.h5", "r") as b:
        difference = np.abs(a["trajectory/contact"][0] - b["trajectory/contact"][0]).max()
        assert difference < 1e-7          # linear interpolation of 1 ms samples
        assert np.abs(a["trajectory/contact"][0]).max() > 1e-3


@pytest.mark.parametrize("content,words", [
    ("0, 0, 0\n0.5, 1, 1\n0.4, 1, 1\n20, 0, 0\n", "rec.csv:3: time 0.4 s does not increase"),
    ("0, 0, 0\n1, nan, 1\n20, 0, 0\n", "rec.csv:2: value 2 is not finite: nan"),
    ("1, 0, 0\n5, 1, 1\n20, 0, 0\n", "rec.csv: the record starts at 1 s; it must cover t = 0"),
    ("0, 0\n20, 0\n", "expected 3 or 4 numbers"),
    ("0, 0, 0\n1, x, 1\n20, 0, 0\n", "rec.csv:2: not numbers"),
    ("0, 0, 0\n1, 1, 1, 1\n20, 0, 0\n", "4 columns where the first row has 3"),
])
def test_bad_record_files(ellroll, tmp_path, content, words):
    (tmp_path / "rec.csv").write_text(content)
    name = write(tmp_path, excitation="kind = 'record', record_file = 'rec.csv'")
    result = run(ellroll, "run", name, cwd=tmp_path)
    assert result.returncode == 2
    assert "cup.nml:5: &excitation: record_file = 'rec.csv'" in result.stderr and words in result.stderr, result.stderr
    assert sorted(p.name for p in tmp_path.iterdir()) == ["cup.nml", "rec.csv"]


@pytest.mark.parametrize("excitation,words", [
    ("kind = 'shaker'", "must be 'none', 'harmonic' or 'record'"),
    ("kind = 'record'", "record_file is required"),
    ("kind = 'record', record_file = 'missing.csv'", "cannot open"),
    ("kind = 'harmonic', amplitude = 1.0, nan, 0.0, frequency = 1", "three finite numbers"),
    ("kind = 'harmonic', amplitude = 1.0, 0.0, 0.0, frequency = -1", "frequency = -1: must be between"),
    ("kind = 'harmonic', amplitude = 1.0, 0.0, 0.0, frequency = 1, scale = 2", "scale = 2: applies to kind = 'record'"),
    ("kind = 'record', record_file = 'x.csv', frequency = 1", "frequency = 1: applies to kind = 'harmonic'"),
    ("kind = 'none', amplitude = 1, 0, 0", "amplitude = 1, 0, 0: applies to kind = 'harmonic'"),
    ("kind = 'record', record_file = 'x.csv', scale = -1", "scale = -1: must be between 0 and 1000"),
])
def test_bad_excitation_input(ellroll, tmp_path, excitation, words):
    name = write(tmp_path, excitation=excitation)
    result = run(ellroll, "check", name, cwd=tmp_path)
    assert result.returncode == 2 and words in result.stderr, result.stderr


def test_example_inputs_and_plot(ellroll, tmp_path):
    for name in ("isolator_harmonic.nml", "isolator_record.nml", "isolator_suite.nml"):
        result = run(ellroll, "check", ROOT / "input" / name, cwd=tmp_path)
        assert result.returncode == 0, result.stderr
    text = (ROOT / "input" / "isolator_harmonic.nml").read_text().replace("count = 81", "count = 9")
    (tmp_path / "iso.nml").write_text(text.replace("t_end = 300.0", "t_end = 100.0"))
    assert run(ellroll, "run", "iso.nml", "-q", "-o", "iso.h5", cwd=tmp_path).returncode == 0
    import subprocess
    import sys
    result = subprocess.run([sys.executable, "-m", "ellroll_post.cli", "transmissibility", str(tmp_path / "iso.h5"),
                             "--out", str(tmp_path)], capture_output=True, text=True)
    assert result.returncode == 0, result.stderr
    assert (tmp_path / "iso_transmissibility.png").stat().st_size > 10000


def test_the_pairs_agree_on_a_shaken_cup(ellroll, tmp_path):
    """The base acceleration enters each stage at its own time t + c_s h: a
    wrong node would show as a difference of the two pairs' trajectories of
    the order of their steps' error. Both at rtol 1e-12 on a cup shaken near
    resonance (a 0.01 m/s^2 base at 1.2 f_n, 20 s): the centres agree to
    1e-12 m (measured: 2e-14 m), against a swing of 5 cm."""
    centers = {}
    for pair in ("dop853", "vern9"):
        name = write(tmp_path, integration=f"method = '{pair}', rtol = 1e-12, atol = 1e-14", t_end=20.0,
                     interval=0.05, excitation=f"kind = 'harmonic', amplitude = 0.01, 0.0, 0.0, "
                                               f"frequency = {1.2 * F_N!r}")
        assert run(ellroll, "run", name, "-q", "--overwrite", cwd=tmp_path).returncode == 0
        with h5py.File(tmp_path / "out.h5", "r") as f:
            centers[pair] = f["trajectory/center"][0]
    assert np.ptp(centers["dop853"][:, 0]) > 0.04
    assert np.abs(centers["dop853"] - centers["vern9"]).max() < 1e-12
