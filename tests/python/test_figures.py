"""ellroll-plot's figures on the file shapes that meet users: fields not
stored, cases never run, a moving cup, sweeps, suites, samples. Each figure
is drawn with the Agg backend and its objects inspected: what is drawn,
labels and titles, legends beside the data, and one-line errors (exit 2,
no traceback) where a figure cannot be drawn."""
import contextlib
import io
import re
import shlex
import shutil

import numpy as np
import pytest

matplotlib = pytest.importorskip("matplotlib")
matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402

import ellroll_post  # noqa: E402
from ellroll_post import plots  # noqa: E402
from ellroll_post.cli import main as plot_main  # noqa: E402
from conftest import ROOT, run  # noqa: E402

CUP = """&geometry    a = 1.0, b = 0.4, c = 0.2 /
&ball        radius = 0.2, weight = 2620.0 /
&initial     x = 0.0, y = 0.0, omega = {omega} /
&integration method = '{method}', dt = {dt}, t_end = {t_end} /
&output      file = '{name}.h5', interval = {interval}{fields} /
"""


def make(folder, name, extra="", omega="-2.0, 2.0, 20.0", method="rk4", dt="1.0e-3", t_end=1.0, interval=0.01,
         fields=None):
    text = CUP.format(name=name, omega=omega, method=method, dt=dt, t_end=t_end, interval=interval,
                      fields="" if fields is None else ", fields = " + fields)
    (folder / f"{name}.nml").write_text(text + extra)
    return folder / f"{name}.nml"


@pytest.fixture(scope="module")
def files(ellroll, tmp_path_factory):
    """Small files of every shape, run once: {name: path}."""
    folder = tmp_path_factory.mktemp("figures")
    shutil.copytree(ROOT / "input" / "records", folder / "records")
    harmonic = "&excitation kind = 'harmonic', amplitude = {amp}, frequency = 0.2 /\n"
    sweep = "&sweep name = 'excitation_frequency', start = {lo}, stop = {hi}, count = 7, spacing = 'log' /\n"
    made = [
        make(folder, "fixed", t_end=2.0),
        make(folder, "contact_only", fields="'contact', 'nutation'"),
        make(folder, "bare", fields="'none'"),
        make(folder, "invalid", "&campaign invalid = 'skip' /\n&sweep name = 'radius', values = 0.2, 0.9 /\n"),
        make(folder, "moving", harmonic.format(amp="0.1, 0.0, 0.0"), omega="0.0, 0.0, 0.0", t_end=10.0,
             interval=0.02),
        make(folder, "harm_x", harmonic.format(amp="0.01, 0.0, 0.0") + sweep.format(lo=0.02, hi=2.0),
             omega="0.0, 0.0, 0.0", method="dop853", dt="0.05", t_end=40.0, interval=0.05, fields="'none'"),
        make(folder, "harm_y", harmonic.format(amp="0.0, 0.01, 0.0") + sweep.format(lo=0.15, hi=0.6),
             omega="0.0, 0.0, 0.0", method="dop853", dt="0.05", t_end=40.0, interval=0.05, fields="'none'"),
        make(folder, "record", "&excitation kind = 'record', record_file = 'records/synthetic_ground.csv' /\n",
             omega="0.0, 0.0, 0.0", t_end=4.0, interval=0.02),
        make(folder, "suite", "&excitation kind = 'record' /\n"
             "&record name = 'SYN1', record_file = 'records/SYN1_H1.AT2', 'records/SYN1_H2.AT2' /\n"
             "&record name = 'SYN3', record_file = 'records/SYN3_H1.AT2', 'records/SYN3_H2.AT2', factor = 1.5 /\n"
             "&sweep name = 'scale', values = 1.0, 2.0 /\n", omega="0.0, 0.0, 0.0", t_end=4.0, interval=0.02),
        make(folder, "sampled", "&campaign samples = 120, seed = 3 /\n"
             "&sample name = 'omega_z', low = 5, high = 50 /\n&sample name = 'radius', low = 0.05, high = 0.2 /\n",
             dt="2.0e-3", t_end=0.3, fields="'none'"),
        make(folder, "sampled_few", "&campaign samples = 60, seed = 4 /\n"
             "&sample name = 'omega_z', low = 5, high = 50 /\n&sample name = 'radius', low = 0.05, high = 0.5 /\n",
             dt="2.0e-3", t_end=1.5, fields="'none'"),
    ]
    for nml in made:
        result = run(ellroll, "run", nml.name, "-q", "--threads", 2, cwd=folder)
        assert result.returncode == 0, result.stderr
    (folder / "wp.csv").write_text("method,setting,error_m,time_s,rhs_evaluations\n"
                                   "rk4,dt=0.01,1e-4,1e-3,12001\nrk4,dt=0.001,1e-8,1e-2,120001\n"
                                   "dop853,rtol=1e-6,1e-5,5e-4,8000\ndop853,rtol=1e-12,1e-12,3e-3,60000\n"
                                   "vern9,rtol=1e-8,1e-8,8e-4,9000\nvern9,rtol=1e-12,1e-13,2e-3,30000\n")
    return {nml.stem: folder / f"{nml.stem}.h5" for nml in made} | {"wp": folder / "wp.csv"}


