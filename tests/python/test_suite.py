"""Suite statistics that know failure, the suite figure and the fragility
command, against independent truth: numpy's percentiles of the completed
cases chosen by hand (cases at a model limit, with absurd peaks, never mixed
in; two design values kept apart), the figure's artists (legend labels, log
axes, counts, limit marks), a lognormal fragility drawn at random (seeded)
and fitted back within its bootstrap interval, and the commands on a real
small suite (input/isolator_fragility.nml: input/isolator_suite.nml at
higher scales, where some records lift the ball off)."""
import csv
import io
import json
import math
import shutil
import time

import h5py
import numpy as np
import pytest
from scipy import stats

matplotlib = pytest.importorskip("matplotlib")
matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402

import ellroll_post  # noqa: E402
from ellroll_post import cli, suite  # noqa: E402
from ellroll_post.fragility import fit_stripes  # noqa: E402
from conftest import ROOT, plot_in_process, run  # noqa: E402

SCALES = (40.0, 70.0, 80.0, 90.0, 120.0)


def plot_cli(*args):
    return plot_in_process(*args)


@pytest.fixture(scope="module")
def small_suite(ellroll, tmp_path_factory):
    """input/isolator_fragility.nml: input/isolator_suite.nml's cup and 3
    records x 2 rolling resistances at five scales, 12 s: the lower scales
    complete, the higher lift the ball off."""
    folder = tmp_path_factory.mktemp("small_suite")
    shutil.copytree(ROOT / "input" / "records", folder / "records")
    text = (ROOT / "input" / "isolator_fragility.nml").read_text()
    suite_text = (ROOT / "input" / "isolator_suite.nml").read_text()
    for group in ("&geometry", "&ball", "&record      name = 'SYN3'"):
        assert [l for l in text.splitlines() if l.startswith(group)] == \
            [l for l in suite_text.splitlines() if l.startswith(group)]
    assert f"values = {', '.join(map(str, SCALES))} /" in text
    (folder / "small.nml").write_text(text.replace("isolator_fragility.h5", "small.h5"))
    start = time.perf_counter()
    result = run(ellroll, "run", "small.nml", "-q", "--threads", "2", cwd=folder)
    seconds = time.perf_counter() - start
    assert result.returncode == 0, result.stderr
    assert seconds < 10, f"the small suite took {seconds:.1f} s"
    path = folder / "small.h5"
    with ellroll_post.open(path) as f:
        status = set(f.status_names())
    assert "completed" in status and status & set(suite.MODEL_LIMITS), status
    # the input's comment: settle = 20 brings every completed case at 1e-3 m to rest, none at 1e-5 m
    with h5py.File(path, "r") as f:
        done = f["summary/status"][:] == 1
        resistance, at_rest = f["case/rolling_resistance"][:], f["summary/at_rest"][:]
        residual, t_final = f["summary/residual_displacement"][:], f["summary/t_final"][:]
        assert sorted(k for k in f["case"] if k.startswith("sa_")) == ["sa_0.2", "sa_1"]
    upper, lower = done & (resistance == 1e-3), done & (resistance == 1e-5)
    assert upper.sum() == lower.sum() == 6
    assert np.all(at_rest[upper] == 1) and np.all(np.isfinite(residual[upper])) and t_final[upper].max() < 32
    assert np.all(at_rest[lower] == 0) and np.all(np.isnan(residual[lower])) and np.all(t_final[lower] == 32)
    return path


def constructed(source, target, status=None, values=None, scale=None, extra=None):
    """A copy of an ellroll file with statuses, summary values, scales or
    extra datasets set by hand."""
    shutil.copy(source, target)
    with h5py.File(target, "r+") as f:
        if status is not None:
            codes = dict(zip(f["summary/status"].attrs["flag_meanings"].split(), f["summary/status"].attrs["flag_values"]))
            f["summary/status"][...] = [codes[s] for s in status]
        for name, column in (values or {}).items():
            f[f"summary/{name}"][...] = column
        if scale is not None:
            f["case/scale"][...] = scale
        for name, column in (extra or {}).items():
            if name in f:               # (ellroll's own, replaced by the test's)
                del f[name]
            f.create_dataset(name, data=column)
    return target


