"""Where and when the ball comes to rest for good (/summary residual_displacement,
rest_time, at_rest) and &integration settle: against the Coulomb-damped planar
swing of docs/model.md and a reference run, with every method; NaN while the ball
moves, without rolling resistance and while the cup still moves; independent of
t_end once the ball is at rest."""
import math
import shutil

import h5py
import numpy as np
import pytest

from conftest import ROOT, run

RHO, RADIUS, DELTA, G, K = 1.0**2 / 0.2, 0.2, 2.0e-4, 9.81, 0.4
HALF_PERIOD = math.pi * math.sqrt((1 + K) * (RHO - RADIUS) / G)      # linearised x-z swing, 2.6002 s

CUP = """&geometry a = 1.0, b = 0.4, c = 0.2 /
&ball radius = 0.2, weight = 2620.0{resistance} /
&initial x = {x}, y = 0.0, omega = 0.0, 0.0, 0.0 /
&integration {integration}, t_end = {t_end}{settle} /
{excitation}&output file = 'out.h5', interval = 1.0e-2 /
"""
METHODS = {"rk4": "method = 'rk4', dt = 1.0e-3", "gauss4": "method = 'gauss4', dt = 1.0e-3",
           "dop853": "method = 'dop853', rtol = 1.0e-10", "vern9": "method = 'vern9', rtol = 1.0e-10"}
REFERENCE = "method = 'vern9', rtol = 1.0e-13, atol = 1.0e-16"
FIGURES = ("residual_displacement", "rest_time", "at_rest", "t_final")


def run_cup(ellroll, folder, integration=METHODS["rk4"], delta=DELTA, x=0.052, t_end=30.0, settle=None,
            excitation="", ball="", start=""):
    text = CUP.format(resistance=(f", rolling_resistance = {delta!r}" if delta else "") + ball, x=f"{x!r}{start}",
                      integration=integration, t_end=t_end, settle=f", settle = {settle!r}" if settle else "",
                      excitation=excitation)
    (folder / "cup.nml").write_text(text)
    result = run(ellroll, "run", "cup.nml", "-q", "--overwrite", cwd=folder)
    assert result.returncode == 0, result.stderr
    with h5py.File(folder / "out.h5", "r") as f:
        figures = {name: f["summary/" + name][0] for name in FIGURES}
        for name in ("status", "sliding_time", "slip_episodes"):
            figures[name] = f["summary/" + name][0]
        figures["center"] = f["trajectory/center"][0]
        figures["time"] = f["time"][()]
    return figures


@pytest.fixture(scope="module")
def reference(ellroll, tmp_path_factory):
    return run_cup(ellroll, tmp_path_factory.mktemp("reference"), REFERENCE)


@pytest.mark.parametrize("method", METHODS)
def test_rest_of_the_planar_swing(ellroll, tmp_path, reference, method):
    """From x = 0.052 m with delta = 2e-4 m the swing loses 2 rho delta / R =
    0.010 m of contact amplitude each half period and stops at the fifth turn,
    contact -0.002 m (centre 0.002 (1 - R / rho) = 1.92 mm from the axis):
    the linear theory to its own accuracy (the ball rests at contact -0.002021 m,
    docs/model.md: 2e-5 m of the centre; the half period of the swing of 0.05 m
    is 2.5e-3 s shorter over five), and a reference run to 1e-8 s and 1e-11 m."""
    got = run_cup(ellroll, tmp_path, METHODS[method])
    assert got["at_rest"] == 1 and reference["at_rest"] == 1
    assert got["rest_time"] == pytest.approx(5 * HALF_PERIOD, rel=5e-4)
    assert abs(got["residual_displacement"] - 0.002 * (1 - RADIUS / RHO)) < 3e-5
    assert abs(got["rest_time"] - reference["rest_time"]) < 1e-8
    assert abs(got["residual_displacement"] - reference["residual_displacement"]) < 1e-11
    # where it rests, the trajectory stays: the figure is its centre's distance there
    assert got["residual_displacement"] == math.hypot(*got["center"][-1, :2])
    resting = got["time"] >= got["rest_time"]
    assert np.all(got["center"][resting] == got["center"][-1])
    assert np.any(got["center"][got["time"] < got["rest_time"] - 0.02] != got["center"][-1])


