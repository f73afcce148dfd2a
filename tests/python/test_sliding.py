"""Sliding with Coulomb friction (&ball slip = 'slide'): the flat-plate
limit (a = b = c = 1e6 m near the bottom, slope below 1e-6) against the
closed forms of a ball spinning set down and of a ball launched sliding;
the friction's work is the energy lost in a triaxial cup with several
switches; a mu that rolling never reaches gives the rolling run bit for
bit; the inputs are checked."""
import random

import h5py
import numpy as np
import pytest

from conftest import FULL, ROOT, run

R, MU, G = 0.1, 0.2, 9.81
PLATE = """&geometry a = 1e6, b = 1e6, c = 1e6 /
&ball radius = 0.1, mass = 1.0, mu = 0.2, slip = 'slide' /
&environment g = 9.81 /
&initial x = 0, y = 0, omega = {omega}, velocity = {velocity} /
&integration {integration}, t_end = 0.3 /
&output file = 'out.h5', interval = 1e-3 /
"""
METHODS = {"rk4": "method = 'rk4', dt = 1e-3", "dop853": "method = 'dop853', rtol = 1e-10",
           "vern9": "method = 'vern9', rtol = 1e-12"}


def run_text(ellroll, folder, text):
    (folder / "case.nml").write_text(text)
    result = run(ellroll, "run", "case.nml", "-q", "--overwrite", cwd=folder)
    assert result.returncode == 0, result.stderr
    return h5py.File(folder / "out.h5", "r")


@pytest.mark.parametrize("method", METHODS)
def test_a_spinning_ball_set_down_rolls_off_at_two_sevenths(ellroll, tmp_path, method):
    omega0 = 10.0
    with run_text(ellroll, tmp_path, PLATE.format(omega="0, 10, 0", velocity="0, 0, 0",
                                                  integration=METHODS[method])) as f:
        s = {k: f["summary"][k][0] for k in ("status", "sliding_time", "slip_episodes", "friction_energy")}
        omega = f["trajectory/omega"][0]
        center = f["trajectory/center"][0]
        t = f["time"][()]
    t_slide = 2 * R * omega0 / (7 * MU * G)                      # 0.1456 s
    assert s["status"] == 1 and s["slip_episodes"] == 1
    assert s["sliding_time"] == pytest.approx(t_slide, rel=1e-6)
    assert s["friction_energy"] == pytest.approx(R**2 * omega0**2 / 7, rel=1e-6)
    assert omega[-1, 1] == pytest.approx(2 / 7 * omega0, rel=1e-6)  # rolling at (2/7) R omega0
    x_end = MU * G * t_slide**2 / 2 + 2 / 7 * R * omega0 * (t[-1] - t_slide)
    assert center[-1, 0] == pytest.approx(x_end, rel=1e-6)


@pytest.mark.parametrize("method", METHODS)
def test_a_ball_launched_sliding_rolls_at_five_sevenths(ellroll, tmp_path, method):
    v0 = 1.0
    with run_text(ellroll, tmp_path, PLATE.format(omega="0, 0, 0", velocity="1.0, 0, 0",
                                                  integration=METHODS[method])) as f:
        s = {k: f["summary"][k][0] for k in ("status", "sliding_time", "friction_energy", "slip_speed_max")}
        omega = f["trajectory/omega"][0]
        center = f["trajectory/center"][0]
        t = f["time"][()]
    t_slide = 2 * v0 / (7 * MU * G)
    assert s["status"] == 1
    assert s["sliding_time"] == pytest.approx(t_slide, rel=1e-6)
    assert s["friction_energy"] == pytest.approx(v0**2 / 7, rel=1e-6)
    assert s["slip_speed_max"] == pytest.approx(v0, rel=1e-12)
    assert R * omega[-1, 1] == pytest.approx(5 / 7 * v0, rel=1e-6)
    x_end = 12 * v0**2 / (49 * MU * G) + 5 / 7 * v0 * (t[-1] - t_slide)
    assert center[-1, 0] == pytest.approx(x_end, rel=1e-6)


SWITCH_METHODS = ("method = 'rk4', dt = 1e-3", "method = 'rk4', dt = 1e-4", "method = 'dop853', rtol = 1e-10",
                  "method = 'vern9', rtol = 1e-12")


@pytest.mark.parametrize("omega, velocity, closed_form", [("0, 10, 0", "0, 0, 0", 2 * R * 10 / (7 * MU * G)),
                                                          ("0, 0, 0", "1.0, 0, 0", 2 * 1.0 / (7 * MU * G))],
                         ids=["spinning", "launched"])
