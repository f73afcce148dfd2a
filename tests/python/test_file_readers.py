"""The output file opens in every reader without options: h5py, xarray's
default engine and its h5netcdf and netcdf4 engines, netCDF4-python and
ncdump; on a single case, a sweep, a record suite and a merged file. A
reader not installed is skipped with its reason."""
import csv
import io
import os
import shutil
import signal
import subprocess
import sys
import time

import h5py
import numpy as np
import pytest

from conftest import PAPER_INPUT, ROOT, run

SWEEP = """
&sweep name = 'omega_z', values = 10.0, 40.0 /
&sweep name = 'x', values = 0.0, 0.05, 1.5 /
"""


@pytest.fixture(scope="module")
def files(ellroll, tmp_path_factory):
    """{kind: path}: one case, a sweep (with an invalid case: NaN figures),
    a record suite and a file merged from two shards."""
    from test_records import SUITE, write_suite_records
    folder = tmp_path_factory.mktemp("readers")
    text = PAPER_INPUT.read_text().replace("t_end = 30.0", "t_end = 0.5").replace("interval = 0.01", "interval = 0.1")
    (folder / "single.nml").write_text(text)
    (folder / "sweep.nml").write_text(text.replace("&output", "&campaign invalid = 'skip' /\n&output") + SWEEP)
    write_suite_records(folder)
    (folder / "suite.nml").write_text(SUITE)
    for name in ("single", "sweep", "suite"):
        result = run(ellroll, "run", f"{name}.nml", "-q", "-o", f"{name}.h5", cwd=folder)
        assert result.returncode == 0, result.stderr
    for i in (0, 1):
        assert run(ellroll, "run", "sweep.nml", "-q", "--shard", f"{i}/2", "-o", f"shard_{i}.h5",
                   cwd=folder).returncode == 0
    assert run(ellroll, "merge", "merged.h5", "shard_0.h5", "shard_1.h5", cwd=folder).returncode == 0
    return {name: folder / f"{name}.h5" for name in ("single", "sweep", "suite", "merged")}


KINDS = ["single", "sweep", "suite", "merged"]


@pytest.mark.parametrize("kind", KINDS)
def test_hdf5_signature_at_the_start(files, kind):
    """No user block: the HDF5 signature is the file's first bytes (xarray
    guesses the engine from them)."""
    assert files[kind].read_bytes()[:8] == b"\x89HDF\r\n\x1a\n"
    with h5py.File(files[kind], "r") as f:
        assert f.userblock_size == 0
        assert f["trajectory_label"][()].startswith(b"ellroll trajectories: 3 ")


@pytest.mark.parametrize("engine", [None, "h5netcdf", "netcdf4"])
@pytest.mark.parametrize("kind", KINDS)
def test_xarray_every_engine(files, kind, engine):
    xr = pytest.importorskip("xarray")
    if engine == "netcdf4" or engine is None:
        pytest.importorskip("netCDF4", reason="netCDF4-python is not installed (pip install netCDF4)")
    if engine == "h5netcdf":
        pytest.importorskip("h5netcdf")
    path = files[kind]
    tree = xr.open_datatree(path, engine=engine)
    assert set(tree.children) >= {"case", "summary", "trajectory"}
    for group in ("case", "summary", "trajectory"):
        ds = xr.open_dataset(path, group=group, engine=engine).load()
        assert ds.sizes["case"] == tree["summary"].sizes["case"]
    case = xr.open_dataset(path, group="case", engine=engine)
    assert case["method"].values[0] == "rk4"         # text as str, whatever the engine
    traj = xr.open_dataset(path, group="trajectory", engine=engine)
    assert "time" in traj.coords and traj["time"].attrs["units"] == "s"
    with h5py.File(path, "r") as f:
        np.testing.assert_array_equal(traj["time"].values, f["time"][:])
        nutation = f["trajectory/nutation"][:, np.flatnonzero(f["time"][:] == 0.5)[0]]
    np.testing.assert_array_equal(traj.sel(time=0.5)["nutation"].values, nutation)
    if kind == "suite":
        summary = xr.open_dataset(path, group="summary", engine=engine)
        assert set(summary["record"].values) == {"first", "second", "third"}