# ---------------------------------------------------------------- statistics
def table_of_cases():
    """Two scales x two rolling resistances x five records; the limit cases
    carry peaks of 1e6 (what a peak on the approach to no_fit looks like)."""
    scale = np.repeat([1.0, 2.0], 10)
    resistance = np.tile(np.repeat([1e-5, 1e-3], 5), 2)
    status = np.array(["completed"] * 20, dtype=object)
    status[[3, 4]] = ["rim", "no_fit"]                  # scale 1, 1e-5
    status[[12, 13, 14]] = ["liftoff", "slip", "nonfinite"]   # scale 2, 1e-5
    status[19] = "invalid"                              # scale 2, 1e-3
    rng = np.random.default_rng(7)
    displacement = rng.uniform(0.01, 0.2, 20)
    displacement[np.isin(status, suite.MODEL_LIMITS)] = 1e6
    displacement[5] = np.nan                            # a completed case without the figure
    drift = displacement > 0.1
    return scale, resistance, status.astype(str), displacement, drift


def test_stripe_statistics_are_numpys_over_the_completed_cases_only():
    scale, resistance, status, displacement, drift = table_of_cases()
    table = suite.stripe_statistics({"scale": scale, "rolling_resistance": resistance}, status,
                                    {"displacement_max": displacement}, {"drift": drift})
    assert len(table) == 4
    assert list(table["scale"]) == [1, 1, 2, 2] and list(table["rolling_resistance"]) == [1e-5, 1e-3] * 2
    for _, row in table.iterrows():
        cases = (scale == row["scale"]) & (resistance == row["rolling_resistance"])
        done = cases & (status == "completed")
        limit = cases & np.isin(status, ("rim", "no_fit", "slip", "liftoff"))
        values = displacement[done & np.isfinite(displacement)]
        assert row["n_cases"] == 5 and row["n_completed"] == done.sum() and row["n_limit"] == limit.sum()
        assert row["n_unresolved"] == 5 - done.sum() - limit.sum()
        assert row["fraction_limit"] == limit.sum() / (done.sum() + limit.sum())
        assert row["n_drift"] == np.sum(done & drift) + limit.sum()
        assert row["fraction_drift"] == row["n_drift"] / (done.sum() + limit.sum())
        assert row["displacement_max_n"] == values.size
        assert [row[f"displacement_max_p{q}"] for q in (16, 50, 84)] == list(np.percentile(values, [16, 50, 84]))
        assert row["displacement_max_p84"] < 1            # no 1e6 peak of a limit case
    first = table.iloc[0]                               # scale 1, 1e-5: 3 completed, rim, no_fit
    assert (first["n_completed"], first["n_limit"], first["n_rim"], first["n_no_fit"]) == (3, 2, 1, 1)
    third = table.iloc[2]                               # scale 2, 1e-5: nonfinite left out
    assert (third["n_completed"], third["n_limit"], third["n_unresolved"]) == (2, 2, 1)
    assert third["fraction_limit"] == 0.5
    assert table.iloc[3]["n_unresolved"] == 1 and table.iloc[3]["fraction_limit"] == 0


def test_lognormal_percentiles_are_the_fitted_lognormals():
    values = np.array([0.05, 0.08, 0.11, 0.2])
    table = suite.stripe_statistics({"scale": np.ones(4)}, ["completed"] * 4, {"d": values}, percentiles="lognormal")
    mean, sd = np.log(values).mean(), np.log(values).std(ddof=1)
    row = table.iloc[0]
    assert row["d_p50"] == pytest.approx(math.exp(mean), rel=1e-14)
    assert row["d_p16"] == pytest.approx(math.exp(mean - sd), rel=1e-14)
    assert row["d_p84"] == pytest.approx(math.exp(mean + sd), rel=1e-14)
    # p16 and p84 of the lognormal are its 15.87 % and 84.13 % quantiles
    assert row["d_p84"] == pytest.approx(stats.lognorm(sd, scale=math.exp(mean)).ppf(stats.norm.cdf(1)), rel=1e-12)
    with pytest.raises(ValueError, match="percentiles"):
        suite.stripe_statistics({"scale": np.ones(4)}, ["completed"] * 4, {"d": values}, percentiles="nearest")


@pytest.mark.parametrize("value", [0.07, 2.5, 1e-9])
def test_a_stripe_of_one_value_has_its_lognormal_median_and_no_spread(value):
    # ln y has no sample standard deviation with one value; exp(mean ln y) is y
    table = suite.stripe_statistics({"scale": np.ones(3)}, ["completed", "rim", "no_fit"],
                                    {"d": np.array([value, 0.3, 0.4])}, percentiles="lognormal")
    row = table.iloc[0]
    assert row["d_n"] == 1 and row["d_p50"] == pytest.approx(value, rel=1e-15)
    assert math.isnan(row["d_p16"]) and math.isnan(row["d_p84"])