def test_every_method_puts_the_plate_s_switch_at_one_time(ellroll, tmp_path, omega, velocity, closed_form):
    """The flat plate's one switch (the slip stops), at sliding_time: the
    closed forms 2 R omega0 / (7 mu g) and 2 v0 / (7 mu g) to the cup's slope
    (7.1e-9 and -1.7e-7 of them, the same for every method), and rk4 at
    dt 1e-3 and 1e-4, dop853 and vern9 within 1e-9 of each other (3e-15
    measured: the stop located inside the step, the slip's last 1e-6
    taken to its zero)."""
    times = []
    for integration in SWITCH_METHODS:
        with run_text(ellroll, tmp_path, PLATE.format(omega=omega, velocity=velocity,
                                                      integration=integration)) as f:
            assert f["summary/status"][0] == 1 and f["summary/slip_episodes"][0] == 1
            times.append(f["summary/sliding_time"][0])
    times = np.array(times)
    assert np.all(np.abs(times / closed_form - 1) < 1e-6)
    assert np.ptp(times) < 1e-9 * closed_form


TRIAXIAL = """&geometry a = 1.0, b = 0.4, c = 0.2 /
&ball radius = 0.2, weight = 2620.0, mu = {mu}, slip = '{slip}' /
&initial x = 0.0, y = 0.0, omega = -2.0, 2.0, 20.0 /
&integration method = 'rk4', dt = {dt}, t_end = 5.0 /
&output file = 'out.h5', interval = 1e-2 /
"""


def test_the_friction_work_is_the_energy_lost(ellroll, tmp_path):
    """The paper's case with mu = 0.05: it slides from the start, rolls
    at 3.0 s, slides again at 4.19 s and rolls at 4.37 s; E(t_end) - E(0)
    against the friction's work mu N |u| integrated along the steps (and
    the stopping impulses)."""
    with run_text(ellroll, tmp_path, TRIAXIAL.format(mu=0.05, slip="slide", dt=5e-5)) as f:
        energy = f["trajectory/energy"][0]
        work = f["summary/friction_energy"][0]
        episodes = f["summary/slip_episodes"][0]
        status = f["summary/status"][0]
    assert status == 1 and episodes == 2
    assert work > 80                                         # J, of E0 - m g R = 524 J
    # -6.4e-10 measured (the trapezoidal rule over the steps and substeps)
    assert abs(energy[-1] - energy[0] + work) < 2e-9 * work


BALANCE = {"rk4": ("method = 'rk4', dt = 1e-4", "method = 'rk4', dt = 5e-5"),
           "dop853": ("method = 'dop853', rtol = 1e-7", "method = 'dop853', rtol = 1e-9"),
           "vern9": ("method = 'vern9', rtol = 1e-6", "method = 'vern9', rtol = 1e-7")}


@pytest.mark.parametrize("method", BALANCE)
def test_the_energy_balance_closes_as_the_tolerance_falls(ellroll, tmp_path, method):
    """The paper's case with mu = 0.05 up to 4.3 s (slides, rolls at 3.0 s,
    slides again at 4.19 s): (E(t_end) - E(0) + friction_energy) / friction_energy
    at two step sizes or tolerances of each method is below 5e-9 and falls
    with them, or is below 1e-11 at both (measured: rk4 1.2e-9, 3.1e-10 at
    dt 1e-4, 5e-5 (the trapezoidal rule's h^2); dop853 7.1e-12, 3.2e-13 at
    rtol 1e-7, 1e-9; vern9 2.5e-12, 2.2e-12 at rtol 1e-6, 1e-7, where the
    aligned slip law takes the small slip in long steps). An error of the
    friction's tally that does not fall with the tolerance (a quadrature of
    the long steps' own) fails it."""
    residuals = []
    for integration in BALANCE[method]:
        text = TRIAXIAL.format(mu=0.05, slip="slide", dt=1e-4).replace(
            "method = 'rk4', dt = 0.0001", integration).replace("t_end = 5.0", "t_end = 4.3")
        assert integration in text
        with run_text(ellroll, tmp_path, text) as f:
            energy = f["trajectory/energy"][0]
            work = f["summary/friction_energy"][0]
            assert f["summary/status"][0] == 1 and f["summary/slip_episodes"][0] == 2
        assert work > 80
        residuals.append(abs(energy[-1] - energy[0] + work) / work)
    assert residuals[0] < 5e-9 and (residuals[1] < residuals[0] / 2 or max(residuals) < 1e-11), residuals


def test_a_mu_never_reached_gives_the_rolling_run_bit_for_bit(ellroll, tmp_path):
    runs = {}
    for slip in ("end", "slide"):
        folder = tmp_path / slip
        folder.mkdir()
        with run_text(ellroll, folder, TRIAXIAL.format(mu=0.5, slip=slip, dt=1e-3)) as f:
            runs[slip] = {k: f["trajectory"][k][()] for k in f["trajectory"]}
            # (the checksum also covers the fields and switches a sliding run stores besides)
            runs[slip].update({f"summary/{k}": f["summary"][k][()] for k in f["summary"]
                               if k not in ("wall_time", "checksum") and isinstance(f["summary"][k], h5py.Dataset)})
    for key, value in runs["end"].items():
        assert np.array_equal(value.view(np.uint8), runs["slide"][key].view(np.uint8)), key


