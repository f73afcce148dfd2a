"""The hard cases of input/hard/: each input states what it must do; these
tests hold it to that."""
import re
import shutil

import h5py
import numpy as np
import pytest

from conftest import ROOT, SANITIZED, run

HARD = ROOT / "input" / "hard"
G = 9.81


def run_hard(ellroll, tmp_path, name, *extra, edits=()):
    text = (HARD / name).read_text()
    for old, new in edits:
        assert old in text, old
        text = text.replace(old, new)
    (tmp_path / name).write_text(text)
    result = run(ellroll, "run", name, "-q", "--overwrite", "-o", "out.h5", *extra, cwd=tmp_path, timeout=300)
    assert result.returncode == 0, result.stderr
    return h5py.File(tmp_path / "out.h5", "r"), result


def status(f, case=0):
    ds = f["summary/status"]
    return ds.attrs["flag_meanings"].split()[ds[case]]


def crossing_period(t, u):
    s = np.where(np.sign(u[:-1]) != np.sign(u[1:]))[0]
    crossings = t[s] + u[s] / (u[s] - u[s + 1]) * (t[1] - t[0])
    return 2 * (crossings[-1] - crossings[0]) / (len(crossings) - 1)


def test_fast_spin_is_accurate_at_the_advised_step(ellroll, tmp_path):
    f, result = run_hard(ellroll, tmp_path, "fast_spin.nml")
    assert status(f) == "completed" and "warning" not in result.stderr
    assert f["summary/error_contact"][0] < 1e-7
    assert f["summary/error_theta"][0] < 1e-7


def test_fast_spin_with_a_coarse_step_is_warned(ellroll, tmp_path):
    f, result = run_hard(ellroll, tmp_path, "fast_spin_coarse.nml")
    assert "dt is large" in result.stderr and "suggested dt <= 0.001 s" in result.stderr
    assert f["summary/error_contact"][0] > 1e-4      # the warning was right


def test_ball_just_smaller_than_the_smallest_radius(ellroll, tmp_path):
    f, _ = run_hard(ellroll, tmp_path, "near_fit.nml")
    assert status(f) == "completed"
    period = crossing_period(f["time"][:], f["trajectory/contact"][0, :, 1])
    expected = 2 * np.pi * np.sqrt(7 * (0.4**2 / 0.2 - 0.79992) / (5 * G))
    assert abs(period / expected - 1) < 1e-5


def test_ball_reaching_the_radius_of_curvature(ellroll, tmp_path):
    f, _ = run_hard(ellroll, tmp_path, "reaches_no_fit.nml")
    assert status(f) == "no_fit"
    assert f["summary/theta_max"][0] == pytest.approx(0.17708961628, rel=1e-9)
    theta = f["trajectory/nutation"][0]
    done = f["time"][:] <= f["summary/t_final"][0]
    assert np.all(np.isfinite(theta[done])) and np.all(np.isnan(theta[~done]))


def test_energy_just_below_the_rim_stays_in(ellroll, tmp_path):
    f, _ = run_hard(ellroll, tmp_path, "rim_below.nml")
    assert status(f) == "completed"
    assert 0.199 < np.nanmax(f["trajectory/contact"][0, :, 2]) < 0.2


@pytest.mark.parametrize("pair", ["dop853", "vern9"])
def test_energy_just_above_the_rim_stops_at_the_right_time(ellroll, tmp_path, pair):
    f, _ = run_hard(ellroll, tmp_path, "rim_above.nml")
    t_rk4 = f["summary/t_final"][0]
    assert status(f) == "rim"
    f, _ = run_hard(ellroll, tmp_path, "rim_above.nml",
                    edits=[("method = 'rk4', dt = 1.0e-4", f"method = '{pair}', rtol = 1.0e-12, atol = 1.0e-14")])
    assert status(f) == "rim"
    assert abs(f["summary/t_final"][0] - t_rk4) < 1e-9
    assert t_rk4 == pytest.approx(0.39725374360, abs=1e-9)


