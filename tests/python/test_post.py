"""post/: every subcommand on files written by the real solver; the figures
carry exactly the file's data; the energy bound satisfies the energy
equation; bad files and arguments give clear errors, not tracebacks."""
import csv
import html
import html.parser
import io
import json
import pathlib
import re
import urllib.parse

import h5py
import numpy as np
import pytest

matplotlib = pytest.importorskip("matplotlib")
matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402

import ellroll_post  # noqa: E402
from conftest import plot_in_process, run  # noqa: E402
from test_campaign import BASE  # noqa: E402


def plot_cli(*args):
    return plot_in_process(*args)


@pytest.fixture(scope="module")
def sweep_file(ellroll, tmp_path_factory):
    """A 2 x 3 campaign with error figures; radius 0.5 ends early (no_fit)."""
    folder = tmp_path_factory.mktemp("sweep")
    (folder / "s.nml").write_text(BASE.format(t_end=3.0).replace("dt = 1.0e-3", "dt = 1.0e-3, error_estimate = 'reference'")
                                  + "&sweep name = 'omega_z', values = 10, 40 /\n"
                                  + "&sweep name = 'radius', values = 0.1, 0.2, 0.5 /\n")
    assert run(ellroll, "run", "s.nml", "-q", cwd=folder).returncode == 0
    return folder / "out.h5"


def is_png(path):
    return path.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n" and path.stat().st_size > 5000


def test_trace_carries_the_contact_points_rim_and_energy_bound(paper_file):
    with ellroll_post.open(paper_file) as runfile, h5py.File(paper_file, "r") as f:
        fig, ax = plt.subplots()
        ellroll_post.plot_trace(ax, runfile)
        lines = {line.get_label(): line for line in ax.get_lines()}
        contact = f["trajectory/contact"][0]
        np.testing.assert_array_equal(lines["contact point"].get_xdata(), contact[:, 0])
        np.testing.assert_array_equal(lines["contact point"].get_ydata(), contact[:, 1])
        rim = lines["rim of the cup (z = c)"]
        np.testing.assert_allclose((rim.get_xdata() / 1.0)**2 + (rim.get_ydata() / 0.4)**2, 1, rtol=1e-12)
        assert ax.get_aspect() == 1.0
        # the energy bound: m g z_C + J (omega0 . n0)^2 / 2 = E0 at every point
        bound = lines["energy bound (spin about n kept)"]
        x, y = bound.get_xdata(), bound.get_ydata()
        m, g, radius = f["case/mass"][0], f["case/g"][0], 0.2
        omega0, n0, energy0 = f["trajectory/omega"][0, 0], f["trajectory/normal"][0, 0], f["trajectory/energy"][0, 0]
        z_center = ellroll_post.center_height(1.0, 0.4, 0.2, radius, x, y)
        energy = m * g * z_center + 0.5 * 0.4 * m * radius**2 * (omega0 @ n0)**2
        np.testing.assert_allclose(energy, energy0, rtol=1e-12)
        # and the ball does not cross it (the paper's claim for this case)
        center = f["trajectory/center"][0]
        assert np.max(center[:, 2]) < np.max(z_center)
        plt.close(fig)


def test_nutation_reaction_energy_carry_the_file_data(paper_file):
    with ellroll_post.open(paper_file) as runfile, h5py.File(paper_file, "r") as f:
        fig, ax = plt.subplots()
        ellroll_post.plot_nutation(ax, runfile)
        line = ax.get_lines()[0]
        np.testing.assert_array_equal(line.get_xdata(), f["time"][:])
        np.testing.assert_array_equal(line.get_ydata(), f["trajectory/nutation"][0])
        assert "nutation period" in ax.texts[0].get_text() and "rad" in ax.get_ylabel()
        fig, axes = plt.subplots(3, 1)
        ellroll_post.plot_reaction(axes, runfile)
        force, normal = f["trajectory/reaction"][0], f["trajectory/normal"][0]
        n_force = np.sum(force * normal, axis=1)
        lines = {line.get_label(): line for line in axes[0].get_lines()}
        np.testing.assert_allclose(lines[r"normal force $F_n = \mathbf{F} \cdot \mathbf{n}$"].get_ydata(), n_force)
        assert lines["weight $m g$ = 2620 N"].get_ydata()[0] == pytest.approx(2620)
        friction = np.linalg.norm(force - n_force[:, None] * normal, axis=1)
        np.testing.assert_allclose(axes[1].get_lines()[0].get_ydata(), friction)    # on its own axis
        mu = axes[2].get_lines()[0].get_ydata()
        np.testing.assert_allclose(mu.max(), f["summary/friction_needed_max"][0], rtol=1e-3)
        fig, ax = plt.subplots()
        ellroll_post.plot_energy(ax, runfile)
        energy = f["trajectory/energy"][0]
        np.testing.assert_allclose(ax.get_lines()[0].get_ydata(),
                                   np.maximum(np.abs(energy / energy[0] - 1), 1e-18))
        residual = ellroll_post.geometry.surface_residual(1.0, 0.4, 0.2, f["trajectory/contact"][0])
        constraint = ax.get_lines()[1].get_ydata()             # the running maximum: a line, not a block
        assert np.all(np.diff(constraint) >= 0) and constraint[-1] == max(residual.max(), 1e-18)
        assert ax.get_yscale() == "log"
        plt.close("all")