def test_suite_statistics_of_a_file_keep_limit_cases_and_design_values_apart(small_suite, tmp_path):
    with h5py.File(small_suite, "r") as f:
        n = f["summary/status"].shape[0]
        scale, resistance = f["case/scale"][:], f["case/rolling_resistance"][:]
        factor = f["case/record_factor"][:]
        force = f["summary/horizontal_force_max"][:]
    status = ["completed"] * n
    status[0], status[1] = "rim", "no_fit"
    force = force.copy()
    force[:2] = 1e9
    path = constructed(small_suite, tmp_path / "c.h5", status=status, values={"horizontal_force_max": force},
                       extra={"limit_state/drift": (np.arange(n) % 3 == 0).astype(np.int8)})
    with ellroll_post.open(path) as f:
        table = suite.suite_statistics(f)
        assert set(factor) == {1.0, 1.5}                    # SYN3's factor: a record's, not a stripe
        assert table.attrs["stripe_inputs"] == ["scale", "rolling_resistance"]
        assert len(table) == len(SCALES) * 2
        assert table.attrs["units"]["horizontal_force_max_p50"] == "N"
        for _, row in table.iterrows():
            cases = (scale == row["scale"]) & (resistance == row["rolling_resistance"])
            done = cases & (np.array(status) == "completed")
            assert row["n_cases"] == 3
            assert row["horizontal_force_max_p50"] == np.median(force[done])
            assert row["horizontal_force_max_p84"] == np.percentile(force[done], 84) < 1e9
            drift = (np.arange(n) % 3 == 0)
            assert row["n_drift"] == np.sum(done & drift) + np.sum(cases & ~(np.array(status) == "completed"))
        text = suite.format_suite(table)
        assert "rolling_resistance" in text.splitlines()[0] and "linear" in text
        parsed = list(csv.DictReader(io.StringIO(suite.format_suite(table, "csv"))))
        assert len(parsed) == len(table) and float(parsed[0]["displacement_max_p50"]) == table.iloc[0]["displacement_max_p50"]
        data = json.loads(suite.format_suite(table, "json"))
        assert data["percentiles"] == "linear" and data["units"]["displacement_max_p16"] == "m"
    result = plot_cli("summary", path, "--suite", "--format", "csv")
    assert result.returncode == 0, result.stderr
    assert result.stdout == suite.format_suite(table, "csv")


# --------------------------------------------------------------------- figure
def suite_figure(path):
    fig, axes = plt.subplots(1, 2)
    with ellroll_post.open(path) as f:
        ellroll_post.plot_suite(axes, f)
        table = suite.suite_statistics(f, figures=("displacement_max", "absolute_acceleration_max"))
    return fig, axes, table


def test_suite_figure_labels_groups_counts_and_limit_cases(small_suite):
    fig, axes, table = suite_figure(small_suite)
    for ax in axes:
        labels = [line.get_label() for line in ax.get_lines()]
        assert "rolling_resistance = 1e-05 m: median" in labels and "rolling_resistance = 0.001 m: median" in labels
        assert ax.get_xlabel() == "record scale factor" and ax.get_xscale() == "linear"
        counts = sorted(t.get_text() for t in ax.texts if t.get_gid() == "suite-count")
        assert counts == sorted(f"{r.n_completed}/{r.n_cases}" for r in table.itertuples())
        marks = [line for line in ax.get_lines() if line.get_gid() == "suite-limit"]
        assert sorted(m.get_xdata()[0] for m in marks) == sorted(table["scale"][table["n_limit"] > 0])
        limits = sorted(t.get_text() for t in ax.texts if t.get_gid() == "suite-limit-count")
        assert limits == sorted(f"{r.n_limit}/{r.n_cases}" for r in table.itertuples() if r.n_limit)
        for colour_label in ("rolling_resistance = 1e-05 m: median", "rolling_resistance = 0.001 m: median"):
            line = [l for l in ax.get_lines() if l.get_label() == colour_label][0]
            rows = table[table["rolling_resistance"] == float(colour_label.split()[2])]
            quantity = "displacement_max" if ax is axes[0] else "absolute_acceleration_max"
            np.testing.assert_array_equal(line.get_ydata(), rows[f"{quantity}_p50"])
    assert axes[1].get_ylabel() == "absolute_acceleration_max, m/s$^{2}$"
    plt.close(fig)


