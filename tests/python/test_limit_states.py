"""User limit states (&limit_state): /limit_state/NAME per case equals what
numpy finds from /summary and the status (exceeded: ended at a model limit,
or completed with the figure above the capacity; undefined, -1: completed
with the figure NaN), the same bits after shards are merged and after a
killed run is resumed, read by ellroll_post.suite's statistics and
fragility fits and by `ellroll summary --suite` alike (an undefined case
counted apart, in no fraction or fit); bad groups are refused with the
file, group, variable and value."""
import json
import math
import shutil

import h5py
import numpy as np
import pytest

import ellroll_post
from ellroll_post import suite
from conftest import ROOT, run
from test_campaign import assert_same_datasets, kill_after_records, record_bytes

SUITE = """&geometry    a = 1.0, b = 0.4, c = 0.2 /
&ball        radius = 0.2, weight = 2620.0 /
&initial     x = 0.0, y = 0.0, omega = 0.0, 0.0, 0.0 /
&integration method = 'rk4', dt = 1.0e-3, t_end = 12.0 /
&excitation  kind = 'record' /
&record      name = 'SYN1', record_file = 'records/SYN1_H1.AT2', 'records/SYN1_H2.AT2' /
&record      name = 'SYN2', record_file = 'records/SYN2_H1.AT2', 'records/SYN2_H2.AT2' /
&record      name = 'SYN3', record_file = 'records/SYN3_H1.AT2', 'records/SYN3_H2.AT2', factor = 1.5 /
&sweep       name = 'scale', values = 40.0, 70.0, 90.0 /
&sweep       name = 'rolling_resistance', values = 1.0e-5, 1.0e-3 /
&output      file = 'out.h5', interval = 0.1, fields = 'center' /
&limit_state name = 'drift', figure = 'displacement_max', capacity = 0.1 /
&limit_state name = 'shock', figure = 'Absolute_acceleration_max', capacity = 14.0 /
&limit_state name = 'rest', figure = 'residual_displacement', capacity = 0.001 /
"""
STATES = {"drift": ("displacement_max", 0.1, "m"), "shock": ("absolute_acceleration_max", 14.0, "m/s^2")}


def write(folder, text=SUITE):
    if not (folder / "records").exists():
        shutil.copytree(ROOT / "input" / "records", folder / "records")
    (folder / "suite.nml").write_text(text)
    return "suite.nml"


@pytest.fixture(scope="module")
def whole(ellroll, tmp_path_factory):
    folder = tmp_path_factory.mktemp("limit_states")
    name = write(folder)
    result = run(ellroll, "run", name, "-q", "--threads", "2", "-o", "whole.h5", cwd=folder)
    assert result.returncode == 0, result.stderr
    return folder / "whole.h5"


def test_flags_equal_the_status_and_the_figures(whole):
    with h5py.File(whole, "r") as f:
        status = f["summary/status"]
        names = np.array(status.attrs["flag_meanings"].split())[status[()]]
        assert {"completed", "liftoff"} <= set(names)
        at_limit = np.isin(names, ["rim", "no_fit", "slip", "liftoff"])
        for state, (figure, capacity, units) in STATES.items():
            flags = f[f"limit_state/{state}"]
            assert flags.dtype == np.int8 and flags.shape == names.shape
            assert flags.attrs["figure"] == figure and flags.attrs["capacity"] == capacity
            assert flags.attrs["capacity_units"] == units and flags.attrs["units"] == "1"
            expected = at_limit | ((names == "completed") & (f[f"summary/{figure}"][()] > capacity))
            assert np.array_equal(flags[()], expected.astype(np.int8)), state
            # both kinds occur among the completed cases: the test can fail
            completed = names == "completed"
            assert 0 < np.sum(flags[()][completed]) < np.sum(completed), state
        # no ball comes to rest by t_end = 12 s: residual_displacement is NaN
        # for every completed case, which has no outcome for 'rest' (-1)
        rest = f["limit_state/rest"]
        assert np.all(np.isnan(f["summary/residual_displacement"][()][names == "completed"]))
        assert np.array_equal(rest[()], np.where(at_limit, 1, np.where(names == "completed", -1, 0)))
        assert rest.attrs["flag_meanings"] == "undefined not_exceeded exceeded"
        assert rest.attrs["flag_values"].dtype == np.int8 and list(rest.attrs["flag_values"]) == [-1, 0, 1]