@pytest.mark.parametrize("figure,stem", [("trace", "fig2_trace"), ("nutation", "fig3_nutation"),
                                         ("reaction", "reaction"), ("energy", "energy")])
def test_case_subcommands_write_images(paper_file, tmp_path, figure, stem):
    result = plot_cli(figure, paper_file, "--out", tmp_path)
    assert result.returncode == 0, result.stderr
    assert is_png(tmp_path / f"legeza1990_{stem}.png")                # named after the file
    result = plot_cli(figure, paper_file, "--out", tmp_path, "--format", "svg")
    assert result.returncode == 0 and (tmp_path / f"legeza1990_{stem}.svg").read_text().startswith("<?xml")


def test_an_input_left_unset_is_not_varied_but_one_set_in_some_cases_is(sweep_file, tmp_path):
    """&output capacity unset is NaN in every case: the same input, not a
    varied one; NaN in one case and a number in another differ."""
    import shutil
    with ellroll_post.open(sweep_file) as runfile:
        assert np.all(np.isnan(runfile.input_column("capacity")))
        assert "capacity" not in runfile.swept_inputs()
    changed = tmp_path / "changed.h5"
    shutil.copy(sweep_file, changed)
    with h5py.File(changed, "r+") as f:
        capacity = f["case/capacity"][:]
        capacity[1] = 0.1
        f["case/capacity"][:] = capacity
    with ellroll_post.open(changed) as runfile:
        assert runfile.swept_inputs() == ["radius", "omega_z", "capacity"]


def test_sweep_line_and_heat_map(sweep_file, tmp_path):
    result = plot_cli("sweep", sweep_file, "--x", "omega_z", "--y", "theta_max,nutation_period", "--out", tmp_path)
    assert result.returncode == 0, result.stderr
    assert is_png(tmp_path / "out_sweep_omega_z.png")
    with ellroll_post.open(sweep_file) as runfile:
        assert runfile.swept_inputs() == ["radius", "omega_z"]
        fig = plt.figure()
        axes = ellroll_post.plot_sweep(fig, runfile, ["omega_z"], ["theta_max"])
        lines = {line.get_label(): line for line in axes[0].get_lines()}
        theta_max = runfile.summary("theta_max")
        spin, radius = runfile.input_column("omega_z"), runfile.input_column("radius")
        line = lines["radius = 0.2"]
        np.testing.assert_array_equal(line.get_xdata(), [10, 40])
        np.testing.assert_array_equal(line.get_ydata(), theta_max[radius == 0.2][np.argsort(spin[radius == 0.2])])
        early = lines["ended: no_fit"]
        assert len(early.get_xdata()) == 2 and all(r == 0.5 for r in radius[np.array(runfile.status_names()) != "completed"])
        legend = axes[0].get_legend()                           # beside the axes, not over the data
        fig.canvas.draw()
        assert legend.get_window_extent().x0 >= axes[0].get_window_extent().x1
        plt.close(fig)
    result = plot_cli("sweep", sweep_file, "--x", "omega_z,radius", "--out", tmp_path)
    assert result.returncode == 0 and is_png(tmp_path / "out_sweep_omega_z_radius.png")
    with ellroll_post.open(sweep_file) as runfile:               # the heat map names how cases ended
        fig = plt.figure()
        (ax,) = ellroll_post.plot_sweep(fig, runfile, ["omega_z", "radius"], ["theta_max"])
        marked = {line.get_label(): line for line in ax.get_lines()}
        assert list(marked) == ["ended: no_fit"] and np.all(marked["ended: no_fit"].get_ydata() == 0.5)
        assert ax.get_legend().get_title().get_text() == "status"
        plt.close(fig)