def test_suite_figure_takes_log_axes_over_decades_and_survives_all_or_no_failures(small_suite, tmp_path, capsys):
    with h5py.File(small_suite, "r") as f:
        n = f["summary/status"].shape[0]
        scale = f["case/scale"][:]
    spread = constructed(small_suite, tmp_path / "spread.h5", scale=10.0 ** (np.searchsorted(SCALES, scale) - 3),
                         values={"displacement_max": np.linspace(1e-4, 1.0, n)}, status=["completed"] * n)
    fig, axes, _ = suite_figure(spread)
    assert axes[0].get_xscale() == "log" and axes[0].get_yscale() == "log"
    plt.close(fig)
    for name, status in (("none", ["completed"] * n), ("all", ["rim"] * n)):
        path = constructed(small_suite, tmp_path / f"{name}.h5", status=status)
        result = plot_cli("suite", path, "--out", tmp_path)
        assert result.returncode == 0 and "Traceback" not in result.stderr, result.stderr
        assert (tmp_path / f"{name}_suite.png").stat().st_size > 5000
        fig, axes, table = suite_figure(path)
        marks = [line for line in axes[0].get_lines() if line.get_gid() == "suite-limit"]
        assert len(marks) == (0 if name == "none" else len(table))
        plt.close(fig)
        assert cli.main(["fragility", str(path), "--out", str(tmp_path), "--bootstrap", "10"]) == 0
        capsys.readouterr()
        assert cli.main(["fragility", str(path), "--format", "csv"]) == 0
        rows = list(csv.DictReader(io.StringIO(capsys.readouterr().out)))
        # (a user limit state keeps the run's own /limit_state flags: only a model limit exceeds them all)
        checked = [r for r in rows if r["limit_state"] == "model_limit" or name == "all"]
        assert len(checked) == (2 if name == "none" else 6)
        assert all(r["theta"] == "nan" and ("no case exceeds" if name == "none" else "every case") in r["note"]
                   for r in checked)


# ------------------------------------------------------------------ fragility
THETA, BETA = 0.8, 0.4


def test_a_known_lognormal_fragility_is_fitted_back_within_its_bootstrap_interval():
    """Cases at ten intensities, 30 records each; each ends at the rim with
    the probability of the true fragility (seeded), a few never run.
    fragility_points counts them, the fit finds theta and beta within its
    5-95 % bootstrap interval."""
    levels = np.array([0.2, 0.35, 0.5, 0.65, 0.8, 1.0, 1.25, 1.6, 2.0, 2.5])
    rng = np.random.default_rng(11)
    x = np.repeat(levels, 30)
    p = stats.norm.cdf(np.log(x / THETA) / BETA)
    status = np.where(rng.uniform(size=x.size) < p, "rim", "completed").astype(object)
    status[::37] = "invalid"                   # never run: not counted
    status = status.astype(str)
    points, n, z = suite.fragility_points(x, status)
    assert np.array_equal(points, levels)
    for level, count, hits in zip(levels, n, z):
        at = (x == level) & (status != "invalid")
        assert count == at.sum() and hits == np.sum(at & (status == "rim"))
    fit = fit_stripes(points, n, z, bootstrap=400, seed=3)
    print(f"theta {fit.theta:.4f} {fit.theta_interval}, beta {fit.beta:.4f} {fit.beta_interval}")
    assert fit.theta_interval[0] < THETA < fit.theta_interval[1]
    assert fit.beta_interval[0] < BETA < fit.beta_interval[1]
    assert abs(math.log(fit.theta / THETA)) < 0.1 and abs(fit.beta / BETA - 1) < 0.3
    low, high = fit.band(np.array([THETA]))
    assert low[0] < 0.5 < high[0]


def probit_glm(x, n, z, iterations=100):
    """The binomial GLM with the probit link on log x, fitted by iteratively
    reweighted least squares (Fisher scoring), as statsmodels' GLM does:
    P = Phi(a + b ln x) gives theta = exp(-a / b), beta = 1 / b."""
    design = np.column_stack([np.ones_like(x), np.log(x)])
    coef = np.array([0.0, 1.0])
    for _ in range(iterations):
        eta = design @ coef
        p = np.clip(stats.norm.cdf(eta), 1e-300, 1 - 1e-16)
        density = stats.norm.pdf(eta)
        weight = n * density**2 / (p * (1 - p))
        working = eta + (z / n - p) / density
        step = np.linalg.solve(design.T @ (weight[:, None] * design), design.T @ (weight * working))
        if np.allclose(step, coef, rtol=1e-14, atol=0):
            coef = step
            break
        coef = step
    return math.exp(-coef[0] / coef[1]), 1 / coef[1]