def cli(*args):
    """ellroll-plot in this process: (exit code, stdout, stderr)."""
    out, err = io.StringIO(), io.StringIO()
    with contextlib.redirect_stdout(out), contextlib.redirect_stderr(err):
        try:
            code = plot_main([str(a) for a in args])
        except SystemExit as exc:          # argparse
            code = exc.code
        except Exception as exc:           # noqa: BLE001 - a traceback is the failure asserted against
            import traceback
            code, err = "traceback", io.StringIO("Traceback (most recent call last):\n" + "".join(
                traceback.format_exception(exc)))
    plt.close("all")
    return code, out.getvalue(), err.getvalue()


def legend_outside(ax, legend):
    """The legend's box and the axes' data area do not overlap."""
    ax.figure.canvas.draw()
    box, area = legend.get_window_extent(), ax.get_window_extent()
    return box.x0 >= area.x1 or box.x1 <= area.x0 or box.y0 >= area.y1 or box.y1 <= area.y0


def legend_texts(ax):
    return [t.get_text() for t in ax.get_legend().get_texts()]


def outside_math(text):
    return re.sub(r"\$[^$]*\$", "", text)


# ------------------------------------------------------------------ errors
@pytest.mark.parametrize("args, file, words", [
    (["reaction"], "contact_only", ["reaction figure", "reaction, normal", "&output fields"]),
    (["energy"], "contact_only", ["energy figure", "energy", "&output fields"]),
    (["nutation"], "bare", ["nutation figure", "nutation", "&output fields"]),
    (["trace"], "bare", ["trace figure", "contact", "&output fields"]),
    (["spectrum"], "fixed", ["spectrum figure", "base_acceleration", "&excitation", "&output fields"]),
    (["spectrum"], "contact_only", ["reaction, base_acceleration", "&output fields"]),
    (["trace", "--case", 1], "invalid", ["case 1 was never run", "invalid"]),
    (["nutation", "--case", 1], "invalid", ["case 1 was never run"]),
    (["reaction", "--case", 1], "invalid", ["case 1 was never run"]),
    (["energy", "--case", 1], "invalid", ["case 1 was never run"]),
    (["trace", "--case", 5], "invalid", ["case 5 out of range"]),
    (["report", "--case", 5], "invalid", ["case 5 out of range"]),
    (["transmissibility"], "fixed", ["excitation_frequency"]),
    (["transmissibility"], "invalid", ["excitation_frequency"]),
    (["suite"], "fixed", ["not a record suite"]),
    (["sweep"], "bare", ["nothing to sweep"]),
    (["sweep", "--y", "speed"], "sampled", ["no summary quantity speed"]),
    (["workprecision"], "bare", ["no error figures", "error_estimate"]),
])
def test_a_figure_that_cannot_be_drawn_is_a_one_line_error(files, tmp_path, args, file, words):
    code, _, err = cli(args[0], files[file], *args[1:], "--out", tmp_path)
    assert code == 2 and "Traceback" not in err, err
    lines = err.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("ellroll-plot: error: ") and f"{file}.h5" in lines[0], err
    for word in words:
        assert word in lines[0], (word, err)
    assert not list(tmp_path.glob("*.png"))                     # no empty figure left behind


@pytest.mark.parametrize("file, case", [("bare", 0), ("contact_only", 0), ("invalid", 1)])
def test_every_subcommand_on_files_without_its_fields_ends_cleanly(files, tmp_path, file, case):
    """Each subcommand on a file without trajectories, with only some, and
    on a case never run: a figure, or one line saying why not; never a
    traceback. (The other file shapes: the tests below and the docs' commands.)"""
    drawn = 0
    for command in ("trace", "nutation", "reaction", "energy", "spectrum", "sweep", "transmissibility", "suite",
                    "workprecision", "report", "summary"):
        extra = ["--case", case] if command not in ("sweep", "transmissibility", "suite", "workprecision",
                                                    "summary") else []
        out = [] if command == "summary" else ["--out", tmp_path / command]
        code, _, err = cli(command, files[file], *extra, *out)
        assert code in (0, 2) and "Traceback" not in err, (command, file, err)
        assert code == 0 or len(err.strip().splitlines()) == 1, err
        drawn += code == 0
    assert drawn >= 2                          # the report and the summary at least