@pytest.mark.parametrize("method", METHODS)
def test_settle_runs_on_until_the_ball_is_at_rest(ellroll, tmp_path, reference, method):
    """t_end = 10 s: still rolling, so NaN and at_rest 0; settle = 60 s runs on
    to the rest (t_final there, the trajectory still to t_end), with the rest
    time and place of the run to 30 s; settle = 2 s is not enough: t_end + 2."""
    moving = run_cup(ellroll, tmp_path, METHODS[method], t_end=10.0)
    assert moving["at_rest"] == 0 and moving["t_final"] == 10.0
    assert np.isnan(moving["residual_displacement"]) and np.isnan(moving["rest_time"])
    settled = run_cup(ellroll, tmp_path, METHODS[method], t_end=10.0, settle=60.0)
    assert settled["status"] == 1 and settled["at_rest"] == 1
    assert settled["rest_time"] <= settled["t_final"] < settled["rest_time"] + 1.0e-3
    assert len(settled["time"]) == 1001 and settled["time"][-1] == 10.0
    assert abs(settled["rest_time"] - reference["rest_time"]) < 1e-8
    assert abs(settled["residual_displacement"] - reference["residual_displacement"]) < 1e-11
    short = run_cup(ellroll, tmp_path, METHODS[method], t_end=10.0, settle=2.0)
    assert short["at_rest"] == 0 and short["t_final"] == 12.0 and np.isnan(short["residual_displacement"])


@pytest.mark.parametrize("method", ["rk4", "dop853"])
def test_settle_with_slip_slide_rests_as_rolling(ellroll, tmp_path, reference, method):
    """slip = 'slide' with a mu rolling never reaches (10; the swing needs
    |F_t|/N < 0.1): settle runs on past t_end = 10 s to the rest as the rolling
    run does (slip = 'end'), with its rest time and place: bit for bit with
    rk4 (the sliding loop's rolling steps are the rolling path's), to 1e-9
    with dop853 (the sliding loop ends its steps at the output samples)."""
    runs = [run_cup(ellroll, tmp_path, METHODS[method], t_end=10.0, settle=60.0,
                    ball=f", mu = 10.0, slip = '{slip}'") for slip in ("end", "slide")]
    rolling, sliding = runs
    for got in runs:
        assert got["status"] == 1 and got["at_rest"] == 1 and got["sliding_time"] == 0
        assert got["rest_time"] <= got["t_final"] < got["rest_time"] + 1.0e-3
        assert len(got["time"]) == 1001 and got["time"][-1] == 10.0
        assert abs(got["rest_time"] - reference["rest_time"]) < 1e-8
        assert abs(got["residual_displacement"] - reference["residual_displacement"]) < 1e-11
    if method == "rk4":
        for name in FIGURES:
            assert sliding[name].tobytes() == rolling[name].tobytes(), name
    else:
        assert abs(sliding["rest_time"] - rolling["rest_time"]) < 1e-9
        assert abs(sliding["residual_displacement"] - rolling["residual_displacement"]) < 1e-9
        assert abs(sliding["t_final"] - rolling["t_final"]) < 1e-9


@pytest.mark.parametrize("method", ["rk4", "dop853"])
def test_settle_after_sliding_rests_where_a_long_run_does(ellroll, tmp_path, method):
    """Launched sliding from the bottom at 1 m/s with mu = 0.05 and rolling
    resistance 1e-3 m: it slides for 0.48 s, then rolls and comes to rest
    at 31.5 s, past t_end = 5 s;
    settle = 50 s ends it there, at the rest time and place of a run to 60 s
    without settle (rk4: bit for bit; dop853 to 1e-9: steps past t_end are
    not cut at output samples), with the trajectory to t_end."""
    launch = dict(integration=METHODS[method], delta=1.0e-3, x=0.0, start=", velocity = 1.0, 0.0, 0.0",
                  ball=", mu = 0.05, slip = 'slide'")
    settled = run_cup(ellroll, tmp_path, t_end=5.0, settle=50.0, **launch)
    long = run_cup(ellroll, tmp_path, t_end=60.0, **launch)
    for got in (settled, long):
        assert got["status"] == 1 and got["at_rest"] == 1 and got["slip_episodes"] == 1
        assert 0.4 < got["sliding_time"] < 0.6
        assert 5.0 < got["rest_time"] < 55.0
    assert settled["rest_time"] <= settled["t_final"] < settled["rest_time"] + 1.0e-3
    assert len(settled["time"]) == 501 and settled["time"][-1] == 5.0
    assert long["t_final"] == 60.0
    tolerance = 0 if method == "rk4" else 1e-9
    assert abs(settled["rest_time"] - long["rest_time"]) <= tolerance
    assert abs(settled["residual_displacement"] - long["residual_displacement"]) <= tolerance
    assert settled["sliding_time"] == long["sliding_time"]
    assert 0 < settled["residual_displacement"] < 2 * RHO * 1.0e-3 / RADIUS   # inside the band it can rest in