def test_summary_formats(sweep_file):
    text = plot_cli("summary", sweep_file)
    assert text.returncode == 0 and "no_fit" in text.stdout and "omega_z" in text.stdout.splitlines()[0]
    rows = list(csv.DictReader(io.StringIO(plot_cli("summary", sweep_file, "--format", "csv").stdout)))
    assert len(rows) == 6 and rows[2]["radius [m]"] == "0.5" and rows[2]["status"] == "no_fit"
    text = plot_cli("summary", sweep_file, "--format", "json").stdout
    data = json.loads(text, parse_constant=lambda token: pytest.fail(f"not strict JSON: {token}"))
    with h5py.File(sweep_file, "r") as f:
        assert [c["theta_max"] for c in data["cases"]] == list(f["summary/theta_max"][:])
        transmissibility = f["summary/transmissibility"][:]                  # NaN: no harmonic excitation
    assert np.all(np.isnan(transmissibility)) and all(c["transmissibility"] is None for c in data["cases"])
    assert {"displacement_max [m]", "residual_displacement [m]", "absolute_acceleration_max [m/s^2]"} <= set(rows[0])


def test_workprecision_from_files_and_bench_csv(sweep_file, tmp_path):
    result = plot_cli("workprecision", sweep_file, "--out", tmp_path)
    assert result.returncode == 0, result.stderr
    assert is_png(tmp_path / "out_workprecision.png")
    table = tmp_path / "wp.csv"
    table.write_text("method,setting,error_m,time_s,rhs_evaluations\nrk4,dt=0.01,1e-6,1e-3,12001\n"
                     "rk4,dt=0.001,1e-10,1e-2,120001\n")
    assert plot_cli("workprecision", table, "--out", tmp_path).returncode == 0
    assert is_png(tmp_path / "wp_workprecision.png")
    from ellroll_post.cli import workprecision_points
    assert workprecision_points([table]) == {"rk4": [(1e-6, 1e-3, 12001.0), (1e-10, 1e-2, 120001.0)]}


def test_report_folder(paper_file, sweep_file, tmp_path):
    for source, expected in [(paper_file, ["legeza1990_fig2_trace.png", "legeza1990_fig3_nutation.png",
                                           "legeza1990_reaction.png", "legeza1990_energy.png"]),
                             (sweep_file, ["out_sweep_radius.png", "out_sweep_omega_z.png", "out_sweep_radius_omega_z.png",
                                           "out_fig2_trace.png"])]:
        out = tmp_path / source.stem
        result = plot_cli("report", source, "--out", out)
        assert result.returncode == 0, result.stderr
        index = (out / "index.html").read_text()
        for name in expected:
            assert is_png(out / name) and f'src="{name}"' in index
        assert (out / "summary.csv").exists() and "<table>" in index
        assert "<th>theta_max, rad</th>" in index and "<th>t_final, s</th>" in index   # units in the table
        assert "<figcaption>Fig. 2: the contact point's trace" in index.replace("&#x27;", "'")


def test_clear_errors(paper_file, sweep_file, tmp_path):
    not_hdf5 = tmp_path / "notes.txt"
    not_hdf5.write_text("hello")
    other = tmp_path / "other.h5"
    with h5py.File(other, "w") as f:
        f["x"] = 1
    cases = [(["trace", not_hdf5], "cannot open as HDF5"), (["trace", other], "not an ellroll file"),
             (["nutation", paper_file, "--case", 5], "case 5 out of range"),
             (["sweep", paper_file], "no input varies"),
             (["sweep", sweep_file, "--x", "mu"], "mu is not a swept input"),
             (["sweep", sweep_file, "--y", "speed"], "no summary quantity speed"),
             (["workprecision", paper_file], "no error figures")]
    for args, words in cases:
        result = plot_cli(*args, "--out", tmp_path) if args[0] != "summary" else plot_cli(*args)
        assert result.returncode == 2 and words in result.stderr and "Traceback" not in result.stderr, (args, result.stderr)