def test_report_of_a_never_run_case_says_so(files, tmp_path):
    code, _, err = cli("report", files["invalid"], "--case", 1, "--out", tmp_path)
    assert code == 0, err
    page = (tmp_path / "index.html").read_text()
    assert "Case 1 was never run (invalid): no per-case figures" in page
    assert not list(tmp_path.glob("*_case1.png"))


# ------------------------------------------------------ transmissibility
def tick_labels(ax):
    ax.figure.canvas.draw()
    low, high = ax.get_xlim()
    return [t.get_text() for t, value in zip(ax.get_xticklabels(which="both"), ax.get_xticks(minor=False).tolist()
                                                 + ax.get_xticks(minor=True).tolist())
            if t.get_text() and low <= value <= high]


def test_transmissibility_labels_its_decades_and_only_the_excited_modes(files):
    with ellroll_post.open(files["harm_x"]) as run_:
        fig, ax = plt.subplots()
        plots.plot_transmissibility(ax, run_)
        labels = tick_labels(ax)
        # every decade of 0.02-2 Hz, and 2 and 5 times each (two decades: one label each would be too few)
        assert {"0.1", "1"} <= set(labels) and {"0.02", "0.05", "0.2", "0.5", "2"} <= set(labels), labels
        texts = legend_texts(ax)
        # shaken along x: the x mode (the longer period, a^2/c > b^2/c) and no other
        period_x = 2 * np.pi * np.sqrt(1.4 * (1.0**2 / 0.2 - 0.2) / 9.81)
        assert [t for t in texts if "resonance" in t] == [f"linear resonance, mode 1 (along x): {1 / period_x:.4g} Hz"]
        assert not any("mode 2" in t for t in texts)
        assert ax.get_ylabel() == r"transmissibility $|a_\mathrm{ball}| / |a_\mathrm{base}|$, 1"
        assert "harm_x.h5" in ax.get_title() and "shaken along x" in ax.get_title()
        assert legend_outside(ax, ax.get_legend())
        plt.close(fig)
    with ellroll_post.open(files["harm_y"]) as run_:           # 0.15-0.6 Hz: under a decade, no decade inside
        fig, ax = plt.subplots()
        plots.plot_transmissibility(ax, run_)
        labels = tick_labels(ax)
        assert len(labels) >= 4 and {"0.2", "0.3", "0.4", "0.5"} <= set(labels), labels
        texts = [t for t in legend_texts(ax) if "resonance" in t]
        assert len(texts) == 1 and "mode 2 (along y)" in texts[0]
        plt.close(fig)


# ---------------------------------------------------------------- spectrum
@pytest.mark.parametrize("file, case, record", [("suite", 3, "record SYN3 (SYN3_H1.AT2, SYN3_H2.AT2), scaled by 3"),
                                                ("suite", 1, "record SYN1 (SYN1_H1.AT2, SYN1_H2.AT2), scaled by 2"),
                                                ("record", 0, "record synthetic_ground.csv"),
                                                ("moving", 0, "harmonic 0.2 Hz, 0.1 m/s$^2$ along x")])
def test_spectrum_names_its_record_and_keeps_the_legend_off_the_curves(files, file, case, record):
    with ellroll_post.open(files[file]) as run_:
        fig, ax = plt.subplots(layout="constrained")
        plots.plot_spectrum(ax, run_, case)
        title = ax.get_title()
        assert record in title and f"{file}.h5" in title and f"case {case}: completed" in title, title
        assert legend_outside(ax, ax.get_legend())
        assert ax.get_ylabel() == r"horizontal amplitude, m/s$^2$"
        plt.close(fig)