def test_no_rest_without_rolling_resistance(ellroll, tmp_path):
    """Without rolling resistance the ball never stops: NaN, and settle does
    not extend the case."""
    free = run_cup(ellroll, tmp_path, delta=None, t_end=20.0, settle=60.0)
    assert free["at_rest"] == 0 and free["t_final"] == 20.0
    assert np.isnan(free["residual_displacement"]) and np.isnan(free["rest_time"])


def test_held_on_a_moving_cup_is_not_at_rest_for_good(ellroll, tmp_path):
    """At rest at the bottom, held by the couple under a harmonic base
    acceleration below delta g / R = 0.0098 m/s^2 (test_rolling_resistance.py):
    the state stays constant, but the cup never stops moving, so no rest for
    good; settle does not extend a harmonic case."""
    held = run_cup(ellroll, tmp_path, x=0.0, t_end=20.0, settle=60.0,
                   excitation="&excitation kind = 'harmonic', amplitude = 0.0095, 0.0, 0.0, frequency = 0.5 /\n")
    assert np.all(held["center"] == held["center"][0])
    assert held["at_rest"] == 0 and held["t_final"] == 20.0 and np.isnan(held["residual_displacement"])


RECORD = """&geometry a = 1.0, b = 0.4, c = 0.2 /
&ball radius = 0.2, weight = 2620.0, rolling_resistance = 1.0e-4 /
&initial x = 0.0, y = 0.0, omega = 0.0, 0.0, 0.0 /
&integration method = 'rk4', dt = 1.0e-3, t_end = {t_end}{settle} /
&excitation kind = 'record', record_file = 'records/SYN1_H1.AT2', 'records/SYN1_H2.AT2', scale = {scale} /
&output file = 'out.h5', interval = 0.01, fields = 'omega', 'normal' /
"""


def run_record(ellroll, folder, t_end, scale=30.0, settle=None):
    (folder / "record.nml").write_text(RECORD.format(t_end=t_end, scale=scale,
                                                     settle=f", settle = {settle!r}" if settle else ""))
    result = run(ellroll, "run", "record.nml", "-q", "--overwrite", cwd=folder)
    assert result.returncode == 0, result.stderr
    with h5py.File(folder / "out.h5", "r") as f:
        figures = {name: f["summary/" + name][0] for name in FIGURES}
        omega, normal = f["trajectory/omega"][0][-1], f["trajectory/normal"][0][-1]
    figures["rolling"] = np.linalg.norm(omega - np.dot(omega, normal) * normal)
    return figures


def test_residual_displacement_after_a_record(ellroll, tmp_path):
    """A 20 s record (SYN1 at scale 30, 6.8 cm peak) with rolling resistance
    1e-4 m: at t_end = 40-43 s the ball still rolls, so the residual
    displacement is NaN (the displacement at t_end varies from 3.1 to 1.5 cm
    there); with settle it comes to rest at one time and place for every t_end,
    bitwise (the steps are the same)."""
    shutil.copytree(ROOT / "input" / "records", tmp_path / "records")
    ends = (40.0, 41.0, 42.0, 43.0)
    for t_end in ends:
        moving = run_record(ellroll, tmp_path, t_end)
        assert moving["rolling"] > 0.1 and moving["at_rest"] == 0
        assert np.isnan(moving["residual_displacement"]) and np.isnan(moving["rest_time"])
    settled = [run_record(ellroll, tmp_path, t_end, settle=120.0) for t_end in ends]
    for case in settled:
        assert case["at_rest"] == 1 and case["rolling"] > 0.1          # rolling at t_end, at rest at t_final
        assert 20.0 < case["rest_time"] <= case["t_final"] < case["rest_time"] + 1.0e-3
        for name in FIGURES:
            assert case[name].tobytes() == settled[0][name].tobytes(), name
    assert 0 < settled[0]["residual_displacement"] < 2 * RHO * 1.0e-4 / RADIUS   # inside the band it can rest in