def test_nearly_spherical_cup_loses_nothing_to_cancellation(ellroll, tmp_path):
    sphere, _ = run_hard(ellroll, tmp_path, "near_sphere.nml",
                         edits=[("a = 1.00000002, b = 1.00000001", "a = 1.0, b = 1.0")])
    contact_sphere = sphere["trajectory/contact"][0]
    sphere.close()
    deviations = []
    for eps in (1, 2):
        f, _ = run_hard(ellroll, tmp_path, "near_sphere.nml",
                        edits=[("a = 1.00000002, b = 1.00000001", f"a = {1 + 2e-8 * eps!r}, b = {1 + 1e-8 * eps!r}")])
        assert f["summary/energy_drift"][0] < 1e-12
        spin = (f["trajectory/omega"][0] * f["trajectory/normal"][0]).sum(axis=1)
        assert np.abs(spin - spin[0]).max() < 1e-6 * eps
        deviations.append(f["trajectory/contact"][0] - contact_sphere)
        f.close()
    # linear response: twice the asphericity, twice the deviation
    ratio = np.linalg.norm(deviations[1]) / np.linalg.norm(deviations[0])
    assert ratio == pytest.approx(2.0, rel=1e-3)


def test_tiny_motions_keep_their_relative_accuracy(ellroll, tmp_path):
    f, _ = run_hard(ellroll, tmp_path, "tiny_motion.nml")
    expected = 2 * np.pi * np.sqrt(7 * (1.0 / 0.2 - 0.2) / (5 * G))
    for case, x0 in enumerate((1e-9, 1e-150)):
        assert status(f, case) == "completed"
        x = f["trajectory/contact"][case, :, 0]
        theta = f["trajectory/nutation"][case]
        assert np.all(np.isfinite(x)) and np.all(np.isfinite(theta))
        assert abs(crossing_period(f["time"][:], x / x0) / expected - 1) < 1e-10
        assert abs(f["summary/theta_max"][case] / theta[0] - 1) < 1e-12
        assert theta[0] == pytest.approx(x0 * 0.2, rel=1e-12)      # Theta(0) = x0 c / a^2


@pytest.mark.skipif(SANITIZED, reason="a numerical property of long runs: the Release and Debug builds test it")
def test_long_run_energy_drift_per_method(ellroll, tmp_path):
    drift = {}
    for method in ("rk4", "gauss4"):
        for t_end in ("1000.0", "10000.0"):
            f, _ = run_hard(ellroll, tmp_path, "long_run.nml",
                            edits=[("method = 'gauss4'", f"method = '{method}'"), ("t_end = 10000.0", f"t_end = {t_end}")])
            assert status(f) == "completed"
            drift[method, t_end] = f["summary/energy_drift"][0]
            f.close()
    print("energy drift:", drift)
    assert drift["rk4", "10000.0"] / drift["rk4", "1000.0"] > 5
    assert drift["gauss4", "10000.0"] < 1.5 * drift["gauss4", "1000.0"]
    assert drift["gauss4", "10000.0"] < 1e-3 * drift["rk4", "10000.0"]


def test_slip(ellroll, tmp_path):
    f, _ = run_hard(ellroll, tmp_path, "slip.nml")
    assert status(f) == "slip"
    assert f["summary/t_final"][0] == pytest.approx(1.43560110, abs=1e-8)
    assert f["summary/friction_needed_max"][0] <= 0.085
    f, _ = run_hard(ellroll, tmp_path, "slip.nml", edits=[("dt = 1.0e-3", "dt = 2.5e-4")])
    assert f["summary/t_final"][0] == pytest.approx(1.43560110, abs=1e-8)