@pytest.mark.parametrize("seed", range(5))
def test_the_fragility_fit_is_the_probit_glms(seed):
    """Counts drawn from a known lognormal (seeded): fit_stripes' maximum
    likelihood equals a probit GLM fitted independently by IRLS."""
    rng = np.random.default_rng(100 + seed)
    levels = np.geomspace(0.2, 2.5, 8)
    n = rng.integers(10, 40, size=levels.size)
    z = rng.binomial(n, stats.norm.cdf(np.log(levels / THETA) / BETA))
    fit = fit_stripes(levels, n, z)
    theta, beta = probit_glm(levels, n.astype(float), z.astype(float))
    assert fit.theta == pytest.approx(theta, rel=1e-6) and fit.beta == pytest.approx(beta, rel=1e-6)


@pytest.mark.parametrize("seed", range(6))
def test_exceedances_that_do_not_grow_with_the_intensity_have_no_fit(seed):
    """Flat or falling fractions (seeded, n records at each level; a flat
    3 of 4 included): the likelihood's supremum lies at beta -> infinity,
    so fit_stripes gives NaN (not an optimiser's last point, which drawing
    would crash on), with no interval; the same counts rising in the
    intensity get the probit GLM's fit."""
    rng = np.random.default_rng(200 + seed)
    levels = np.geomspace(0.2, 2.5, 4 + seed)
    n = np.full(levels.size, int(rng.integers(4, 20)))
    if seed == 0:
        n[:] = 4
        z = np.full(levels.size, 3)
    else:
        z = np.sort(np.round(n * rng.uniform(0.1, 0.9, levels.size)).astype(int))[::-1]
    fit = fit_stripes(levels, n, z, bootstrap=50, seed=1)
    assert math.isnan(fit.theta) and math.isnan(fit.beta)
    assert np.all(np.isnan(fit.theta_interval))
    if seed > 0 and np.ptp(z) > 0:
        rising = fit_stripes(levels, n, z[::-1])
        theta, beta = probit_glm(levels, n.astype(float), z[::-1].astype(float))
        assert rising.theta == pytest.approx(theta, rel=1e-6) and rising.beta == pytest.approx(beta, rel=1e-6)