def test_held_through_the_end_of_a_record(ellroll, tmp_path):
    """SYN1 at scale 1 moves the ball by 1.9 mm; it stops at 14.7 s, held while
    the record goes on to its end (19.98 s, at rest from 20.0 s): at rest for
    good from its stop, when t_end reaches the record's padded end, not before."""
    shutil.copytree(ROOT / "input" / "records", tmp_path / "records")
    during = run_record(ellroll, tmp_path, 19.0, scale=1.0)
    assert during["at_rest"] == 0 and np.isnan(during["rest_time"])
    after = run_record(ellroll, tmp_path, 20.0, scale=1.0)
    assert after["at_rest"] == 1 and 14.0 < after["rest_time"] < 15.0
    later = run_record(ellroll, tmp_path, 30.0, scale=1.0)
    assert later["rest_time"] == after["rest_time"]
    assert later["residual_displacement"] == after["residual_displacement"]


def test_a_record_at_scale_zero_leaves_the_ball_at_rest_for_good(ellroll, tmp_path):
    """Scale 0: the cup never moves, and a ball set at the bottom with
    rolling resistance is at rest for good from t = 0 at any t_end (before
    the record's end too), where it is: residual displacement 0."""
    shutil.copytree(ROOT / "input" / "records", tmp_path / "records")
    for t_end in (1.0, 5.0, 25.0):
        case = run_record(ellroll, tmp_path, t_end, scale=0.0)
        assert case["at_rest"] == 1 and case["rest_time"] == 0 and case["t_final"] == t_end, case
        assert case["residual_displacement"] == 0, case


SUITE = """&geometry a = 1.0, b = 0.4, c = 0.2 /
&ball radius = 0.2, weight = 2620.0, rolling_resistance = 1.0e-4{slip} /
&initial x = 0.0, y = 0.0, omega = 0.0, 0.0, 0.0 /
&integration method = 'rk4', dt = 1.0e-3, t_end = 25.0, settle = 120.0 /
&excitation kind = 'record' /
&record name = 'SYN1', record_file = 'records/SYN1_H1.AT2', 'records/SYN1_H2.AT2' /
&record name = 'SYN3', record_file = 'records/SYN3_H1.AT2', 'records/SYN3_H2.AT2' /
&sweep name = 'scale', values = 1.0, 30.0 /
&output file = 'out.h5', interval = 0.01 /
"""


def test_a_record_suite_that_may_slide_settles_case_by_case(ellroll, tmp_path):
    """A suite of two records at scales 1 and 30 with settle: with slip =
    'slide' every case runs on to its own rest, as the rolling suite's (mu =
    10, never reached: the same rest to 1e-9; the rolling suite runs in
    batches); with mu = 0.05 the strong cases slide and still end at rest
    before t_end + settle, with a residual displacement each."""
    shutil.copytree(ROOT / "input" / "records", tmp_path / "records")
    suites = {}
    for name, slip in (("rolling", ""), ("never", ", mu = 10.0, slip = 'slide'"), ("slides", ", mu = 0.05, slip = 'slide'")):
        (tmp_path / "suite.nml").write_text(SUITE.format(slip=slip))
        result = run(ellroll, "run", "suite.nml", "-q", "--overwrite", cwd=tmp_path)
        assert result.returncode == 0, result.stderr
        with h5py.File(tmp_path / "out.h5", "r") as f:
            suites[name] = {k: f["summary/" + k][()] for k in FIGURES + ("status", "sliding_time")}
    rolling, never, slides = suites["rolling"], suites["never"], suites["slides"]
    assert np.all(rolling["at_rest"] == 1) and np.any(rolling["t_final"] > 25.0)
    assert np.all(never["sliding_time"] == 0) and np.all(never["at_rest"] == 1)
    for name in ("rest_time", "residual_displacement", "t_final"):
        assert np.max(np.abs(never[name] - rolling[name])) < 1e-9, name
    assert np.all(slides["status"] == 1) and np.all(slides["at_rest"] == 1)
    assert np.any(slides["sliding_time"] > 0) and np.any((slides["sliding_time"] > 0) & (slides["t_final"] > 25.0))
    assert np.all(slides["rest_time"] <= slides["t_final"]) and np.all(slides["t_final"] < 25.0 + 120.0)
    assert np.all(np.isfinite(slides["residual_displacement"]))