@pytest.mark.parametrize("change,message", [
    ("slip = 'slide'", "slip = 'maybe'"),
])
def test_unknown_slip_is_refused(ellroll, tmp_path, change, message):
    text = PLATE.format(omega="0, 10, 0", velocity="0, 0, 0", integration=METHODS["rk4"]).replace(change, message)
    (tmp_path / "case.nml").write_text(text)
    result = run(ellroll, "run", "case.nml", "-q", "--overwrite", cwd=tmp_path)
    assert result.returncode == 2
    assert "slip" in result.stderr and "'end' or 'slide'" in result.stderr


def test_gauss4_is_refused_for_sliding(ellroll, tmp_path):
    """gauss4's Newton iteration does not converge at the switch into
    sliding: the input check names &ball slip and the method."""
    text = PLATE.format(omega="0, 10, 0", velocity="0, 0, 0", integration="method = 'gauss4', dt = 1e-3")
    (tmp_path / "case.nml").write_text(text)
    result = run(ellroll, "run", "case.nml", "-q", "--overwrite", cwd=tmp_path)
    assert result.returncode == 2
    assert "case.nml:2: &ball: slip = 'slide': does not run with &integration method = 'gauss4'" in result.stderr
    assert not (tmp_path / "out.h5").exists()


@pytest.mark.parametrize("velocity,slip,words", [
    ("1.0, 0, 0.1", "slide", "tangent"),
    ("1.0, 0, 0", "end", "slip = 'slide'"),
])
def test_a_bad_initial_velocity_is_refused(ellroll, tmp_path, velocity, slip, words):
    text = PLATE.format(omega="0, 0, 0", velocity=velocity, integration=METHODS["rk4"])
    text = text.replace("slip = 'slide'", f"slip = '{slip}'")
    (tmp_path / "case.nml").write_text(text)
    result = run(ellroll, "run", "case.nml", "-q", "--overwrite", cwd=tmp_path)
    assert result.returncode == 2
    assert "velocity" in result.stderr and words in result.stderr, result.stderr


@pytest.mark.parametrize("threads", ["1", "2"])
def test_a_sweep_of_sliding_cases_gives_each_cases_own_run(ellroll, tmp_path, threads):
    """Sliding cases in a campaign (a sweep that a fixed-cup rolling case
    would run in SIMD batches): each case equals its own single run bit for
    bit, with the switches of its own sliding, on any number of threads."""
    case = PLATE.format(omega="0, 10, 0", velocity="0, 0, 0", integration=METHODS["rk4"])
    alone = {}
    for mu in (0.2, 0.3):
        with run_text(ellroll, tmp_path, case.replace("mu = 0.2", f"mu = {mu}")) as f:
            alone[mu] = {k: f["summary"][k][0] for k in ("sliding_time", "slip_episodes", "friction_energy")}
            alone[mu]["omega"] = f["trajectory/omega"][0]
    mus = (0.2, 0.3) * 5                 # more cases than SIMD lanes
    (tmp_path / "sweep.nml").write_text(case.replace("'out.h5'", "'sweep.h5'")
                                        + f"&sweep name = 'mu', values = {', '.join(map(str, mus))} /\n")
    result = run(ellroll, "run", "sweep.nml", "-q", "--threads", threads, cwd=tmp_path)
    assert result.returncode == 0, result.stderr
    with h5py.File(tmp_path / "sweep.h5", "r") as f:
        for i, mu in enumerate(mus):
            assert alone[mu]["slip_episodes"] == 1
            for k in ("sliding_time", "slip_episodes", "friction_energy"):
                assert f["summary"][k][i] == alone[mu][k], (i, k)
            assert np.array_equal(f["trajectory/omega"][i], alone[mu]["omega"]), i


@pytest.mark.parametrize("method", METHODS)
@pytest.mark.parametrize("omega, velocity, u0", [("0, 10, 0", "0, 0, 0", R * 10.0), ("0, 0, 0", "1.0, 0, 0", 1.0)])
def test_the_regime_and_slip_speed_follow_the_closed_form(ellroll, tmp_path, method, omega, velocity, u0):
    """Per sample on the flat plate: the slip speed |u| = |u0| - (7/2) mu g t
    while sliding (regime 1), 0 while rolling (regime 0); the regime turns at
    /summary's sliding_time; the friction stored while sliding is mu N."""
    with run_text(ellroll, tmp_path, PLATE.format(omega=omega, velocity=velocity,
                                                  integration=METHODS[method])) as f:
        regime = f["trajectory/regime"][0]
        slip = f["trajectory/slip_speed"][0]
        reaction = f["trajectory/reaction"][0]
        normal = f["trajectory/normal"][0]
        sliding_time = f["summary/sliding_time"][0]
        t = f["time"][()]
    t_slide = 2 * u0 / (7 * MU * G)
    sliding = t < t_slide - 1e-9
    rolling = t > t_slide + 1e-9
    assert set(np.unique(regime)) == {0.0, 1.0}
    assert np.array_equal(regime[sliding | rolling], sliding[sliding | rolling].astype(float))
    assert np.all(t[regime == 1] <= sliding_time) and np.all(t[regime == 0] >= sliding_time)
    # 1e-6 of |u0|, as the speeds above (near its end |u| is a difference of terms
    # of size |u0|; 1.7e-7 |u0| measured with rk4 at dt 1e-3)
    assert slip[sliding] == pytest.approx(u0 - 3.5 * MU * G * t[sliding], rel=1e-6, abs=1e-6 * u0)
    assert np.all(slip[rolling] == 0)
    n = np.einsum("ij,ij->i", reaction, normal)
    tangential = np.linalg.norm(reaction - n[:, None] * normal, axis=1)
    assert tangential[sliding] / n[sliding] == pytest.approx(MU, rel=1e-12)
    assert np.all(tangential[rolling] / n[rolling] < 1e-6)    # the plate's slope: rolling needs no friction