def test_suite_statistics_read_the_flags(whole):
    with ellroll_post.open(whole) as f:
        assert sorted(suite.limit_state_columns(f)) == ["drift", "rest", "shock"]
        table = suite.suite_statistics(f)
        status = np.array(f.status_names())
        displacement = f.summary("displacement_max")
    assert {"n_drift", "fraction_drift", "n_shock", "fraction_shock"} <= set(table.columns)
    row = table[(table["scale"] == 40.0) & (table["rolling_resistance"] == 1e-5)].iloc[0]
    with ellroll_post.open(whole) as f:
        cases = (f.input_column("scale") == 40.0) & (f.input_column("rolling_resistance") == 1e-5)
    hit = np.sum(cases & (status == "completed") & (displacement > 0.1)) + np.sum(cases & (status == "liftoff"))
    assert row["n_drift"] == hit and row["fraction_drift"] == hit / cases.sum()
    # 'rest': the completed cases are undefined, counted apart; the limit cases exceed
    completed = np.sum(cases & (status == "completed"))
    assert completed > 0 and row["n_undefined_rest"] == completed and row["n_undefined_drift"] == 0
    assert row["n_rest"] == np.sum(cases & (status == "liftoff"))
    if row["n_rest"]:
        assert row["fraction_rest"] == 1.0
    else:
        assert math.isnan(row["fraction_rest"])


def test_shards_merge_and_a_resume_give_the_same_flags(ellroll, whole):
    folder = whole.parent
    name = "suite.nml"
    for i in range(2):
        result = run(ellroll, "run", name, "-q", "--shard", f"{i}/2", "-o", f"shard_{i}.h5", cwd=folder)
        assert result.returncode == 0, result.stderr
    result = run(ellroll, "merge", "merged.h5", "shard_1.h5", "shard_0.h5", cwd=folder)
    assert result.returncode == 0, result.stderr
    assert_same_datasets(whole, folder / "merged.h5")
    journal = folder / "out.h5.journal"
    # 18 cases of about 17 ms on one thread: killed after the second
    assert kill_after_records([str(ellroll), "run", name, "-q", "--threads", "1"], folder, journal, 2,
                              record_bytes())
    assert journal.exists() and not (folder / "out.h5").exists()
    result = run(ellroll, "run", name, "-q", "--resume", cwd=folder)
    assert result.returncode == 0, result.stderr
    assert_same_datasets(whole, folder / "out.h5")
    with h5py.File(folder / "out.h5", "r") as f:
        assert sorted(f["limit_state"]) == sorted(["case", "scale", "rolling_resistance", "record", "drift", "shock",
                                                   "rest"])
        assert -1 in f["limit_state/rest"][()] and 1 in f["limit_state/rest"][()]


def test_a_file_without_limit_states_has_no_group(paper_file):
    with h5py.File(paper_file, "r") as f:
        assert "limit_state" not in f


