"""The peaks of a case that ends at a model limit are taken over its path
clear of the cup's curvature (both principal radii above 1.05 R,
docs/output.md): towards `no_fit` the forces grow as 1 / (r_min - R), so the
largest clear value lies where the path leaves the clear part, and that
point is located on the flow's dense output. Seeded balls rolling into the
fit limit, in a fixed and a shaken cup: every method and step (and the
Debug build) gives the figures of vern9 at rtol 1e-12 to 1e-7 and their
times to 1e-8 s; a case in a batch of lanes gives the same bits as alone;
and no stored sample clear of the curvature lies above the peak."""
import h5py
import numpy as np
import pytest

from conftest import run

PEAKS = ("reaction_normal_max", "horizontal_force_max", "absolute_acceleration_max", "displacement_max")
TIMES = ("displacement_max_time", "absolute_acceleration_max_time")
METHODS = ("method = 'rk4', dt = 1e-3", "method = 'rk4', dt = 2.5e-4", "method = 'gauss4', dt = 5e-4",
           "method = 'dop853', rtol = 1e-9", "method = 'vern9', rtol = 1e-8")


def scene(seed):
    """A ball of radius 0.7 m rolling up the paper cup's short axis, where
    the cup's radius of curvature falls from 0.8 m to the ball's; odd seeds
    in a cup shaken along both horizontal axes."""
    rng = np.random.default_rng(7100 + seed)
    x = float(rng.uniform(-0.03, 0.03))
    w = float(rng.uniform(0.8, 1.5) * rng.choice([-1, 1]))
    spin = float(rng.uniform(-1, 1))
    text = ("&geometry a = 1.0, b = 0.4, c = 0.2 /\n&ball radius = 0.7, weight = 100.0 /\n"
            f"&initial x = {x!r}, y = 0.0, omega = {w!r}, 0.1, {spin!r} /\n"
            "&integration INTEGRATION, t_end = 3.0 /\n&output file = 'out.h5', interval = 1.0e-3 /\n")
    if seed % 2:
        text += ("&excitation kind = 'harmonic', amplitude = 0.5, 1.0, 0.0, frequency = 1.0, "
                 f"phase = {float(rng.uniform(0, 6))!r} /\n")
    return text


def figures(exe, folder, name, text):
    (folder / f"{name}.nml").write_text(text.replace("'out.h5'", f"'{name}.h5'"))
    result = run(exe, "run", f"{name}.nml", "-q", cwd=folder)
    assert result.returncode == 0, result.stderr
    with h5py.File(folder / f"{name}.h5", "r") as f:
        s = f["summary"]
        return [{key: s[key][k] for key in ("status", "t_final", "peaks_truncated") + PEAKS + TIMES}
                for k in range(s["status"].shape[0])]


@pytest.mark.parametrize("seed", range(6))
def test_every_method_gives_the_peaks_where_the_path_leaves_the_clear_part(ellroll, ellroll_debug, tmp_path, seed):
    text = scene(seed)
    reference = figures(ellroll, tmp_path, "vern9", text.replace("INTEGRATION", "method = 'vern9', rtol = 1e-12"))[0]
    assert reference["status"] == 3 and reference["peaks_truncated"] == 1, reference
    runs = [(ellroll, method) for method in METHODS] + [(ellroll_debug, METHODS[seed % len(METHODS)])]
    for k, (exe, method) in enumerate(runs):
        case = figures(exe, tmp_path, f"m{k}", text.replace("INTEGRATION", method))[0]
        label = (seed, method, str(exe))
        assert case["status"] == 3 and case["peaks_truncated"] == 1, label
        for key in PEAKS:
            assert case[key] == pytest.approx(reference[key], rel=1e-7), (label, key, case[key], reference[key])
        for key in TIMES:
            assert abs(case[key] - reference[key]) < 1e-8, (label, key, case[key], reference[key])


def principal_radii_above(contact, radius, axes=(1.0, 0.4, 0.2)):
    """Whether both principal radii of curvature of the cup (x/a)^2 +
    (y/b)^2 + ((z - c)/c)^2 = 1 at each contact point exceed 1.05 radius:
    the shape operator on the tangent plane, from the gradient and the
    Hessian of the ellipsoid's function."""
    inverse = 1 / np.square(axes)
    clear = []
    for p in contact:
        gradient = 2 * (p - [0, 0, axes[2]]) * inverse
        n = gradient / np.linalg.norm(gradient)
        tangent = np.linalg.svd(n[None, :])[2][1:]                  # two unit vectors normal to n
        shape = tangent @ np.diag(2 * inverse) @ tangent.T / np.linalg.norm(gradient)
        clear.append(np.all(1 / np.linalg.eigvalsh(shape) > 1.05 * radius))
    return np.array(clear)


@pytest.mark.parametrize("seed", range(2))
def test_no_sample_clear_of_the_curvature_lies_above_the_peak(ellroll, tmp_path, seed):
    text = scene(seed).replace("INTEGRATION", "method = 'rk4', dt = 1e-5").replace("interval = 1.0e-3", "interval = 1.0e-4")
    case = figures(ellroll, tmp_path, "fine", text)[0]
    with h5py.File(tmp_path / "fine.h5", "r") as f:
        time, contact = f["time"][:], f["trajectory/contact"][0]
        force = np.hypot(*f["trajectory/reaction"][0, :, :2].T)
    done = np.isfinite(force)
    clear = np.zeros_like(done)
    clear[done] = principal_radii_above(contact[done], 0.7)
    last = np.flatnonzero(clear)[-1]
    # the samples (every 1e-4 s) clear of the curvature lie below the peak,
    # the first beyond it above, and the peak's time between them
    assert force[clear].max() < case["horizontal_force_max"] < force[last + 1], seed
    assert time[last] < case["absolute_acceleration_max_time"] < time[last + 1], seed


def test_a_case_in_a_batch_gives_the_peaks_it_gives_alone(ellroll, tmp_path):
    base = scene(1).replace("INTEGRATION", "method = 'dop853', rtol = 1e-9")
    starts = [-0.02, -0.005, 0.01, 0.025]
    batch = figures(ellroll, tmp_path, "batch",
                    base + "&sweep name = 'x', values = " + ", ".join(map(repr, starts)) + " /\n")
    x_line = next(line for line in base.splitlines() if line.startswith("&initial"))
    for k, x in enumerate(starts):
        alone_text = base.replace(x_line, x_line.split(", y")[0].split("x = ")[0] + f"x = {x!r}, y" +
                                  x_line.split(", y", 1)[1])
        alone = figures(ellroll, tmp_path, f"alone{k}", alone_text)[0]
        assert batch[k]["status"] == 3, (x, batch[k])
        for key in PEAKS + TIMES + ("t_final",):
            assert batch[k][key] == alone[key], (x, key, batch[k][key], alone[key])