def test_the_regime_samples_add_up_to_the_sliding_time(ellroll, tmp_path):
    """Several episodes in a triaxial cup: the samples flagged sliding, each
    standing for one output interval, add up to /summary's sliding_time
    within one interval per switch; |u| > 0 exactly where the flag is 1."""
    interval = 1e-2
    with run_text(ellroll, tmp_path, TRIAXIAL.format(mu=0.05, slip="slide", dt=5e-5)) as f:
        regime = f["trajectory/regime"][0]
        slip = f["trajectory/slip_speed"][0]
        sliding_time = f["summary/sliding_time"][0]
        episodes = f["summary/slip_episodes"][0]
    assert episodes == 2
    assert abs(np.count_nonzero(regime == 1) * interval - sliding_time) <= 2 * episodes * interval
    starts = np.count_nonzero(np.diff(regime) == 1) + (regime[0] == 1)
    assert starts == episodes
    assert np.all(slip[regime == 0] == 0) and np.all(slip[regime == 1][1:] > 0)


def test_a_rolling_case_stores_no_regime_unless_asked(ellroll, tmp_path):
    text = TRIAXIAL.format(mu=0.05, slip="end", dt=1e-3)
    with run_text(ellroll, tmp_path, text) as f:
        assert "regime" not in f["trajectory"] and "slip_speed" not in f["trajectory"]
    asked = text.replace("interval = 1e-2", "interval = 1e-2, fields = 'all'")
    with run_text(ellroll, tmp_path, asked) as f:
        assert np.all(f["trajectory/regime"][0][np.isfinite(f["trajectory/regime"][0])] == 0)
        assert f["trajectory/slip_speed"].attrs["units"] in (b"m/s", "m/s")


LAUNCH = """&geometry a = 1.0, b = 0.4, c = 0.2 /
&ball radius = 0.2, weight = 2620.0, mu = {mu}, slip = 'slide', inertia_factor = {k} /
&initial x = 0.0, y = 0.0, omega = 0.0, 0.0, 0.0, velocity = {v}, 0.0, 0.0 /
&integration {integration}, t_end = {t_end} /
&output file = 'out.h5', interval = {interval} /
"""
M_CUP = 2620.0 / 9.81


@pytest.mark.parametrize("method", METHODS)
def test_energy_drift_of_a_sliding_start_is_the_balance_residual(ellroll, tmp_path, method):
    """A ball launched sliding: E0 holds the launch's kinetic energy, and
    energy_drift is max |E - E0 + W| / |E0| over the step ends, W the
    friction's work so far. Flat plate (m = 1): E0 = g R + v0^2 / 2, the
    friction takes v0^2 / 7."""
    v0 = 1.0
    with run_text(ellroll, tmp_path, PLATE.format(omega="0, 0, 0", velocity="1.0, 0, 0",
                                                  integration=METHODS[method])) as f:
        energy = f["trajectory/energy"][0]
        drift = f["summary/energy_drift"][0]
        work = f["summary/friction_energy"][0]
    e0 = G * R + v0**2 / 2
    assert energy[0] == pytest.approx(e0, rel=1e-12)
    assert energy[0] - energy[-1] == pytest.approx(v0**2 / 7, rel=1e-6)
    # (the last sample's E and the step end's E + W are summed apart: a few
    # units of round-off between them)
    assert abs(energy[-1] - energy[0] + work) / e0 <= drift + 8 * np.finfo(float).eps
    # 2.5e-9 measured with rk4 (the friction's work by the trapezoidal rule
    # over the last piece of sliding); the loss itself is 0.096 of E0
    assert drift < 1e-7


def test_energy_drift_of_the_launch_in_the_cup(ellroll, tmp_path):
    """The probe's triaxial launch (v0 = 0.5 m/s, mu = 0.1): E0 = m g R +
    m v0^2 / 2 = 557.38 J, and the balance closes over the step ends."""
    with run_text(ellroll, tmp_path, LAUNCH.format(mu=0.1, k=0.4, v=0.5, integration="method = 'rk4', dt = 1e-3",
                                                   t_end=3.0, interval=0.01)) as f:
        energy = f["trajectory/energy"][0]
        drift = f["summary/energy_drift"][0]
        work = f["summary/friction_energy"][0]
        status = f["summary/status"][0]
    assert status == 1
    assert energy[0] == pytest.approx(2620.0 * 0.2 + M_CUP * 0.5**2 / 2, rel=1e-12)
    assert 9.0 < work < 9.6                            # m v0^2 / 7 = 9.54 J on a plate
    assert abs(energy[-1] - energy[0] + work) / energy[0] <= drift < 1e-7    # 3.7e-9 measured