@pytest.mark.parametrize("kind", KINDS)
def test_netcdf4_python_and_ncdump(files, kind):
    netCDF4 = pytest.importorskip("netCDF4", reason="netCDF4-python is not installed (pip install netCDF4)")
    with netCDF4.Dataset(files[kind]) as nc:
        assert nc.Conventions == "CF-1.10"
        assert nc["trajectory"]["time"].dimensions == ("time",)
        assert nc["case"]["method"][0] == "rk4"
    if shutil.which("ncdump") is None:
        pytest.skip("ncdump is not installed (Debian: netcdf-bin)")
    result = subprocess.run(["ncdump", "-h", str(files[kind])], capture_output=True, text=True)
    assert result.returncode == 0, result.stderr
    assert "group: trajectory" in result.stdout and "double time(time)" in result.stdout


def test_status_flags_are_cf(files):
    """CF: flag_values of the type of the variable, one meaning per value."""
    with h5py.File(files["sweep"], "r") as f:
        status = f["summary/status"]
        values = status.attrs["flag_values"]
        assert values.dtype == status.dtype == np.int64
        assert len(status.attrs["flag_meanings"].split()) == len(values) == len(set(values))
        assert set(status[:]) <= set(values)


def summary_frame_of(path):
    import ellroll_post
    return ellroll_post.summary_frame(path)


def test_summary_frame(files):
    pd = pytest.importorskip("pandas")
    frame = summary_frame_of(files["sweep"])
    with h5py.File(files["sweep"], "r") as f:
        n = f["summary/status"].shape[0]
        assert frame.shape[0] == n == 6
        assert list(frame.index) == list(f["summary/case"][:])
        np.testing.assert_array_equal(frame["omega_z"], f["case/omega"][:, 2])
        np.testing.assert_array_equal(frame["x"], f["case/x"][:])
        np.testing.assert_array_equal(frame["theta_max"], f["summary/theta_max"][:])
        np.testing.assert_array_equal(frame["linear_periods_2"], f["summary/linear_periods"][:, 1])
        assert (frame["method"] == "rk4").all()
    assert isinstance(frame["status"].dtype, pd.CategoricalDtype)
    assert frame["status"].value_counts()["invalid"] == 2          # x = 1.5 lies outside the cup
    assert frame.attrs["units"]["omega_z"] == "rad/s" and frame.attrs["units"]["theta_max"] == "rad"


def test_csv_of_both_tools_byte_identical(ellroll, files):
    """`ellroll summary --format csv` and `ellroll-plot summary --format csv`
    write the same text: integers as integers, NaN alike, units in the
    header; also for random numbers of every magnitude put in the file."""
    rng = np.random.default_rng(43)
    random = files["sweep"].with_name("random.h5")
    shutil.copy(files["sweep"], random)
    with h5py.File(random, "r+") as f:
        theta = f["summary/theta_max"]
        shape = theta.shape
        mantissa, exponent = rng.uniform(-10, 10, shape), rng.integers(-320, 308, shape)
        theta[...] = mantissa * 10.0 ** exponent.astype(float)
        f["summary/energy_drift"][...] = rng.choice([0.1, 1e-4, 9.99999e-5, 1e10, 9999999999.5, 123.0,
                                                     -0.0, np.inf, -np.inf, 2.0 ** -1074], shape)
    for kind in ("sweep", "suite", "merged"):
        path = files[kind] if kind != "merged" else random
        fortran = run(ellroll, "summary", path, "--format", "csv").stdout
        python = subprocess.run([sys.executable, "-m", "ellroll_post.cli", "summary", str(path), "--format", "csv"],
                                capture_output=True, text=True).stdout
        assert fortran == python and fortran
    rows = list(csv.reader(io.StringIO(run(ellroll, "summary", files["sweep"], "--format", "csv").stdout)))
    header = rows[0]
    assert header[:4] == ["case", "omega_z [rad/s]", "x [m]", "status"] and "theta_max [rad]" in header
    invalid = [row for row in rows[1:] if row[3] == "invalid"]
    assert invalid and invalid[0][header.index("theta_max [rad]")] == "NaN"
    assert rows[1][header.index("n_steps")] == "500" and rows[1][1] == "10"


STOPPED = """&geometry a = 1.0, b = 0.4, c = 0.2 /
&ball radius = 0.2, weight = 2620.0 /
&initial x = 0.0, y = 0.0, omega = -2.0, 2.0, 20.0 /
&integration method = 'rk4', dt = 1.0e-3, t_end = 20.0 /
&output file = 'k.h5', interval = 0.05 /
&sweep name = 'omega_z', start = 1, stop = 100, count = 300 /
&sweep name = 'rolling_resistance', values = 0.0, 1e-4 /
"""