def test_fragility_command_on_a_real_suite(small_suite, tmp_path, capsys):
    assert cli.main(["fragility", str(small_suite), "--format", "csv", "--bootstrap", "100"]) == 0
    rows = list(csv.DictReader(io.StringIO(capsys.readouterr().out)))
    with ellroll_post.open(small_suite) as f:
        table, details = suite.suite_fragility(f, bootstrap=100)
        status = np.array(f.status_names())
        scale = f.input_column("scale")
        resistance = f.input_column("rolling_resistance")
    with h5py.File(small_suite, "r") as h:
        summary = {name: h[f"summary/{name}"][:] for name in ("displacement_max", "absolute_acceleration_max")}
    # input/isolator_fragility.nml's limit states, recomputed from the /summary figures
    capacities = {"model_limit": None, "drift": ("displacement_max", 0.15),
                  "acceleration": ("absolute_acceleration_max", 9.81)}
    assert [(r["limit_state"], r["rolling_resistance"]) for r in rows] == \
        [(state, d) for state in capacities for d in ("1e-05", "0.001")]
    for row, detail in zip(rows, details):
        cases = resistance == float(row["rolling_resistance"])
        exceeded = np.isin(status, suite.MODEL_LIMITS)
        if capacities[row["limit_state"]] is not None:
            figure, capacity = capacities[row["limit_state"]]
            exceeded = exceeded | ((status == "completed") & (summary[figure] > capacity))
        expected = fit_stripes(np.array(SCALES), [np.sum(cases & (scale == s)) for s in SCALES],
                               [np.sum(cases & exceeded & (scale == s)) for s in SCALES], bootstrap=100)
        assert float(row["theta"]) == pytest.approx(expected.theta, rel=1e-12)
        assert float(row["beta"]) == pytest.approx(expected.beta, rel=1e-12)
        if "separate" in row["note"]:       # no finite maximum: no interval
            assert all(math.isnan(float(row[k])) for k in ("theta_low", "theta_high", "beta_low", "beta_high"))
        else:
            assert float(row["theta_low"]) < float(row["theta"]) < float(row["theta_high"])
        assert SCALES[0] < float(row["theta"]) < SCALES[-1]
        assert int(row["n_known"]) == cases.sum() and int(row["n_exceeded"]) == np.sum(cases & exceeded)
    # docs/isolator.md's figures (200 resamples, seed 0)
    with ellroll_post.open(small_suite) as f:
        documented = suite.suite_fragility(f, bootstrap=200)[0].iloc[0]
    assert [round(documented[k], 1) for k in ("theta", "theta_low", "theta_high")] == [74.3, 70.0, 81.0]
    assert [round(documented[k], 2) for k in ("beta", "beta_low", "beta_high")] == [0.11, 0.0, 0.21]
    result = plot_cli("fragility", small_suite, "-o", tmp_path / "f.png", "--bootstrap", "50")
    assert result.returncode == 0 and (tmp_path / "f.png").stat().st_size > 5000, result.stderr
    fig, ax = plt.subplots()
    with ellroll_post.open(small_suite) as f:
        ellroll_post.plot_fragility(ax, f, bootstrap=50)
    labels = [line.get_label() for line in ax.get_lines()]
    assert any(label.startswith("rolling_resistance = 1e-05 m: $\\theta$ = ") for label in labels), labels
    counts = {t.get_text() for t in ax.texts if t.get_gid() == "fragility-count"}
    assert "0/6" not in counts and {"0/3", "3/3"} <= counts
    assert ax.get_xlabel() == "record scale factor"
    plt.close(fig)
    assert cli.main(["fragility", str(small_suite), "--im", "Sa(7.5)", "--out", str(tmp_path)]) == 2
    error = capsys.readouterr().err
    assert "no intensity measure Sa(7.5)" in error and "scale" in error and "pga" in error \
        and "Traceback" not in error
    assert not (tmp_path / "small_fragility.png").exists()
    for spelling in ("Sa(", "Sa", "Sa)", "Sa()", "Sa(1", "sa_", "Sa((1))"):
        assert cli.main(["fragility", str(small_suite), "--im", spelling, "--out", str(tmp_path)]) == 2, spelling
        error = capsys.readouterr().err
        assert f"{spelling} is not an intensity measure's name: Sa is spelled Sa(T), Sa(T2), Sa(1.0) or sa_1" \
            in error and "Traceback" not in error, error
    assert not (tmp_path / "small_fragility.png").exists()


def test_fragility_says_what_it_leaves_out_and_refuses_a_campaign_without_stripes(ellroll, small_suite, tmp_path,
                                                                                  capsys):
    """A stripe at scale 0 has no likelihood (P = 0 there whatever theta):
    its cases are left out of n_known, and the note says how many; a file
    whose groups of equal design inputs each hold one intensity has no
    stripes: exit 2 with a message, no figure, no one-case fits. `ellroll
    summary --suite` notes the same."""
    zero = tmp_path / "zero.h5"
    shutil.copy(small_suite, zero)
    with h5py.File(zero, "r+") as f:
        scale = f["case/scale"][:]
        at_zero = scale == SCALES[0]
        for name in ("case/scale", "summary/scale"):       # (the input, and the stripes' coordinate)
            f[name][at_zero] = 0.0
    with ellroll_post.open(zero) as f:
        table, _ = suite.suite_fragility(f)
        status = np.array(f.status_names())
        resistance = f.input_column("rolling_resistance")
    with ellroll_post.open(small_suite) as f:
        whole, _ = suite.suite_fragility(f)
    outcome = np.isin(status, suite.MODEL_LIMITS) | (status == "completed")
    for row, before in zip(table.to_dict("records"), whole.to_dict("records")):
        cases = resistance == row["rolling_resistance"]
        dropped = int(np.sum(cases & at_zero & outcome))
        assert dropped > 0
        assert row["n_points"] == before["n_points"] - 1 and row["n_known"] == before["n_known"] - dropped
        assert f"{dropped} cases at intensity 0 left out (no likelihood)" in row["note"], row["note"]
    assert assert_fortran_fits_are_pythons(ellroll, zero) >= 1
    flat = tmp_path / "flat.h5"
    shutil.copy(small_suite, flat)
    with h5py.File(flat, "r+") as f:
        f["case/scale"][:] = f["summary/scale"][:] = SCALES[1]
    assert cli.main(["fragility", str(flat), "--out", str(tmp_path)]) == 2
    error = capsys.readouterr().err
    assert (f"{flat}: no stripes to fit a fragility to: none of its 2 groups of cases with the same design "
            "inputs (rolling_resistance) spans two intensities (scale)") in error and "Traceback" not in error
    assert not list(tmp_path.glob("*.png"))