@pytest.mark.parametrize("method", METHODS)
def test_a_launch_without_gravity_is_held_by_the_cup(ellroll, tmp_path, method):
    """g = 0, launched at v0 = 0.5 m/s along x from the bottom: the cup
    pushes with N = m v0^2 / (a^2/c - R) = 5.2083 N (the centre's circle),
    friction -mu N, E0 = m v0^2 / 2; the ball slides on (a rolling start at
    rest lifts off, since nothing presses it)."""
    text = LAUNCH.format(mu=0.1, k=0.4, v=0.5, integration=METHODS[method], t_end=1.0, interval=0.01)
    text = text.replace("weight = 2620.0", "mass = 100.0") + "&environment g = 0.0 /\n"
    with run_text(ellroll, tmp_path, text) as f:
        meanings = f["summary/status"].attrs["flag_meanings"].split()
        status = meanings[f["summary/status"][0]]
        reaction = f["trajectory/reaction"][0, 0]
        energy = f["trajectory/energy"][0]
        work = f["summary/friction_energy"][0]
    normal = 100.0 * 0.5**2 / (1.0**2 / 0.2 - 0.2)
    assert status == "completed"
    assert reaction == pytest.approx([-0.1 * normal, 0.0, normal], rel=1e-12, abs=1e-12)
    assert energy[0] == pytest.approx(12.5, rel=1e-14)
    assert 0 < work < 12.5 and energy[-1] - energy[0] + work == pytest.approx(0, abs=1e-6)


@pytest.mark.parametrize("v0", [5, 20, 100])
def test_the_friction_work_ends_where_a_case_ends_at_a_limit(ellroll, tmp_path, v0):
    """Launched fast in the paper's cup, the ball climbs to where it no
    longer fits (no_fit at 0.18, 0.044, 0.0087 s). The friction's work
    stops at the last step end clear of the cup's curvature, as the peaks
    do (N grows without bound towards the limit): it is no more than the
    energy lost by the last step end (a sample at every step), and the
    balance closes over the step ends to the method's accuracy."""
    with run_text(ellroll, tmp_path, LAUNCH.format(mu=0.1, k=0.4, v=v0, integration="method = 'rk4', dt = 1e-3",
                                                   t_end=3.0, interval=1e-3)) as f:
        energy = f["trajectory/energy"][0]
        s = {k: f["summary"][k][0] for k in ("status", "friction_energy", "energy_drift", "peaks_truncated")}
    energy = energy[np.isfinite(energy)]
    assert s["status"] == 3 and s["peaks_truncated"] == 1
    e0 = energy[0]
    # (equality to round-off where the last clear step end is the last sample)
    assert 0 < s["friction_energy"] <= e0 - energy[-1] + (s["energy_drift"] + 1e-12) * e0
    # measured 5.2e-4, 1.3e-3, 2.0e-3: the trapezoidal rule over a step in
    # which N changes by several times its size (1.5e-4 for v0 = 100 at dt 1e-5)
    assert s["energy_drift"] < 5e-3


@pytest.mark.parametrize("method", METHODS)
def test_a_stiff_slip_stops_inside_a_step(ellroll_debug, tmp_path, method):
    """A large mu or a small inertia factor stops the slip in
    |u| / (mu g (1 + 1/k)) (5e-11 s at k = 1e-3, mu = 1e6, |u| = 0.5 m/s), far inside a
    step: located there, it loses the stopping impulse's energy
    m v0^2 k / (2 (1 + k)), on the Debug build (floating-point traps), for a
    seeded grid of k and mu at and inside their bounds."""
    rng = np.random.default_rng(20261126)
    grid = [(1e-3, 1e6), (1e-3, 1e2), (0.4, 1e6), (2 / 3, 1e6)]
    grid += [(10 ** rng.uniform(-3, np.log10(2 / 3)), 10 ** rng.uniform(2, 6)) for _ in range(3)]
    integration = {"rk4": "method = 'rk4', dt = 1e-3", "dop853": "method = 'dop853', rtol = 1e-8",
                   "vern9": "method = 'vern9', rtol = 1e-8"}[method]
    for k, mu in grid:
        v0 = rng.uniform(0.2, 1.0)
        text = LAUNCH.format(mu=repr(mu), k=repr(k), v=repr(v0), integration=integration, t_end=0.3, interval=0.01)
        with run_text(ellroll_debug, tmp_path, text) as f:
            energy = f["trajectory/energy"][0]
            s = {n: f["summary"][n][0] for n in ("status", "friction_energy", "sliding_time")}
        loss = M_CUP * v0**2 / 2 * k / (1 + k)
        case = (k, mu, v0)
        assert s["status"] == 1, case
        assert s["sliding_time"] < 1e-3, case
        assert np.all(energy <= energy[0]), case
        # the stop's loss to 2.6e-8 (1e-12 where the stop takes under 1e-6 s)
        assert energy[0] - energy[1] == pytest.approx(loss, rel=1e-6), case
        # the work is the trapezoidal rule over the piece of the stop, in which
        # N changes with v^2 / rho by up to 1 %: 4.7e-3 measured
        assert s["friction_energy"] == pytest.approx(loss, rel=1e-2), case