def test_settle_is_checked(ellroll, tmp_path):
    text = CUP.format(resistance="", x=0.0, integration="method = 'rk4', dt = 1.0e-3", t_end=1.0,
                      settle=", settle = -1.0", excitation="")
    (tmp_path / "bad.nml").write_text(text)
    result = run(ellroll, "run", "bad.nml", cwd=tmp_path)
    assert result.returncode == 2
    assert "bad.nml:4: &integration: settle = -1.0: must be between 0 and" in result.stderr
    (tmp_path / "bad.nml").write_text(text.replace("dt = 1.0e-3", "dt = 1.0e-9").replace("-1.0", "1.0e9"))
    result = run(ellroll, "run", "bad.nml", cwd=tmp_path)
    assert result.returncode == 2 and "must be at least (t_end + settle) / 1e+12" in result.stderr


def test_a_csv_and_an_at2_record_end_at_rest_alike(ellroll, tmp_path):
    """Both formats fall to zero one step past their last sample, whatever
    t_end: a 3 s record run to t_end = 1 s with settle comes to rest for good
    after the record's end, at the same time and place from a CSV as from
    AT2 files of the same samples (to the round-off of the CSV's decimal
    times)."""
    from test_records import ground, write_at2
    dt, n = 0.02, 150
    x, y = ground(21, n, dt), ground(22, n, dt)
    write_at2(tmp_path / "H1.AT2", x, dt)
    write_at2(tmp_path / "H2.AT2", y, dt)
    rows = "".join(f"{k * dt!r}, {float(a)!r}, {float(b)!r}\n" for k, (a, b) in enumerate(zip(x, y)))
    (tmp_path / "ground.csv").write_text("# units: g\n" + rows)
    results = []
    for files in ("'ground.csv'", "'H1.AT2', 'H2.AT2'"):
        got = run_cup(ellroll, tmp_path, delta=1.0e-4, x=0.0, t_end=1.0, settle=400.0,
                      excitation=f"&excitation kind = 'record', record_file = {files} /\n")
        assert got["status"] == 1 and got["at_rest"] == 1
        assert n * dt < got["rest_time"] <= got["t_final"] < 1.0 + 400.0
        results.append(got)
    csv, at2 = results
    assert abs(csv["rest_time"] - at2["rest_time"]) < 1e-9
    assert abs(csv["residual_displacement"] - at2["residual_displacement"]) < 1e-12


def test_settle_leaves_the_step_advice_as_it_is(ellroll, tmp_path):
    """The warning that dt caps an adaptive method's steps comes from a probe
    over the first 100 dt: settle does not run the probe on to the rest."""
    messages = []
    for settle in (None, 200.0):
        text = CUP.format(resistance=f", rolling_resistance = {DELTA!r}", x=0.052,
                          integration="method = 'dop853', rtol = 1.0e-6, dt = 1.0e-3", t_end=10.0,
                          settle=f", settle = {settle!r}" if settle else "", excitation="")
        (tmp_path / "cup.nml").write_text(text)
        result = run(ellroll, "run", "cup.nml", "-q", "--overwrite", cwd=tmp_path)
        assert result.returncode == 0, result.stderr
        messages.append(result.stderr)
    assert "caps dop853's steps" in messages[0] and messages[1] == messages[0]


SPINNING_STOP = """&geometry a = 0.5, b = 0.43043632453998515, c = 0.9020031461644527 /
&ball radius = 0.05440854213006758, mass = 100.0, inertia_factor = 0.1, rolling_resistance = 0.0011109046182971455 /
&initial x = 0.017112483783385368, y = -0.03235973216375581, omega = -3.431969859120537, 1.271572413852124, -5.946281168382165 /
&integration {integration}, t_end = 4.0, settle = 30.0 /
&output file = 'spin.h5', interval = 0.01, fields = 'none' /
"""