def stop_a_run(ellroll, folder, name, journal):
    """Run name in folder, stopped by SIGTERM 0.2 s after its journal appears."""
    writer = subprocess.Popen([str(ellroll), "run", name, "-q", "--threads", "1"], cwd=folder,
                              stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    while not (folder / journal).exists():
        time.sleep(0.01)
    time.sleep(0.2)
    writer.send_signal(signal.SIGTERM)
    assert writer.wait(timeout=60) != 0


def test_a_stopped_suite_s_record_names_are_the_same_from_both_tools(ellroll, tmp_path):
    """A record suite stopped by SIGTERM: both tools write the same CSV,
    the pending cases' record named (from /summary's coordinate), as the
    reader's record_names and input_column give it."""
    import ellroll_post
    from test_records import SUITE, write_suite_records
    write_suite_records(tmp_path)
    (tmp_path / "s.nml").write_text(SUITE.replace("values = 1.0, 2.0", "start = 0.5, stop = 2.0, count = 200"))
    stop_a_run(ellroll, tmp_path, "s.nml", "suite.h5.journal")
    path = tmp_path / "suite.h5.partial"
    fortran = run(ellroll, "summary", path, "--format", "csv")
    python = subprocess.run([sys.executable, "-m", "ellroll_post.cli", "summary", str(path), "--format", "csv"],
                            capture_output=True, text=True)
    pending = [row for row in csv.DictReader(io.StringIO(python.stdout)) if row["status"] == "pending"]
    assert pending and all(row["record"] in ("first", "second", "third") for row in pending), python.stderr[-300:]
    assert fortran.stdout == python.stdout
    with ellroll_post.open(path) as f:
        assert all(f.record_names()) and len(set(f.record_names())) == 3


def test_a_stopped_runs_summary_is_the_same_from_both_tools(ellroll, tmp_path):
    """A run stopped by SIGTERM (its OUT.h5.partial, pending cases in it):
    both tools write the same CSV, the pending cases' swept inputs their
    values (the file's coordinates, in /summary), and --suite's stripes
    (one per case here) count every case of the campaign once."""
    (tmp_path / "a.nml").write_text(STOPPED)
    stop_a_run(ellroll, tmp_path, "a.nml", "k.h5.journal")
    path = tmp_path / "k.h5.partial"
    for options in ([], ["--suite"]):
        fortran = run(ellroll, "summary", path, "--format", "csv", *options)
        python = subprocess.run([sys.executable, "-m", "ellroll_post.cli", "summary", str(path), "--format", "csv",
                                 *options], capture_output=True, text=True)
        rows = list(csv.DictReader(io.StringIO(python.stdout)))
        if options:
            assert len(rows) == 600 and sum(int(row["n_cases"]) for row in rows) == 600, python.stderr[-300:]
            assert [row["n_cases"] for row in csv.DictReader(io.StringIO(fortran.stdout))] == ["1"] * 600
        else:
            assert fortran.stdout == python.stdout and fortran.stdout, python.stderr[-300:]
            pending = [row for row in rows if row["status"] == "pending"]
            assert pending and all(row["omega_z [rad/s]"] != "NaN" for row in pending)


def test_docs_snippet(files, tmp_path):
    """docs/output.md's summary_frame example runs on a sweep."""
    pytest.importorskip("pandas")
    text = (ROOT / "docs" / "output.md").read_text()
    block = text.split("<!-- summary_frame example -->")[1].split("```python\n")[1].split("```")[0]
    shutil.copy(files["sweep"], tmp_path / "spin_sweep.h5")
    subprocess.run([sys.executable, "-c", block], cwd=tmp_path, check=True, capture_output=True, text=True)


def test_csv_numbers_at_every_power_of_ten_read_back(ellroll, files):
    """Each number the CSV writes reads back as the double stored, and both
    tools write the same text, for the doubles at and beside every power of
    ten (where rounding to 15 digits carries into the next decade) and the
    ends of the range."""
    edges = [0.5 ** 1074, 0.5 ** 1022, np.nextafter(0.5 ** 1022, 0), np.finfo(float).max]
    for k in range(-323, 309):
        power = float(f"1e{k}")
        edges += [power, np.nextafter(power, 0), np.nextafter(power, np.inf),
                  float(f"9.999999999999999e{k - 1}"), float(f"9.9999999999999999e{k - 1}")]
    edges = [x for x in edges if x > 0]
    edges += [-x for x in edges[::7]]
    # a sweep of 400 short cases holds them in a few files
    folder = files["sweep"].parent
    text = PAPER_INPUT.read_text().replace("t_end = 30.0", "t_end = 0.01").replace("interval = 0.01", "interval = 0.01")
    spins = ", ".join(str(1 + i / 10) for i in range(400))
    (folder / "powers.nml").write_text(text + f"&sweep name = 'omega_z', values = {spins} /\n")
    assert run(ellroll, "run", "powers.nml", "-q", "-o", "powers.h5", cwd=folder).returncode == 0
    edited = folder / "powers.h5"
    header = next(csv.reader(io.StringIO(run(ellroll, "summary", edited, "--format", "csv").stdout)))
    varied = {h.split(" [")[0] for h in header[1:header.index("status")]}      # the inputs' columns
    with h5py.File(edited, "r") as f:
        columns = [name for name, item in f["summary"].items()
                   if item.dtype == np.float64 and item.ndim == 1 and name != "wall_time" and name not in varied]
        n_cases = f["summary/theta_max"].shape[0]
    per_file = n_cases * len(columns)
    for start in range(0, len(edges), per_file):
        chunk = np.array(edges[start:start + per_file] + [1.0] * (per_file - len(edges[start:start + per_file])))
        with h5py.File(edited, "r+") as f:
            for j, name in enumerate(columns):
                f["summary"][name][...] = chunk[j * n_cases:(j + 1) * n_cases]
        fortran = run(ellroll, "summary", edited, "--format", "csv").stdout
        python = subprocess.run([sys.executable, "-m", "ellroll_post.cli", "summary", str(edited), "--format", "csv"],
                                capture_output=True, text=True).stdout
        assert fortran == python and fortran
        rows = list(csv.reader(io.StringIO(fortran)))
        header = rows[0]
        for j, name in enumerate(columns):
            column = next(i for i, h in enumerate(header) if h == name or h.startswith(name + " ["))
            written = [float(row[column]) for row in rows[1:]]
            expected = chunk[j * n_cases:(j + 1) * n_cases]
            assert np.array_equal(np.array(written), expected), (name, [(w, e, row[column]) for w, e, row in
                                                                      zip(written, expected, rows[1:]) if w != e][:3])


def test_summary_table_gives_each_figure_over_the_completed_cases(ellroll, files):
    """`ellroll summary` of a campaign: per real figure, min / median / max
    over the completed cases (not the invalid one), to six digits."""
    table = run(ellroll, "summary", files["sweep"]).stdout
    with h5py.File(files["sweep"], "r") as f:
        status = f["summary/status"][()]
        completed = status == list(f["summary/status"].attrs["flag_meanings"].split()).index("completed")
        assert 0 < completed.sum() < len(status)
        assert f"over the {completed.sum()} completed cases:" in table
        rows = {line.split()[0]: line.split()[-3:] for line in table.splitlines() if line.startswith("    ")}
        checked = 0
        for name in ("theta_max", "displacement_max", "energy_drift", "reaction_normal_max"):
            values = f["summary"][name][()][completed]
            expected = [np.min(values), np.median(values), np.max(values)]
            written = [float(v) for v in rows[name]]
            assert np.allclose(written, expected, rtol=5e-6, atol=0), (name, written, expected)
            checked += 1
        assert checked == 4 and "wall_time" not in rows


@pytest.mark.parametrize("change", ["another output copied over it", "truncated", "one byte rewritten"])
def test_a_file_written_to_while_open_is_named_not_read(files, tmp_path, change):
    """A file changed in place while ellroll_post holds it open (cp or rsync
    --inplace of another output, a truncation, a byte written as it was):
    each read after raises NotAnEllrollFile saying so, never the zeros and
    NaN that HDF5's cached tables give against the new bytes; opened again,
    the file reads as what it now is."""
    import ellroll_post
    path = tmp_path / "held.h5"
    shutil.copyfile(files["sweep"], path)
    with ellroll_post.open(path) as f:
        before = f.summary("theta_max")
        assert np.all(np.isfinite(before[:2]))
        if change == "truncated":
            os.truncate(path, path.stat().st_size // 2)
        elif change == "one byte rewritten":
            time.sleep(0.05)                          # (a later modification time: the clock of file times is coarse)
            with open(path, "r+b") as out:
                out.seek(100)
                byte = out.read(1)
                out.seek(100)
                out.write(byte)
        else:
            shutil.copyfile(files["single"], path)       # the same inode: copied into it
        reads = [lambda: f.summary("theta_max"), lambda: f.input_column("omega_z"), lambda: f.time,
                 lambda: f.trajectory("nutation", case=0), lambda: f.attrs, lambda: f.n_cases]
        for read in reads:
            with pytest.raises(ellroll_post.NotAnEllrollFile, match="written to since it was opened"):
                read()
    if change == "another output copied over it":
        with ellroll_post.open(path) as f:
            assert f.n_cases == 1