def test_a_figure_or_report_already_there_is_kept_unless_asked(paper_file, tmp_path):
    figure = tmp_path / "legeza1990_fig2_trace.png"
    assert plot_cli("trace", paper_file, "--out", tmp_path).returncode == 0
    first = figure.read_bytes()
    figure.write_bytes(first + b"kept")           # one of ours: its metadata marks it
    result = plot_cli("trace", paper_file, "--out", tmp_path)
    assert result.returncode == 2 and "exists; give --overwrite" in result.stderr
    assert figure.read_bytes() == first + b"kept"
    assert plot_cli("trace", paper_file, "--out", tmp_path, "--overwrite").returncode == 0
    assert figure.read_bytes() == first
    figure.write_bytes(b"somebody's picture")     # not ours: never replaced
    result = plot_cli("trace", paper_file, "--out", tmp_path, "--overwrite")
    assert result.returncode == 2 and "not made by ellroll-plot" in result.stderr
    assert figure.read_bytes() == b"somebody's picture"
    report = tmp_path / "report"
    assert plot_cli("report", paper_file, "--out", report).returncode == 0
    page = (report / "index.html").read_text()
    result = plot_cli("report", paper_file, "--out", report)
    assert result.returncode == 2 and "index.html exists" in result.stderr
    assert (report / "index.html").read_text() == page


def test_lazy_on_large_campaigns(sweep_file):
    """Only what is asked is read: the reader never touches trajectories for a summary."""
    with ellroll_post.open(sweep_file) as runfile:
        touched = []
        original = runfile._dataset
        runfile._dataset = lambda name: touched.append(name) or original(name)
        ellroll_post.format_summary(runfile, "csv")
        assert not any(name.startswith("trajectory/") for name in touched)


@pytest.fixture(scope="module")
def suite_file(ellroll, tmp_path_factory):
    """Three records (one of them halved by its factor) at two scales."""
    from test_records import SUITE, write_suite_records
    folder = tmp_path_factory.mktemp("suite")
    write_suite_records(folder)
    (folder / "suite.nml").write_text(SUITE.replace("values = 1.0, 2.0", "values = 0.5, 1.0, 2.0")
                                      .replace("interval = 0.01", "interval = 0.01, fields = 'center', "
                                               "'reaction', 'base_acceleration'"))
    result = run(ellroll, "run", "suite.nml", "-q", cwd=folder)
    assert result.returncode == 0, result.stderr
    return folder / "suite.h5"


def test_suite_statistics_are_numpys_median_and_percentiles(suite_file):
    with h5py.File(suite_file, "r") as f:
        scale = f["case/scale"][:]
        status = f["summary/status"][:]
        records = [n.decode().strip() for n in f["case/record"][:]]
        values = {q: f["summary"][q][:] for q in ("displacement_max", "absolute_acceleration_max")}
    assert len(set(records)) == 3
    with ellroll_post.open(suite_file) as run_:
        table = ellroll_post.suite_statistics(run_)
        names = np.array(run_.status_names())
    assert list(table["scale"]) == [0.5, 1.0, 2.0] and list(table["n_cases"]) == [3, 3, 3]
    # the records that end at no_fit (their peaks taken on the approach to it) are left out
    assert list(table["n_completed"]) == [3 - np.sum((scale == s) & (status != 1)) for s in (0.5, 1.0, 2.0)]
    assert list(table["n_limit"]) == [np.sum((scale == s) & (names == "no_fit")) for s in (0.5, 1.0, 2.0)]
    assert table["n_limit"].sum() > 0
    for quantity, column in values.items():
        for _, row in table.iterrows():
            chosen = column[(scale == row["scale"]) & (status == 1)]
            assert row[f"{quantity}_p50"] == np.median(chosen)
            assert row[f"{quantity}_p16"] == np.percentile(chosen, 16)
            assert row[f"{quantity}_p84"] == np.percentile(chosen, 84)