def run_spinning(ellroll, folder, name, integration, sweep=""):
    """Every /summary figure of the spinning stop (wall_time left out)."""
    (folder / f"{name}.nml").write_text(SPINNING_STOP.format(integration=integration) + sweep)
    result = run(ellroll, "run", f"{name}.nml", "-q", "-o", f"{name}.h5", cwd=folder)
    assert result.returncode == 0, result.stderr
    with h5py.File(folder / f"{name}.h5") as f:
        return {key: item[()] for key, item in f["summary"].items() if key not in ("wall_time", "case")}


def test_rk4_rests_where_a_spinning_ball_stops(ellroll, tmp_path):
    """A ball spinning at 5.9 rad/s about the normal rolls to a stop where
    the couple (3.4 rad/s^2 over the rolling inertia) just outweighs the
    drive (net 0.11 rad/s^2): the rolling part runs down along the drive
    for some 30 steps of 1e-3 s in which the couple's direction would turn
    faster than the step (docs/model.md, "Rolling resistance": the step's
    law). dop853 at rtol 1e-12 rests from 2.6461618409 s (vern9 at 1e-13
    agrees to 3e-11 s), 3.0074319 mm from the axis; rk4 and gauss4 rest
    there to their order: rk4 1.4e-6 s early at dt 1e-3, 7.5e-8 s at 5e-4
    (4.2 orders), 3.5e-11 s at 1e-4, the residual 1.3e-9 m and 1e-13 m
    off, the couple's work 2.7e-7 of it; gauss4 1.9e-7 s at 1e-3."""
    reference = run_spinning(ellroll, tmp_path, "dop853", "method = 'dop853', rtol = 1e-12, atol = 1e-15")
    assert reference["rest_time"][0] == pytest.approx(2.646162, abs=1e-6)
    errors = {}
    for name, bound, place in (("rk4 1e-3", 2e-6, 2e-9), ("rk4 5e-4", 1e-7, 2e-10), ("rk4 1e-4", 1e-9, 1e-11),
                               ("gauss4 1e-3", 3e-7, 1e-9)):
        method, dt = name.split()
        got = run_spinning(ellroll, tmp_path, method + dt, f"method = '{method}', dt = {dt}")
        assert got["at_rest"][0] == 1 and got["t_final"][0] == 4.0, name
        errors[name] = abs(got["rest_time"][0] - reference["rest_time"][0])
        assert errors[name] < bound, name
        assert abs(got["residual_displacement"][0] - reference["residual_displacement"][0]) < place, name
        assert got["rolling_resistance_energy"][0] == pytest.approx(reference["rolling_resistance_energy"][0], rel=1e-6)
    assert errors["rk4 1e-3"] / errors["rk4 5e-4"] > 2**3.5               # fourth order


# omega_z across a sweep: the first the case above; in a campaign of 9 a
# batch of 8 and a lone one
SPINS = [-5.946281168382165, -5.5, -5.0, -6.5, -4.0, -7.0, -3.0, -8.0, -2.0]


def test_a_spinning_stop_in_lanes_is_the_case_alone(ellroll, tmp_path):
    """The sweep of omega_z with rk4 in SIMD lanes and reversed (each case
    in another lane, among other neighbours, or alone): each case's summary
    bitwise the same; against each case run alone (the one-case path, whose
    steps take the same laws: docs/model.md) its rest time to 1e-12 s and its
    residual displacement to 1e-15 m; every case at rest, within 3e-4 s and
    2e-8 m of dop853 at rtol 1e-12."""
    sweep = "&sweep name = 'omega_z', values = {} /\n"
    forward = run_spinning(ellroll, tmp_path, "forward", "method = 'rk4', dt = 1e-3",
                           sweep.format(", ".join(map(repr, SPINS))))
    backward = run_spinning(ellroll, tmp_path, "backward", "method = 'rk4', dt = 1e-3",
                            sweep.format(", ".join(map(repr, SPINS[::-1]))))
    reference = run_spinning(ellroll, tmp_path, "reference", "method = 'dop853', rtol = 1e-12, atol = 1e-15",
                             sweep.format(", ".join(map(repr, SPINS))))
    for name in forward:
        assert forward[name].tobytes() == backward[name][::-1].tobytes(), name
    assert np.all(forward["at_rest"] == 1)
    assert np.max(np.abs(forward["rest_time"] - reference["rest_time"])) < 3e-4
    assert np.max(np.abs(forward["residual_displacement"] - reference["residual_displacement"])) < 2e-8
    for j in (0, 6, 8):
        text = SPINNING_STOP.format(integration="method = 'rk4', dt = 1e-3").replace(
            "-5.946281168382165 /", f"{SPINS[j]!r} /")
        (tmp_path / f"alone{j}.nml").write_text(text)
        result = run(ellroll, "run", f"alone{j}.nml", "-q", "-o", f"alone{j}.h5", cwd=tmp_path)
        assert result.returncode == 0, result.stderr
        with h5py.File(tmp_path / f"alone{j}.h5") as f:
            assert abs(f["summary/rest_time"][0] - forward["rest_time"][j]) < 1e-12
            assert abs(f["summary/residual_displacement"][0] - forward["residual_displacement"][j]) < 1e-15