@pytest.mark.parametrize("group, words", [
    ("name = '1x', figure = 'displacement_max', capacity = 0.1", "name = '1x': must be an identifier"),
    ("name = 'd', figure = 'displacment_max', capacity = 0.1",
     "figure = 'displacment_max': unknown figure 'displacment_max'; did you mean displacement_max?"),
    ("name = 'd', figure = 'linear_periods', capacity = 1", "unknown figure 'linear_periods'"),
    ("name = 'd', figure = 'wall_time', capacity = 1", "unknown figure 'wall_time'"),
    ("name = 'd', figure = 'displacement_max'", "capacity is required but not given"),
    ("name = 'd', figure = 'displacement_max', capacity = 1e400", "capacity = 1e400: must be a finite number"),
    ("name = 'd', figure = 'displacement_max', capacity = -1.0", "capacity = -1.0: must be >= 0"),
    ("name = 'd', figure = 'sliding_time', capacity = -5e-324", "capacity = -5e-324: must be >= 0"),
    ("figure = 'theta_max', capacity = 0.1", "name is required but not given"),
    ("name = 'd', capacity = 0.1", "figure is required but not given"),
    ("name = 'drift', figure = 'theta_max', capacity = 0.1", "name = 'drift': already names the &limit_state at"),
    ("name = 'd', figure = 'theta_max', capacity = 0.1, margin = 2", "unknown variable margin = 2"),
])
def test_bad_limit_states(ellroll, tmp_path, group, words):
    name = write(tmp_path, SUITE + f"&limit_state {group} /\n")
    result = run(ellroll, "check", name, cwd=tmp_path)
    assert result.returncode == 2, result.stderr
    assert "suite.nml:" in result.stderr and "&limit_state" in result.stderr and words in result.stderr, \
        result.stderr


STATUS_NAMES = ["pending", "completed", "rim", "no_fit", "slip", "liftoff", "nonfinite", "constraint", "invalid",
                "unstable"]


def test_a_name_the_suite_statistics_take_is_refused(ellroll, whole, tmp_path):
    """A limit state's columns (n_NAME, n_undefined_NAME, fraction_NAME) and
    fragility must not be the statistics' own: every name behind an n_ or
    fraction_ column of a suite's statistics that is not a limit state of
    its own (cases, completed, limit, liftoff, ...), each status, the model
    limits' fragility (model_limit) and a name whose n_NAME would be another
    state's n_undefined_ column are refused, in any case of letters; others
    alike in form pass."""
    with ellroll_post.open(whole) as f:
        columns = list(suite.suite_statistics(f).columns)
    own = {c.split("_", 1)[1] for c in columns if c.startswith(("n_", "fraction_"))}
    own -= {state for state in own if state.startswith("undefined_")} | {"drift", "shock", "rest"}
    assert {"cases", "completed", "limit", "unresolved", "liftoff"} <= own
    refused = sorted(own | set(STATUS_NAMES) | {"model_limit", "undefined_drift", "Undefined_x", "CASES", "Liftoff"})
    for name in refused + ["cases_2", "limits", "undefined", "liftoff_x", "model"]:
        state = f"&limit_state name = '{name}', figure = 'displacement_max', capacity = 0.1 /\n"
        result = run(ellroll, "check", write(tmp_path, SUITE + state), cwd=tmp_path)
        if name in refused:
            assert result.returncode == 2 and f"suite.nml:15: &limit_state: name = '{name}': is a name the suite " \
                "statistics take" in result.stderr, (name, result.stderr)
        else:
            assert result.returncode == 0, (name, result.stderr)


def test_a_capacity_of_zero_is_any_value_above_zero(ellroll, tmp_path):
    """capacity = 0 is a bound (every figure a limit state bounds is >= 0):
    sliding_time > 0 flags the cases that slid at all, 0 those that rolled
    throughout (two scales of one record, mu = 0.3: 0.94 s of sliding at
    scale 30, none at scale 1)."""
    text = SUITE.split("&excitation")[0].replace("weight = 2620.0", "weight = 2620.0, mu = 0.3, slip = 'slide'") \
        .replace("t_end = 12.0", "t_end = 6.0") + """&excitation  kind = 'record', record_file = 'records/SYN1_H1.AT2', 'records/SYN1_H2.AT2' /
&sweep       name = 'scale', values = 1.0, 30.0 /
&output      file = 'out.h5', interval = 0.1, fields = 'center' /
&limit_state name = 'slid', figure = 'sliding_time', capacity = 0.0 /
"""
    name = write(tmp_path, text)
    result = run(ellroll, "run", name, "-q", cwd=tmp_path)
    assert result.returncode == 0, result.stderr
    with h5py.File(tmp_path / "out.h5", "r") as f:
        sliding = f["summary/sliding_time"][()]
        assert list(f["summary/status"][()]) == [1, 1]
        assert sliding[0] == 0 and sliding[1] > 0.5
        assert list(f["limit_state/slid"][()]) == [0, 1]
        assert f["limit_state/slid"].attrs["capacity"] == 0.0