def test_suite_and_spectrum_figures(suite_file, paper_file, tmp_path):
    result = plot_cli("suite", suite_file, "--out", tmp_path)
    assert result.returncode == 0, result.stderr
    assert is_png(tmp_path / "suite_suite.png")
    fig, axes = plt.subplots(1, 2)
    with ellroll_post.open(suite_file) as run_:
        ellroll_post.plots.plot_suite(axes, run_)
        table = ellroll_post.suite_statistics(run_)
    line = [l for l in axes[0].get_lines() if l.get_label() == "median"][0]
    assert np.array_equal(line.get_ydata(), table["displacement_max_p50"])
    plt.close(fig)
    result = plot_cli("spectrum", suite_file, "--case", "4", "--out", tmp_path)
    assert result.returncode == 0 and is_png(tmp_path / "suite_spectrum_case4.png"), result.stderr
    with ellroll_post.open(suite_file) as run_:
        frequency, ground, transmitted = ellroll_post.plots.acceleration_spectra(run_, 4)
    assert frequency[1] == pytest.approx(1 / 12.01, rel=1e-9)
    # far above its resonance the rolling ball passes on k / (1 + k) of the
    # ground's acceleration (linearised, docs/model.md; k = 0.4)
    fast = (frequency > 5) & (frequency < 20)
    assert np.median(transmitted[fast] / ground[fast]) == pytest.approx(0.4 / 1.4, rel=0.03)
    result = plot_cli("suite", paper_file, "--out", tmp_path)
    assert result.returncode == 2 and "not a record suite" in result.stderr
    result = plot_cli("spectrum", paper_file, "--out", tmp_path)
    assert result.returncode == 2 and "base_acceleration" in result.stderr


def test_files_with_the_aliases_x0_y0_omega0_read(sweep_file, tmp_path):
    """A file whose /case names the start x0, y0 and omega0 reads as one
    that names it x, y and omega."""
    import shutil
    old = tmp_path / "old.h5"
    shutil.copy(sweep_file, old)
    with h5py.File(old, "r+") as f:
        for name in ("x", "y", "omega"):
            f.move(f"case/{name}", f"case/{name}0")
    with ellroll_post.open(old) as run_, ellroll_post.open(sweep_file) as new:
        assert run_.swept_inputs() == new.swept_inputs() == ["radius", "omega_z"]
        assert np.array_equal(run_.input_column("omega_z"), new.input_column("omega_z"))
        assert run_.case_input("x", 1) == new.case_input("x", 1)


def test_sweep_plots_of_a_sampled_campaign_stay_small(ellroll, tmp_path):
    """Sampled inputs form no grid: the two-input view is a scatter, not a
    heat map of distinct-value pairs, and the one-input view draws points,
    not a line per case."""
    (tmp_path / "s.nml").write_text(BASE.format(t_end=0.01).replace("interval = 0.01", "interval = 0.01, "
                                                                      "fields = 'none'")
                                    + "&campaign samples = 400, seed = 3 /\n"
                                    + "&sample name = 'omega_z', low = 5, high = 50 /\n"
                                    + "&sample name = 'radius', low = 0.05, high = 0.2 /\n")
    result = run(ellroll, "run", "s.nml", "-q", cwd=tmp_path)
    assert result.returncode == 0, result.stderr
    with ellroll_post.open(tmp_path / "out.h5") as run_:
        fig = plt.figure()
        (ax,) = ellroll_post.plot_sweep(fig, run_, ["omega_z", "radius"], ["theta_max"])
        assert len(ax.collections) == 1 and ax.collections[0].get_offsets().shape == (400, 2)
        plt.close(fig)
        fig = plt.figure()
        (ax,) = ellroll_post.plot_sweep(fig, run_, ["omega_z"], ["theta_max"])
        lines = ax.get_lines()                 # the cases as points, the median of the completed ones
        assert len(lines[0].get_xdata()) == 400 and [line.get_label() for line in lines[1:]] == [
            "median of completed cases"]
        plt.close(fig)