# ------------------------------------------------------------------ energy
def test_energy_on_a_moving_cup_is_the_change_by_the_cups_work(files):
    with ellroll_post.open(files["moving"]) as run_:
        fig, ax = plt.subplots()
        plots.plot_energy(ax, run_)
        lines = {line.get_label(): line for line in ax.get_lines()}
        change = lines[r"energy change $E - E_0$"].get_ydata()
        work = [line for label, line in lines.items() if label.startswith("work of the moving cup")][0].get_ydata()
        energy = run_.trajectory("energy")
        np.testing.assert_array_equal(change, energy - energy[0])
        # the energy balance E - E0 = W (no rolling resistance), W from the
        # samples by the trapezoid rule: equal to its O(interval^2) error
        assert np.max(np.abs(change)) > 1e-2 * energy[0]            # the cup does work: not round-off
        assert np.max(np.abs(change - work)) < 1e-3 * np.max(np.abs(change))
        assert not any("error" in outside_math(t).split("constraint")[0] for t in legend_texts(ax)
                       if "constraint" not in t)
        assert ax.get_title().startswith("Energy change and the moving cup's work, moving.h5 (case 0")
        assert ax.get_yscale() == "linear" and ax.get_ylabel() == r"$E - E_0$, J"
        plt.close(fig)
    with ellroll_post.open(files["fixed"]) as run_:
        fig, ax = plt.subplots()
        plots.plot_energy(ax, run_)
        assert ax.get_title().startswith("Energy error and constraint error, fixed.h5")
        assert legend_texts(ax)[0] == r"energy error $|E - E_0| / E_0$"
        plt.close(fig)


# ------------------------------------------------------------------- trace
def test_trace_says_why_the_energy_bound_is_left_out(files):
    for file, note in [("contact_only", "no energy bound: needs the fields energy, omega, normal"),
                       ("moving", "no energy bound: the cup moves (its work changes the energy)"),
                       ("fixed", None)]:
        with ellroll_post.open(files[file]) as run_:
            fig, ax = plt.subplots()
            plots.plot_trace(ax, run_)
            texts = legend_texts(ax)
            bound = "energy bound (spin about n kept)" in [line.get_label() for line in ax.get_lines()]
            if note:
                assert note in texts and not bound, texts
            else:
                assert bound and not any(t.startswith("no energy bound") for t in texts)
            plt.close(fig)


# ---------------------------------------------------------------- reaction
def test_reaction_labels_are_mathtext_with_units_once(files):
    with ellroll_post.open(files["fixed"]) as run_:
        fig, axes = plt.subplots(3, 1)
        plots.plot_reaction(axes, run_)
        assert [ax.get_ylabel() for ax in axes] == ["$F_n$, N", "$|F_t|$, N", "$|F_t| / F_n$, 1"]
        texts = [ax.get_ylabel() for ax in axes] + [t for ax in axes for t in legend_texts(ax)]
        for text in texts:
            assert "N, N" not in text and "|" not in outside_math(text) and "_" not in outside_math(text), text
        plt.close(fig)


# ----------------------------------------------------------- workprecision
def test_workprecision_has_one_shared_legend_outside_the_axes(files, tmp_path):
    from ellroll_post.cli import workprecision_points
    fig, axes = plt.subplots(1, 2, figsize=(12, 4.5), layout="constrained")
    plots.plot_workprecision(axes, workprecision_points([files["wp"]]))
    assert all(ax.get_legend() is None for ax in axes) and len(fig.legends) == 1
    legend = fig.legends[0]
    assert [t.get_text() for t in legend.get_texts()] == ["dop853", "rk4", "vern9"]
    for ax in axes:
        assert legend_outside(ax, legend)
    plt.close(fig)
    code, _, err = cli("workprecision", files["wp"], "--out", tmp_path)
    assert code == 0, err