def test_a_spinning_stop_in_lanes_is_the_case_alone_bitwise_in_debug(ellroll_debug, tmp_path):
    """In the Debug build (no fused multiply-adds, floating-point traps) the
    sweep's lanes take the laws of the case alone bit for bit: every summary
    figure (n_rhs included) and every stored sample of each case equals its
    run alone (the one-case path)."""
    sweep = "&sweep name = 'omega_z', values = {} /\n".format(", ".join(map(repr, SPINS)))
    (tmp_path / "lanes.nml").write_text(SPINNING_STOP.format(integration="method = 'rk4', dt = 1e-3")
                                        .replace("fields = 'none'", "fields = 'all'") + sweep)
    result = run(ellroll_debug, "run", "lanes.nml", "-q", "-o", "lanes.h5", cwd=tmp_path)
    assert result.returncode == 0, result.stderr
    with h5py.File(tmp_path / "lanes.h5") as lanes:
        for j, spin in enumerate(SPINS):
            text = SPINNING_STOP.format(integration="method = 'rk4', dt = 1e-3").replace(
                "-5.946281168382165 /", f"{spin!r} /").replace("fields = 'none'", "fields = 'all'")
            (tmp_path / f"alone{j}.nml").write_text(text)
            result = run(ellroll_debug, "run", f"alone{j}.nml", "-q", "-o", f"alone{j}.h5", cwd=tmp_path)
            assert result.returncode == 0, result.stderr
            with h5py.File(tmp_path / f"alone{j}.h5") as alone:
                assert alone["summary/at_rest"][0] == 1
                for group in ("summary", "trajectory"):
                    for name, item in alone[group].items():
                        if name in ("wall_time", "case") or (group == "trajectory" and item.ndim < 2):
                            continue
                        assert np.asarray(lanes[group][name][j]).tobytes() == np.asarray(item[0]).tobytes(), \
                            (spin, group, name)


@pytest.mark.parametrize("method", list(METHODS))
def test_a_ball_spinning_on_the_spot_is_at_rest_and_keeps_its_spin(ellroll, tmp_path, method):
    """At the bottom, spinning at 5 rad/s about the cup's normal (the
    vertical there), with rolling resistance: its contact point never moves
    (the rolling part of omega is zero), so it is at rest from t = 0
    (at_rest 1, rest_time 0, residual_displacement 0), and with no pivoting
    friction in the model its spin, and its kinetic energy J w^2 / 2, stay
    to round-off (docs/output.md)."""
    text = CUP.format(resistance=", rolling_resistance = 1e-3", x=0.0, integration=METHODS[method], t_end=2.0,
                      settle="", excitation="").replace("omega = 0.0, 0.0, 0.0", "omega = 0.0, 0.0, 5.0")
    (tmp_path / "case.nml").write_text(text)
    result = run(ellroll, "run", "case.nml", "-q", cwd=tmp_path)
    assert result.returncode == 0, result.stderr
    with h5py.File(tmp_path / "out.h5", "r") as f:
        s = {k: f["summary"][k][0] for k in ("status", "at_rest", "rest_time", "residual_displacement")}
        omega, contact = f["trajectory/omega"][0], f["trajectory/contact"][0]
    assert s["status"] == 1 and s["at_rest"] == 1 and s["rest_time"] == 0 and s["residual_displacement"] == 0, s
    assert np.abs(omega - [0.0, 0.0, 5.0]).max() < 1e-12 and np.abs(contact).max() < 1e-15, (s, omega[-1])