def test_ellroll_summary_suite_equals_the_python_statistics(ellroll, whole):
    """`ellroll summary --suite` (JSON and CSV): the columns of
    ellroll_post.suite.suite_statistics in its order, every number the same
    (the percentiles in numpy's arithmetic)."""
    import csv
    import io
    import json
    import math
    with ellroll_post.open(whole) as f:
        table = suite.suite_statistics(f)
    result = run(ellroll, "summary", whole, "--suite", "--format", "json")
    assert result.returncode == 0, result.stderr
    report = json.loads(result.stdout)
    assert report["stripe_inputs"] == ["scale", "rolling_resistance"] and report["percentiles"] == "linear"
    assert list(report["stripes"][0]) == list(table.columns)
    assert report["units"]["displacement_max_p50"] == "m" and report["units"]["n_drift"] == "1"
    rows = list(csv.DictReader(io.StringIO(run(ellroll, "summary", whole, "--suite", "--format", "csv").stdout)))
    assert len(report["stripes"]) == len(rows) == len(table) == 6
    checked = 0
    for stripe, row, (_, expected) in zip(report["stripes"], rows, table.iterrows()):
        for name, value in expected.items():
            for got in (stripe[name], row[name]):
                got = math.nan if got is None or got == "nan" else float(got)
                assert (math.isnan(got) and math.isnan(value)) or got == value, (name, got, value)
                checked += 1
    assert checked > 400
    assert any(math.isnan(v) for v in table["displacement_max_p50"]) or table["n_completed"].min() < 3
    text = run(ellroll, "summary", whole, "--suite")
    assert text.returncode == 0 and "6 stripes" in text.stdout and "fraction_drift" in text.stdout


def test_ellroll_summary_suite_in_the_debug_build(ellroll_debug, whole, paper_file):
    """The Debug build (bounds checks, FP traps) prints every format, also of
    a file with no varied input (one stripe) and one case."""
    import json
    for path in (whole, paper_file):
        for fmt in ("table", "csv", "json"):
            result = run(ellroll_debug, "summary", path, "--suite", "--format", fmt)
            assert result.returncode == 0, result.stderr
        stripes = json.loads(result.stdout)["stripes"]
        assert len(stripes) == (6 if path == whole else 1)


REST = "&limit_state name = 'rest', figure = 'residual_displacement', capacity = 0.0015 /\n"


@pytest.fixture(scope="module")
def resting(ellroll, tmp_path_factory):
    """input/isolator_fragility.nml and a limit state on residual_displacement:
    defined (the ball came to rest) for the completed cases at rolling
    resistance 1e-3 m, NaN for those at 1e-5 m (the ball never stops)."""
    folder = tmp_path_factory.mktemp("resting")
    text = (ROOT / "input" / "isolator_fragility.nml").read_text().replace("isolator_fragility.h5", "rest.h5")
    result = run(ellroll, "run", write(folder, text + REST), "-q", "--threads", "2", cwd=folder)
    assert result.returncode == 0, result.stderr
    return folder / "rest.h5"