# ----------------------------------------------------------- sampled sweep
def test_sampled_sweep_band_from_completed_cases_and_readable_markers(files):
    with ellroll_post.open(files["sampled"]) as run_:
        done = np.array(run_.status_names()) == "completed"
        assert done.sum() >= 100
        fig = plt.figure()
        (ax,) = plots.plot_sweep(fig, run_, ["omega_z"], ["theta_max"])
        bins = plots.band_bins(done.sum())
        assert bins == min(max(done.sum() // 20, 5), 30)
        median = [line for line in ax.get_lines() if line.get_label() == "median of completed cases"][0]
        x, y = run_.input_column("omega_z")[done], run_.summary("theta_max")[done]
        edges = np.linspace(x.min(), x.max(), bins + 1)
        expected = [np.median(y[(x >= lo) & ((x < hi) | (hi == edges[-1]))]) for lo, hi in zip(edges, edges[1:])]
        np.testing.assert_allclose(median.get_ydata(), expected, rtol=1e-12)
        assert any(t.startswith("10-90 % of completed cases") for t in legend_texts(ax))
        plt.close(fig)
    with ellroll_post.open(files["sampled_few"]) as run_:
        status = np.array(run_.status_names())
        done = status == "completed"
        assert 0 < done.sum() < plots.BAND_MIN_CASES and (~done).sum() > 0
        fig = plt.figure()
        (ax,) = plots.plot_sweep(fig, run_, ["omega_z"], ["theta_max"])
        lines = {line.get_label(): line for line in ax.get_lines()}
        assert f"no median or 10-90 % band: {done.sum()} completed cases, {plots.BAND_MIN_CASES} needed" in lines
        assert "median of completed cases" not in lines
        cloud = [line for label, line in lines.items() if "completed case" in label and "(" in label][0]
        assert len(cloud.get_xdata()) == done.sum()               # only the completed cases as coloured points
        for name in set(status[~done]):
            marker = lines[f"ended: {name}"]
            assert marker.get_markeredgewidth() <= 1 and marker.get_markerfacecolor() == "none"
            grey = matplotlib.colors.to_rgb(marker.get_markeredgecolor())
            assert max(grey) - min(grey) < 1e-9                  # grey: no colour to compete with the data's
        plt.close(fig)
        fig = plt.figure()
        (ax,) = plots.plot_sweep(fig, run_, ["omega_z", "radius"], ["theta_max"])
        assert ax.collections[0].get_offsets().shape == (done.sum(), 2)   # coloured: completed cases only
        assert ax.collections[0].get_linewidths()[0] == 0                  # no outline over the colour
        plt.close(fig)


# ------------------------------------------------------------------ report
def table_rows(page, title):
    section = page.split(f"<h2>{title}</h2>")[1].split("</table>")[0]
    return [re.findall(r"<t[dh]>([^<]*)</t[dh]>", row) for row in section.split("<tr>")[1:]]


def report_page(path, folder, **options):
    """index.html of build_report, the figures not drawn (their names only):
    the page is what is tested here, the figures elsewhere."""
    from ellroll_post.report import build_report

    def draw(name, run_, out, case=0, fmt="png", x_names=None, y_names=None):
        return folder / f"{name}.{fmt}"
    with ellroll_post.open(path) as run_:
        build_report(run_, folder, draw, **options)
    return (folder / "index.html").read_text()


def test_report_fits_the_page_summarises_and_pages_the_cases(files, tmp_path):
    page = report_page(files["sampled"], tmp_path / "paged")
    assert "overflow-x:auto" in page and "th{white-space:normal" in page.replace(" ", "")
    with ellroll_post.open(files["sampled"]) as run_:
        n = run_.n_cases
        status = np.array(run_.status_names())
        theta = run_.summary("theta_max")[status == "completed"]
    assert f"<strong>{n} cases: {(status == 'completed').sum()} completed" in page
    cases = table_rows(page, "Cases")
    assert len(cases) == 1 + 50 and f"The first 50 of {n} cases" in page
    summary = {row[0]: row[1:] for row in table_rows(page, "Campaign summary")[1:]}
    assert [float(v) for v in summary["theta_max, rad"][:3]] == pytest.approx(
        [theta.min(), np.median(theta), theta.max()], rel=1e-5)
    assert "error_contact, m" not in cases[0] and "transmissibility" not in cases[0]     # NaN in every case
    assert len(table_rows(report_page(files["sampled"], tmp_path / "all", all_cases=True), "Cases")) == 1 + n
    page = report_page(files["fixed"], tmp_path / "one")
    assert "<strong>1 case: 1 completed.</strong>" in page and "1 cases" not in page
    heads = table_rows(page, "Cases")[0]
    assert "theta_max, rad" in heads and not {"displacement_max, m", "transmissibility"} & set(heads)
    heads = table_rows(report_page(files["moving"], tmp_path / "moving"), "Cases")[0]
    assert "displacement_max, m" in heads
    code, _, err = cli("report", files["sampled"], "--cases", "--out", tmp_path / "cli")     # the option
    assert code == 0 and len(table_rows((tmp_path / "cli" / "index.html").read_text(), "Cases")) == 1 + n, err


# -------------------------------------------------------------------- docs
def docs_plot_commands():
    """Every `ellroll-plot ...` command line of the README, docs/ and post/README.md."""
    commands = []
    for page in [ROOT / "README.md", ROOT / "post" / "README.md", *sorted((ROOT / "docs").glob("*.md"))]:
        for line in page.read_text().splitlines():
            match = re.match(r"^\.venv/bin/ellroll-plot\s+(.*?)\s*(#.*)?$", line.strip())
            if match:
                commands.append(shlex.split(match.group(1)))   # as the shell reads it
    return commands


def test_every_ellroll_plot_command_of_the_docs_runs_on_the_shipped_inputs(ellroll, tmp_path):
    commands = docs_plot_commands()
    assert {c[0] for c in commands} >= {"trace", "nutation", "report", "sweep", "summary", "transmissibility", "suite"}
    shutil.copytree(ROOT / "input", tmp_path / "input")
    made = set()
    for command in commands:
        file = next(a for a in command[1:] if a.endswith(".h5"))
        if file not in made:                 # the shipped input that writes it, run as shipped
            source = {"legeza1990.h5": "legeza1990.nml"}.get(file, file.replace(".h5", ".nml"))
            result = run(ellroll, "run", source, "-q", "--threads", 2, "-o", tmp_path / file,
                         cwd=tmp_path / "input", timeout=300)
            assert result.returncode == 0, result.stderr
            made.add(file)
        args = [str(tmp_path / a) if a == file else a for a in command]
        out = [] if command[0] == "summary" else ["--out", tmp_path / "figures", "--overwrite"]
        code, stdout, err = cli(*args, *out)
        assert code == 0, (command, err)
        assert stdout.strip(), command


def test_trace_colours_the_path_by_regime(ellroll, tmp_path):
    """A case that slides twice (the paper's cup, mu = 0.05): the trace has a
    rolling and a sliding line, each drawn exactly on its regime's samples
    and the one after (where the regime turns)."""
    (tmp_path / "slide.nml").write_text(
        "&geometry a = 1.0, b = 0.4, c = 0.2 /\n&ball radius = 0.2, weight = 2620.0, mu = 0.05, slip = 'slide' /\n"
        "&initial x = 0.0, y = 0.0, omega = -2.0, 2.0, 20.0 /\n"
        "&integration method = 'rk4', dt = 1e-3, t_end = 5.0 /\n&output file = 'slide.h5', interval = 1e-2 /\n")
    assert run(ellroll, "run", "slide.nml", "-q", cwd=tmp_path).returncode == 0
    with ellroll_post.open(tmp_path / "slide.h5") as run_:
        regime = run_.trajectory("regime", 0)
        fig, ax = plt.subplots()
        plots.plot_trace(ax, run_)
        lines = {line.get_label(): line for line in ax.get_lines()}
        for value, name in [(0, "contact point, rolling"), (1, "contact point, sliding")]:
            drawn = ~np.ma.getmaskarray(lines[name].get_xdata())
            expected = regime == value
            expected[1:] |= expected[:-1]
            assert np.array_equal(drawn, expected), name
        assert lines["contact point, rolling"].get_color() != lines["contact point, sliding"].get_color()
        assert 0 < np.count_nonzero(regime == 1) < regime.size and "contact point" not in lines
        plt.close(fig)


def test_a_file_still_being_written_draws_its_finished_cases(ellroll, tmp_path):
    """A sweep stopped by SIGINT part way (OUT.h5.partial, the pending cases'
    inputs not yet written): `sweep` draws the finished cases against the
    swept input and counts the rest as not run yet; `report` is written."""
    import signal
    import subprocess
    import time
    make(tmp_path, "part", "&sweep name = 'omega_z', start = 10, stop = 80, count = 64 /\n", dt="1.0e-4",
         t_end=20.0)
    proc = subprocess.Popen([str(ellroll), "run", "part.nml", "-q", "--threads", "1"], cwd=tmp_path,
                            stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    journal = tmp_path / "part.h5.journal"
    deadline = time.monotonic() + 60
    while proc.poll() is None and time.monotonic() < deadline and not (journal.exists() and
                                                                        journal.stat().st_size > 4096):
        time.sleep(0.002)
    proc.send_signal(signal.SIGINT)
    assert proc.wait(timeout=60) == 130
    partial = tmp_path / "part.h5.partial"
    with ellroll_post.open(partial) as run_:
        status = np.array(run_.status_names())
        assert 0 < (status == "completed").sum() < 64 and (status == "pending").sum() > 0
        assert run_.swept_inputs() == ["omega_z"]
    code, _, err = cli("sweep", partial, "--out", tmp_path)
    assert code == 0, err
    assert (tmp_path / "part.h5_sweep_omega_z.png").stat().st_size > 0
    code, _, err = cli("report", partial, "--out", tmp_path / "report")
    assert code == 0, err