@pytest.mark.parametrize("change, words", [
    ("inertia_factor = 0.4", "inertia_factor = 1e-4: must be between 0.001 and"),
    ("inertia_factor = 0.4", "inertia_factor = 1e-300: must be between 0.001 and"),
    ("mu = 0.1", "mu = 1.0000001e6: must be > 0 and <= 1000000"),
    ("mu = 0.1", "mu = 0.0: must be > 0 and <= 1000000 (leave mu out for unlimited friction)"),
])
def test_a_ball_beyond_the_bounds_is_refused(ellroll_debug, tmp_path, change, words):
    given = words.split(":")[0]
    text = LAUNCH.format(mu=0.1, k=0.4, v=0.5, integration="method = 'rk4', dt = 1e-3", t_end=0.1, interval=0.01)
    (tmp_path / "case.nml").write_text(text.replace(change, given))
    result = run(ellroll_debug, "run", "case.nml", "-q", "--overwrite", cwd=tmp_path)
    assert result.returncode == 2
    assert "case.nml:2: &ball: " + words in result.stderr, result.stderr


@pytest.mark.parametrize("integration", ["method = 'dop853', rtol = 1e-8", "method = 'dop853', rtol = 1e-9",
                                         "method = 'vern9', rtol = 1e-8", "method = 'vern9', rtol = 1e-10"])
def test_a_slip_that_stops_where_rolling_needs_nearly_mu_ends_once(ellroll, tmp_path, integration):
    """The triaxial cup at mu = 0.05 over 5 s: the second episode's slip
    falls to zero (about 4.370 s) where rolling's friction is close to mu N,
    and hovers there at the size of the pair's error; once it has for 64
    steps it counts as stopped. The sliding time is 3.181279 s (dop853 at
    rtol 1e-10 and vern9 at 1e-12 agree to 1e-9 s). A slip left to hover
    takes the pairs' steps down to some 1e-7 s for tens of milliseconds:
    millions of right-hand sides, and a sliding time off by the hover."""
    text = TRIAXIAL.replace("method = 'rk4', dt = {dt}", integration).format(mu=0.05, slip="slide")
    with run_text(ellroll, tmp_path, text) as f:
        status = f["summary/status"][0]
        sliding_time = f["summary/sliding_time"][0]
        episodes = f["summary/slip_episodes"][0]
        n_rhs = f["summary/n_rhs"][0]
    assert status == 1 and episodes == 2
    assert sliding_time == pytest.approx(3.181279, abs=3e-5)
    assert n_rhs < 3_000_000        # 86k (dop853, 1e-8) to 1.6M (vern9, 1e-10)


def test_a_fixed_step_that_chatters_under_a_strong_record_goes_on_sliding(ellroll, tmp_path):
    """Three records at scale 10 (mu = 0.05, 6 s): rk4's slip stops where
    rolling needs just over mu N and slides again at the same instant, on
    and on within a step; after 8 such switches the step's rest goes on
    sliding. Each case completes with vern9's episodes (rtol 1e-12), none
    ending early at the chatter, and rk4 at dt = 1e-4 and 5e-5 s and dop853
    at rtol 1e-10 have its sliding time to 1e-6 s (measured: 5e-8 s, rk4;
    1e-8 s, dop853)."""
    records = ROOT / "input" / "records"
    suite = "".join(f"&record name = 'SYN{k}', record_file = '{records}/SYN{k}_H1.AT2', '{records}/SYN{k}_H2.AT2' /\n"
                    for k in (1, 2, 3))
    runs = {}
    for name, integration in (("rk4_1e-4", "method = 'rk4', dt = 1e-4"), ("rk4_5e-5", "method = 'rk4', dt = 5e-5"),
                              ("dop853", "method = 'dop853', rtol = 1e-10"), ("vern9", "method = 'vern9', rtol = 1e-12")):
        text = (TRIAXIAL.replace("method = 'rk4', dt = {dt}", integration).replace("t_end = 5.0", "t_end = 6.0")
                .replace("omega = -2.0, 2.0, 20.0", "omega = 0.0, 0.0, 0.0").format(mu=0.05, slip="slide")
                + "&excitation kind = 'record' /\n" + suite + "&sweep name = 'scale', values = 10.0 /\n")
        with run_text(ellroll, tmp_path, text) as f:
            runs[name] = {key: f[f"summary/{key}"][:] for key in ("status", "sliding_time", "slip_episodes")}
    reference = runs["vern9"]
    assert list(reference["status"]) == [1, 1, 1]
    for name in ("rk4_1e-4", "rk4_5e-5", "dop853"):
        assert list(runs[name]["status"]) == [1, 1, 1], name
        assert np.all(runs[name]["slip_episodes"] == reference["slip_episodes"]), name
        assert np.max(np.abs(runs[name]["sliding_time"] - reference["sliding_time"])) < 1e-6, name