@pytest.mark.parametrize("name", sorted(p.name for p in HARD.glob("*.nml") if p.name != "long_run.nml"))
def test_both_pairs_end_each_hard_case_as_it_states(ellroll, ellroll_debug, tmp_path, name):
    """dop853 and vern9 on every hard input, at the loosest and the tightest
    tolerance, on the Debug build (runtime checks, floating-point traps): no
    crash at either. At rtol 1e-14 both end each case with the input's own
    status (its rk4 or gauss4 run on the Release build), and where that is a
    model limit, at the same time to 1e-9 s."""
    text = (HARD / name).read_text()
    method = re.search(r"method = '(\w+)', dt = [^,]+,", text)
    f, _ = run_hard(ellroll, tmp_path, name)
    own = [status(f, case) for case in range(len(f["summary/status"]))]
    f.close()
    ends = {}
    for pair in ("dop853", "vern9"):
        for rtol in ("1.0e-3", "1.0e-14"):
            f, result = run_hard(ellroll_debug, tmp_path, name,
                                 edits=[(method.group(0), f"method = '{pair}', rtol = {rtol}, atol = {rtol}, ")])
            assert not result.stderr.strip() or "warning" in result.stderr, result.stderr
            if rtol == "1.0e-14":
                assert [status(f, case) for case in range(len(own))] == own, (pair, own)
                ends[pair] = f["summary/t_final"][:]
            f.close()
    for case, outcome in enumerate(own):
        if outcome != "completed":
            assert abs(ends["dop853"][case] - ends["vern9"][case]) < 1e-9, (outcome, ends)


def principal_radii(point, a, b, c):
    """Both principal radii of curvature of the cup (x/a)^2 + (y/b)^2 +
    ((z - c)/c)^2 = 1 at a point of it: the inverse eigenvalues of the
    shape operator P H P / |grad F| on the tangent plane."""
    d = np.diag([1 / a**2, 1 / b**2, 1 / c**2])
    x = np.array([point[0], point[1], point[2] - c])
    grad = 2 * d @ x
    n = grad / np.linalg.norm(grad)
    p = np.eye(3) - np.outer(n, n)
    shape = p @ (2 * d) @ p / np.linalg.norm(grad)
    curvatures = sorted(np.linalg.eigvalsh(shape))[1:]       # the normal direction's 0 left out
    return 1 / np.array(curvatures)


def test_peaks_at_no_fit_are_taken_clear_of_its_singular_approach(ellroll, tmp_path):
    """The peaks of a case that ends at no_fit are those of its path where
    both radii of curvature at the contact exceed 1.05 R: the force grows
    towards the limit, so its peak lies where the path leaves that part,
    between the last sample (one per step) clear of it and the next; the
    same bits for any fit_margin (the singular peak grows as 1 / fit_margin
    without the cut), of the size of the last samples."""
    peaks = {}
    for margin in ("1.0e-3", "1.0e-9"):
        f, _ = run_hard(ellroll, tmp_path, "reaches_no_fit.nml",
                        edits=[("t_end = 1.0 /", f"t_end = 1.0, fit_margin = {margin} /"),
                               ("interval = 1.0e-3", "interval = 1.0e-4")])
        with f:
            assert status(f) == "no_fit" and f["summary/peaks_truncated"][0] == 1
            peaks[margin] = {n: f[f"summary/{n}"][0] for n in (
                "absolute_acceleration_max", "absolute_acceleration_max_time", "horizontal_force_max",
                "reaction_normal_max", "displacement_max")}
            t, contact = f["time"][:], f["trajectory/contact"][0]
            force = np.hypot(*f["trajectory/reaction"][0, :, :2].T)
            done = np.isfinite(force)
            clear = np.array([np.all(principal_radii(p, 1.0, 0.4, 0.2) > 1.05 * 0.7) if ok else False
                              for p, ok in zip(contact, done)])
            assert 0 < clear.sum() < done.sum()             # the cut leaves some samples out
            mass = 100.0 / 9.81
            k = np.flatnonzero(clear)[-1]
            assert force[clear].max() == force[k] < peaks[margin]["horizontal_force_max"] < force[k + 1]
            assert t[k] < peaks[margin]["absolute_acceleration_max_time"] < t[k + 1]
            last = force[done][-1] / mass
            assert 0.1 * last < peaks[margin]["absolute_acceleration_max"] < 10 * last
    assert peaks["1.0e-3"] == peaks["1.0e-9"]