def test_a_status_outside_flag_values_is_unknown_and_counted(ellroll, sweep_file, tmp_path):
    """A status the reader does not know (a later version's, or an altered
    file): ellroll-plot summary, report and summary_frame name it `unknown`
    as `ellroll summary` does, and in both the counts add up to the cases."""
    altered = tmp_path / "altered.h5"
    altered.write_bytes(sweep_file.read_bytes())
    with h5py.File(altered, "r+") as f:
        status = f["summary/status"]
        n_cases = status.shape[0]
        known = [str(n) for n in np.asarray(status.attrs["flag_meanings"]).ravel()[0].split()]
        codes = status[:]
        codes[1] = 77
        status[...] = codes
    with ellroll_post.open(altered) as runfile:
        names = runfile.status_names()
        assert names[1] == "unknown" and runfile.status_name(1) == "unknown"
        assert [n for k, n in enumerate(names) if k != 1] == [known[c] for k, c in enumerate(codes) if k != 1]
    assert ellroll_post.summary_frame(altered)["status"].iloc[1] == "unknown"
    table = plot_cli("summary", altered)
    assert table.returncode == 0 and "Traceback" not in table.stderr and "unknown" in table.stdout, table.stderr
    report = plot_cli("report", altered, "--out", tmp_path / "report")
    assert report.returncode == 0, report.stderr
    counts = re.search(r"((?:\d+ \w+, )*\d+ \w+)\.", (tmp_path / "report" / "index.html").read_text()).group(1)
    counted = {name: int(count) for count, name in (item.split() for item in counts.split(", "))}
    assert counted["unknown"] == 1 and sum(counted.values()) == n_cases, counts
    printed = run(ellroll, "summary", altered)
    assert printed.returncode == 0, printed.stderr
    lines = [line.split() for line in printed.stdout.splitlines()[1:] if re.fullmatch(r"  \w+ +\d+", line)]
    assert ["unknown", "1"] in lines and sum(int(count) for _, count in lines) == n_cases, printed.stdout


def test_report_of_a_folder_is_a_clear_error(tmp_path):
    for folder in (".", str(tmp_path)):
        result = plot_cli("report", folder)
        assert result.returncode == 2 and "a folder, not an ellroll file" in result.stderr, result.stderr
        assert "Traceback" not in result.stderr
    result = plot_cli("report", tmp_path / "missing.h5")
    assert result.returncode == 2 and "missing.h5: no such file" in result.stderr
    assert not (tmp_path / "missing_report").exists()          # nothing made for a file that cannot be read


def test_suite_figures_of_a_partial_file_say_its_finished_cases_hold_one_record(suite_file, tmp_path):
    """An interrupted suite whose finished cases all ran one record: its
    pending cases hold no record yet; suite and fragility say so."""
    partial = tmp_path / "suite.h5.partial"
    partial.write_bytes(suite_file.read_bytes())
    with h5py.File(partial, "r+") as f:
        records = np.array([r.decode().strip() if isinstance(r, bytes) else str(r).strip() for r in f["case/record"][:]])
        first = records[0]
        status = f["summary/status"][:]
        status[records != first] = 0                       # pending
        f["summary/status"][...] = status
        blank = f["case/record"][:]
        blank[records != first] = b""
        f["case/record"][...] = blank
        finished, n_cases = int(np.sum(records == first)), len(records)
    for command in ("suite", "fragility"):
        result = plot_cli(command, partial, "--out", tmp_path)
        assert result.returncode == 2 and "Traceback" not in result.stderr, result.stderr
        assert (f"its {finished} finished cases of {n_cases} hold one record ({first}); a suite's figures need two "
                "or more") in result.stderr, result.stderr


@pytest.mark.parametrize("name", ['r" onerror="alert(1)" x="', "run#1 50%", "a&b <c>", "naïve 'quote'"])
def test_a_report_names_its_figures_by_any_file_name(paper_file, tmp_path, name):
    """A file's name goes into the report's links quoted (a '#' or '%' of
    it is no fragment or escape) and into their text escaped (a quote of it
    ends no attribute): every figure's link is its file, and the page holds
    no attribute or tag that the name brought."""
    source = tmp_path / f"{name}.h5"
    source.write_bytes(paper_file.read_bytes())
    out = tmp_path / "report"
    result = plot_cli("report", source, "--out", out)
    assert result.returncode == 0, result.stderr
    index = (out / "index.html").read_text()
    links = re.findall(r'<img src="([^"]*)" alt="([^"]*)">', index)
    assert len(links) == len([p for p in out.iterdir() if p.suffix == ".png"]) >= 4, links
    for src, alt in links:
        target = urllib.parse.unquote(html.unescape(src))
        assert (out / target).is_file() and target.startswith(name), (src, target)
        # a URL path: no fragment, no blank, '%' only as an escape
        assert re.fullmatch(r"([A-Za-z0-9._~/-]|%[0-9A-F]{2})+", html.unescape(src)), src
        assert html.unescape(alt) == pathlib.Path(target).stem, alt

    class Images(html.parser.HTMLParser):
        found = []

        def handle_starttag(self, tag, attrs):
            if tag == "img":
                self.found.append([key for key, _ in attrs])
    parser = Images()
    parser.feed(index)
    assert parser.found and all(keys == ["src", "alt"] for keys in parser.found), parser.found