@pytest.mark.parametrize("method, rtol", [(m, r) for m in ("dop853", "vern9") for r in (1e-9, 1e-10, 1e-11, 1e-12)])
def test_long_steps_to_the_stop_take_the_friction_s_work_exactly(ellroll, tmp_path, method, rtol):
    """A flat plate with its output interval the whole run, so that the
    pairs' steps are long and one of them ends where the slip stops: the
    friction's work over it from steps from its start, not from its
    interpolant (whose stages at u = 0 have a friction of round-off's
    direction: 1.5e-3 of the work off). Seeded random balls, spins and
    launches: friction_energy against the energy lost and the closed
    forms m R^2 omega0^2 / 7 and m v0^2 / 7."""
    rng = np.random.default_rng(45)
    number = lambda value: repr(float(value))  # noqa: E731
    for case in range(6):
        radius, mu, g = rng.uniform(0.01, 0.3), rng.uniform(0.1, 1.0), rng.choice([1.62, 9.81, 24.8])
        mass, angle = rng.uniform(0.5, 200.0), rng.uniform(0, 2 * np.pi)
        size = rng.uniform(1.0, 30.0)
        if case % 2 == 0:          # spinning about a horizontal axis, set down
            omega, velocity = (size * np.cos(angle), size * np.sin(angle), 0.0), (0.0, 0.0, 0.0)
            speed, lost = radius * size, mass * radius**2 * size**2 / 7
        else:                      # launched sliding without spin
            speed = size / 10
            omega, velocity = (0.0, 0.0, 0.0), (speed * np.cos(angle), speed * np.sin(angle), 0.0)
            lost = mass * speed**2 / 7
        t_slide = 2 * speed / (7 * mu * g)
        t_end = float(f"{1.5 * t_slide:.3g}")
        text = (f"&geometry a = 1e6, b = 1e6, c = 1e6 /\n"
                f"&ball radius = {number(radius)}, mass = {number(mass)}, mu = {number(mu)}, slip = 'slide' /\n"
                f"&environment g = {number(g)} /\n"
                f"&initial x = 0, y = 0, omega = {', '.join(map(number, omega))}, "
                f"velocity = {', '.join(map(number, velocity))} /\n"
                f"&integration method = '{method}', rtol = {rtol}, t_end = {t_end} /\n"
                f"&output file = 'out.h5', interval = {t_end} /\n")
        with run_text(ellroll, tmp_path, text) as f:
            s = {k: f["summary"][k][0] for k in ("status", "friction_energy", "energy_drift", "sliding_time")}
            energy = f["trajectory/energy"][0]
        label = f"case {case}: {text}"
        assert s["status"] == 1, label
        assert s["friction_energy"] == pytest.approx(energy[0] - energy[-1], rel=1e-9), label
        assert s["friction_energy"] == pytest.approx(lost, rel=1e-6), label
        assert s["sliding_time"] == pytest.approx(t_slide, rel=1e-6), label


NEAR_RIM = """&geometry a = 1.0, b = 0.4, c = 0.2 /
&ball radius = 0.01, mass = 1.0, mu = 0.01, slip = 'slide' /
&initial x = 0.0, y = {y}, omega = 0.0, 0.0, 0.0 /
&integration {integration}, t_end = 0.2 /
&output file = 'out.h5', interval = 0.01 /
"""


@pytest.mark.parametrize("y", [0.39999, 0.3999999, 0.399995])
def test_a_fixed_step_follows_a_start_at_rest_near_the_rim_at_order_four(ellroll, tmp_path, y):
    # weak friction (mu N far below the weight's pull along the steep wall,
    # n_z = 0.014 at y = 0.39999): the ball slides down from rest; rk4's
    # contact converges at order 4 to vern9's
    def contact(integration):
        folder = tmp_path / integration.replace(" ", "").replace("'", "").replace(",", "_").replace("=", "")
        folder.mkdir()
        with run_text(ellroll, folder, NEAR_RIM.format(y=y, integration=integration)) as f:
            status = f["summary/status"]
            names = dict(zip(status.attrs["flag_values"], status.attrs["flag_meanings"].split()))
            assert names[status[0]] == "completed", integration
            assert f["summary/t_final"][0] == pytest.approx(0.2, abs=1e-12)
            return f["trajectory/contact"][0]
    reference = contact("method = 'vern9', rtol = 1e-12")
    errors = [np.abs(contact(f"method = 'rk4', dt = {dt!r}") - reference).max() for dt in (1e-3, 5e-4, 2.5e-4)]
    orders = np.log2(np.array(errors[:-1]) / np.array(errors[1:]))
    assert errors[-1] < 1e-7, errors
    assert np.all(orders > 3.5) and np.all(orders < 4.7), (errors, orders)