def test_an_undefined_figure_is_no_outcome_in_counts_and_fits(ellroll, resting):
    """A completed case whose figure is NaN has flag -1 and no outcome for
    the limit state: `ellroll summary --suite` and ellroll_post count it in
    n_undefined_NAME, leave it out of fraction_NAME, and fit the fragility
    over the defined cases only (the same maximum likelihood as
    fragility.fit_stripes of the counts numpy finds without them)."""
    from ellroll_post.fragility import fit_stripes
    capacity = 0.0015
    with h5py.File(resting, "r") as f:
        status = f["summary/status"]
        names = np.array(status.attrs["flag_meanings"].split())[status[()]]
        residual = f["summary/residual_displacement"][()]
        scale, resistance = f["summary/scale"][()], f["summary/rolling_resistance"][()]
        flags = f["limit_state/rest"][()]
    completed, limit = names == "completed", np.isin(names, ["rim", "no_fit", "slip", "liftoff"])
    undefined = completed & np.isnan(residual)
    exceeded = limit | (completed & (residual > capacity))
    assert np.array_equal(flags, np.where(exceeded, 1, np.where(undefined, -1, 0)))
    # each kind occurs: 6 undefined (1e-5 m), at 1e-3 m both sides of the capacity
    assert undefined.sum() == 6 and np.sum(completed & (residual > capacity)) == 2
    assert np.sum(completed & (residual <= capacity)) == 4
    report = json.loads(run(ellroll, "summary", resting, "--suite", "--format", "json").stdout)
    with ellroll_post.open(resting) as f:
        table = suite.suite_statistics(f)
        fits, _ = suite.suite_fragility(f, bootstrap=0)
    assert len(report["stripes"]) == len(table) == 10
    for stripe, (_, row) in zip(report["stripes"], table.iterrows()):
        cases = (scale == row["scale"]) & (resistance == row["rolling_resistance"])
        known = np.sum(cases & (completed | limit)) - np.sum(cases & undefined)
        expected = {"n_rest": np.sum(cases & exceeded), "n_undefined_rest": np.sum(cases & undefined),
                    "fraction_rest": np.sum(cases & exceeded) / known if known else math.nan}
        for name, value in expected.items():
            for got in (stripe[name], row[name]):
                got = math.nan if got is None else got
                assert got == value or (math.isnan(got) and math.isnan(value)), (name, got, value)
    finite = 0
    for value in (1e-5, 1e-3):
        here = resistance == value
        defined = here & (limit | (completed & ~undefined))
        levels = np.unique(scale[defined])
        n = np.array([np.sum(defined & (scale == x)) for x in levels])
        z = np.array([np.sum(defined & exceeded & (scale == x)) for x in levels])
        fortran = [r for r in report["fragility"] if r["limit_state"] == "rest" and r["rolling_resistance"] == value]
        python = fits[(fits["limit_state"] == "rest") & (fits["rolling_resistance"] == value)]
        assert len(fortran) == len(python) == 1
        for row in (fortran[0], python.iloc[0]):
            assert row["n_known"] == n.sum() and row["n_exceeded"] == z.sum(), row
            assert row["n_undefined"] == np.sum(here & undefined) and row["n_points"] == levels.size
        if 0 < z.sum() < n.sum():
            fit = fit_stripes(levels, n, z, bootstrap=0)
            for row in (fortran[0], python.iloc[0]):
                assert row["note"] == ""
                assert row["theta"] == pytest.approx(fit.theta, rel=1e-6)
                assert row["beta"] == pytest.approx(fit.beta, rel=1e-6)
            finite += 1
        else:           # 1e-5 m: only the lift-offs are defined
            assert fortran[0]["note"] == python.iloc[0]["note"] == "every case exceeds: no fit"
    assert finite == 1


def test_the_fragility_figure_counts_only_the_defined_cases(resting):
    """ellroll-plot fragility's counts per stripe (exceeded/cases) leave the
    undefined cases out: at 1e-5 m only the lift-offs count."""
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    fig, ax = plt.subplots()
    with ellroll_post.open(resting) as f:
        ellroll_post.plot_fragility(ax, f, bootstrap=20, limit_state="rest")
    counts = sorted(t.get_text() for t in ax.texts if t.get_gid() == "fragility-count")
    plt.close(fig)
    # 1e-3 m: 40 1/3, 70 2/3, 80 2/3, 90 3/3, 120 3/3; 1e-5 m: 70 1/1, 80 2/2, 90 3/3, 120 3/3
    assert counts == sorted(["1/3", "2/3", "2/3", "3/3", "3/3", "1/1", "2/2", "3/3", "3/3"])