def test_fragility_against_an_intensity_measure_the_file_holds(small_suite, tmp_path):
    """A /case pga is each case's own; a /records sa_3.0 (a period the
    file has no /case/sa_ for) is the record's,
    times the case's record factor and scale."""
    with h5py.File(small_suite, "r") as f:
        n = f["summary/status"].shape[0]
        scale, factor = f["case/scale"][:], f["case/record_factor"][:]
        records = [r.decode().strip() for r in f["case/record"][:]]
    pga = scale * factor * np.array([{"SYN1": 0.05, "SYN2": 0.08, "SYN3": 0.03}[r] for r in records])
    path = constructed(small_suite, tmp_path / "im.h5",
                       extra={"case/pga": pga, "records/name": np.array([b"SYN1", b"SYN2", b"SYN3"]),
                              "records/sa_3.0": np.array([0.1, 0.2, 0.3])})
    with h5py.File(path, "r+") as f:
        f["case/pga"].attrs["units"] = "m/s^2"
        f["records/sa_3.0"].attrs["period"] = 3.0
    with ellroll_post.open(path) as f:
        name, values, units = suite.intensity(f, "PGA")
        assert name == "pga" and units == "m/s^2" and np.array_equal(values, pga)
        name, values, _ = suite.intensity(f, "Sa(3.0)")
        sa = np.array([{"SYN1": 0.1, "SYN2": 0.2, "SYN3": 0.3}[r] for r in records]) * factor * scale
        assert name == "sa_3.0" and np.allclose(values, sa, rtol=1e-15)
        # Sa(T): at the isolator's own first period, which ellroll stores per case
        name, values, units = suite.intensity(f, "Sa(T)")
        assert name == "sa_linear_periods_1" and units == "m/s^2"
        assert np.array_equal(values, f.summary("sa_linear_periods")[:, 0])
        table, _ = suite.suite_fragility(f, "PGA")
        assert table.iloc[0]["n_points"] == np.unique(pga[f.input_column("rolling_resistance") == 1e-5]).size
    result = plot_cli("fragility", path, "--im", "PGA", "--out", tmp_path, "--bootstrap", "20")
    assert result.returncode == 0, result.stderr
    assert n == len(records)


def test_counts_that_separate_in_the_intensity_are_a_step():
    """Few records a stripe often separate (none exceeds below a level, all
    above, one level between): the likelihood has no finite maximum there,
    it grows as beta -> 0 towards the binomial likelihood of the observed
    fractions, so the bootstrap counts such a resample as a step."""
    from ellroll_post.fragility import _negative_log_likelihood, separating_step
    x, n = np.array([40.0, 70.0, 80.0, 90.0, 120.0]), np.full(5, 3)
    assert separating_step(x, n, [0, 0, 1, 3, 3]) == (80.0, 0.0)
    assert separating_step(x, n, [0, 0, 3, 3, 3]) == pytest.approx((math.sqrt(70 * 80), 0.0))
    for z in ([0, 1, 2, 3, 3], [0, 3, 0, 3, 3], [0, 0, 0, 0, 0]):
        assert separating_step(x, n, z) is None
    z = np.array([0, 0, 1, 3, 3])
    supremum = -(1 * math.log(1 / 3) + 2 * math.log(2 / 3))
    values = []
    for beta in (0.3, 0.1, 0.03, 1e-3):
        theta = 80 * math.exp(-beta * stats.norm.ppf(1 / 3))
        values.append(_negative_log_likelihood([math.log(theta), math.log(beta)], np.log(x), n, z)[0])
    assert np.all(np.diff(values) < 0) and values[0] > supremum + 0.1
    assert values[-1] == pytest.approx(supremum, rel=1e-12)


def summary_fragility(ellroll, path):
    result = run(ellroll, "summary", path, "--suite", "--format", "json")
    assert result.returncode == 0, result.stderr
    return json.loads(result.stdout)["fragility"]