def _stop_with_resistance(resistance, x, y, omega, phase, integration):
    return ("&geometry a = 1.0, b = 0.4, c = 0.2 /\n"
            f"&ball radius = 0.2, mass = 1.0, mu = 0.1, slip = 'slide', rolling_resistance = {resistance!r} /\n"
            f"&initial x = {x!r}, y = {y!r}, omega = {omega[0]!r}, {omega[1]!r}, {omega[2]!r} /\n"
            f"&integration {integration}, t_end = 0.6 /\n"
            f"&excitation kind = 'harmonic', amplitude = 3.0, 1.5, 0.0, frequency = 0.7, phase = {phase!r} /\n"
            "&output file = 'o.h5', interval = 0.01, fields = 'omega', 'regime' /\n")


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_a_fixed_step_rolls_on_from_a_stop_with_rolling_resistance_in_its_own_direction(ellroll, tmp_path, seed):
    """A shaken case that slides at once and stops at about 0.446 s, with
    rolling resistance (1e-4 to 1e-3 m): the rest of rk4's step after the
    stop rolls with the couple against the stop's own rolling, not against
    the rolling before the slip began, so omega after the stop stays within
    rk4's error of vern9's at rtol 1e-13 (2e-9 to 4e-9 rad/s at dt 1e-3 and
    2.5e-4; a couple of the old direction leaves 4e-7 to 7e-7, at every dt)."""
    rng = random.Random(seed)
    resistance = 1e-3 if seed == 0 else rng.uniform(1e-4, 1e-3)
    x = 0.081953401053387 + (0 if seed == 0 else rng.uniform(-1e-3, 1e-3))
    omega = (0.6172792100270948, -2.1740820581976408, 3.5983879206424345)
    args = (resistance, x, -0.24674451151007246, omega, 2.806990937564655)
    stored = {}
    for name, integration in (("vern9", "method = 'vern9', rtol = 1e-13"), ("rk4_1e-3", "method = 'rk4', dt = 1e-3"),
                              ("rk4_2.5e-4", "method = 'rk4', dt = 2.5e-4")):
        (tmp_path / f"{name}.nml").write_text(_stop_with_resistance(*args, integration))
        done = run(ellroll, "run", f"{name}.nml", "-q", "-o", f"{name}.h5", cwd=tmp_path)
        assert done.returncode == 0, done.stderr
        with h5py.File(tmp_path / f"{name}.h5") as f:
            stored[name] = (f["trajectory/omega"][0], f["trajectory/regime"][0], f["switches/switch_time"][:],
                            f["summary/status"][0])
    omega_ref, regime, switches, status = stored["vern9"]
    assert status == 1 and len(switches) == 2 and 0.4 < switches[1] < 0.5     # slides at once, stops once
    after = np.flatnonzero(np.arange(regime.size) * 0.01 > switches[1] + 0.01)
    assert after.size > 5 and np.all(regime[after] == 0)
    for name in ("rk4_1e-3", "rk4_2.5e-4"):
        error = np.max(np.abs(stored[name][0][after] - omega_ref[after]))
        assert error < 2e-8, (name, error)


GRAZING = """&geometry a = 1.0, b = 0.4, c = 0.2 /
&ball radius = 0.2, weight = 2620.0, mu = 0.05, slip = 'slide' /
&initial x = 0.0, y = 0.0, omega = 0.0, 0.0, 0.0 /
&integration {integration}, t_end = 10.0 /
&excitation kind = 'harmonic', amplitude = 1.4356991971190205, 0.7178495985595102, 0.0, frequency = 1.25 /
&output file = 'out.h5', interval = 0.01, fields = 'center' /
"""


def test_a_slip_that_dies_at_the_pairs_error_level_stops_at_tight_tolerances(ellroll, tmp_path):
    """Harmonic shaking of the paper's cup 1e-4 above the slip threshold (mu
    = 0.05, 1.25 Hz): a slip episode ends where rolling needs nearly mu N,
    its slip falling to the size of the pair's error, where the full law's
    direction is stiff and dop853's steps at rtol 1e-12 (and 1e-11,
    ELLROLL_TEST_FULL) crawl (1e-11 s) until the slip counts as stopped
    (after 1e5 of them). The
    case completes with vern9's 28 switches at rtol 1e-12: that stop within
    2e-5 s (the crawl's span), every other switch within 1e-8 s, the centre
    within 1e-9 m (the slip there is 1e-8 m/s and less)."""
    cases = {}
    integrations = ["method = 'vern9', rtol = 1e-12", "method = 'dop853', rtol = 1e-12, atol = 1e-14"]
    if FULL:
        integrations.append("method = 'dop853', rtol = 1e-11, atol = 1e-13")
    for integration in integrations:
        with run_text(ellroll, tmp_path, GRAZING.format(integration=integration)) as f:
            assert f["summary/status"][0] == 1, integration           # completed
            cases[integration] = f["switches/switch_time"][:], f["trajectory/center"][0]
    (switches, center), *others = cases.values()
    assert len(switches) == 28
    for other_switches, other_center in others:
        late = np.sort(np.abs(other_switches - switches))
        assert late[-1] < 2e-5 and late[-2] < 1e-8, late
        assert np.abs(other_center - center).max() < 1e-9