def assert_fortran_fits_are_pythons(ellroll, path):
    """`ellroll summary --suite --format json`'s fragility rows against
    suite.suite_fragility (no bootstrap) on the same file: theta and beta to
    1e-6 where a finite maximum exists, the step of separating_step where the
    counts separate. Returns the number of finite fits compared."""
    from ellroll_post.fragility import separating_step
    fortran = summary_fragility(ellroll, path)
    with ellroll_post.open(path) as f:
        table, details = suite.suite_fragility(f, bootstrap=0)
    assert len(fortran) == len(table)
    finite = 0
    for row, (_, expected), detail in zip(fortran, table.iterrows(), details):
        assert row["limit_state"] == expected["limit_state"] and row["note"] == expected["note"]
        assert [row[k] for k in ("n_points", "n_known", "n_exceeded", "n_undefined")] == \
            [expected[k] for k in ("n_points", "n_known", "n_exceeded", "n_undefined")]
        if detail["fit"] is None:
            assert row["theta"] is None and row["beta"] is None
        elif "separate" in expected["note"]:
            assert (row["theta"], row["beta"]) == separating_step(detail["x"], detail["n"], detail["z"])
        else:
            assert row["theta"] == pytest.approx(expected["theta"], rel=1e-6)
            assert row["beta"] == pytest.approx(expected["beta"], rel=1e-6)
            finite += 1
    return finite


def test_summary_json_fragility_is_the_python_fit(ellroll, small_suite, tmp_path):
    """The Fortran maximum likelihood fit (src/app/fragility_mle.f90) equals
    ellroll_post's on the shipped example (lift-off: theta 74.26, beta 0.107)
    and on counts drawn from a known lognormal (theta 75, beta 0.3; seeded):
    30 cases at 10 scales, one design value."""
    assert assert_fortran_fits_are_pythons(ellroll, small_suite) == 2
    with h5py.File(small_suite, "r") as f:
        n = f["summary/status"].shape[0]
    rng = np.random.default_rng(42)
    finite = 0
    for draw in range(6):
        scale = np.repeat(np.geomspace(40, 140, 10), n // 10)
        exceeded = rng.uniform(size=n) < stats.norm.cdf(np.log(scale / 75.0) / 0.3)
        status = np.where(exceeded, "liftoff", "completed")
        path = constructed(small_suite, tmp_path / f"draw{draw}.h5", status=status, scale=scale,
                           values={"scale": scale, "rolling_resistance": np.full(n, 1e-5)})
        with h5py.File(path, "r+") as f:
            f["case/rolling_resistance"][...] = 1e-5
        finite += assert_fortran_fits_are_pythons(ellroll, path)
    assert finite >= 6        # the lift-off fits at least (every limit state is compared)


@pytest.mark.parametrize("pattern", ["falling", "near_step", "one_level"])
def test_summary_json_fragility_of_degenerate_counts_ends_cleanly(ellroll_debug, small_suite, tmp_path, pattern):
    """Counts with no sensible fragility (exceedances that fall with the
    scale, a near step, every case at one scale) on the Debug build
    (floating-point traps): the command ends normally, each fit a number or
    null, never a signal."""
    with h5py.File(small_suite, "r") as f:
        n = f["summary/status"].shape[0]
    scale = np.repeat(np.geomspace(40, 140, 10), n // 10)
    exceeded = {"falling": scale < 70, "near_step": (scale > 70) | (np.arange(n) == 14),
                "one_level": np.arange(n) % 2 == 0}[pattern]
    if pattern == "one_level":
        scale = np.full(n, 80.0)
    path = constructed(small_suite, tmp_path / f"{pattern}.h5", status=np.where(exceeded, "liftoff", "completed"),
                       scale=scale, values={"scale": scale, "rolling_resistance": np.full(n, 1e-5)})
    with h5py.File(path, "r+") as f:
        f["case/rolling_resistance"][...] = 1e-5
    rows = summary_fragility(ellroll_debug, path)
    assert rows and rows[0]["limit_state"] == "model_limit"
    for row in rows:
        assert row["theta"] is None or (math.isfinite(row["theta"]) and row["theta"] > 0)
        assert row["beta"] is None or (math.isfinite(row["beta"]) and row["beta"] >= 0)
    if pattern == "one_level":
        assert (rows[0]["theta"], rows[0]["beta"]) == (80.0, 0.0)      # one mixed level: the step there
    if pattern == "falling":
        assert rows[0]["theta"] is None and "do not grow" in rows[0]["note"]
