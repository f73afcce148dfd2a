"""The HDF5 file as an h5py / xarray user sees it."""
import datetime
import pathlib
import re
import shutil
import subprocess
import sys

import h5py
import numpy as np
import pytest

import ellroll_post

from conftest import PAPER_INPUT, run

FIELDS = {"contact": ("m", 3), "center": ("m", 3), "omega": ("rad/s", 3), "normal": ("1", 3),
          "nutation": ("rad", 1), "reaction": ("N", 3), "energy": ("J", 1)}
SUMMARY = ["status", "t_final", "n_steps", "n_rejected", "n_rhs", "wall_time", "theta_max", "reaction_normal_max",
           "friction_needed_max", "energy_drift", "constraint_error_max"]


def test_layout_shapes_units_and_scales(paper_file):
    with h5py.File(paper_file, "r") as f:
        nt = 3001
        assert f["time"].shape == (nt,)
        np.testing.assert_allclose(f["time"][:], np.arange(nt) * 0.01, rtol=0, atol=1e-12)
        for name, (units, ncomp) in FIELDS.items():
            ds = f["trajectory"][name]
            assert ds.shape == ((1, nt, 3) if ncomp == 3 else (1, nt)), name
            assert ds.attrs["units"] == units
            scales = [d[0].name for d in ds.dims]
            assert scales == (["/trajectory/case", "/trajectory/time", "/xyz"] if ncomp == 3
                              else ["/trajectory/case", "/trajectory/time"])
            # uncompressed (the default; see test_compression): contiguous, each
            # case's samples in one piece, written in place by the thread that ran it
            assert ds.chunks is None and ds.compression is None
        np.testing.assert_array_equal(f["trajectory/time"][:], f["time"][:])
        for name in SUMMARY:
            assert f["summary"][name].shape == (1,)
        for name in ["a", "b", "c", "radius", "mass", "g", "x", "y", "dt", "t_end", "method"]:
            assert f["case"][name].shape == (1,)
        assert f["case/omega"].shape == (1, 3)

        def every_dataset_has_units(name, obj):
            if isinstance(obj, h5py.Dataset):
                assert "units" in obj.attrs, name
        f.visititems(every_dataset_has_units)


def test_inputs_and_provenance(paper_file):
    with h5py.File(paper_file, "r") as f:
        case = f["case"]
        assert (case["a"][0], case["b"][0], case["c"][0], case["radius"][0]) == (1.0, 0.4, 0.2, 0.2)
        assert case["mass"][0] * case["g"][0] == pytest.approx(2620.0, rel=1e-15)
        np.testing.assert_array_equal(case["omega"][0], [-2.0, 2.0, 20.0])
        assert case["method"].asstr()[0] == "rk4"
        attrs = f.attrs
        assert attrs["program"] == "ellroll"
        assert attrs["version"]
        created = datetime.datetime.strptime(attrs["created"], "%Y-%m-%dT%H:%M:%SZ")
        assert abs((datetime.datetime.utcnow() - created).total_seconds()) < 3600
        assert attrs["input_namelist"] == PAPER_INPUT.read_text()
        assert " run legeza1990.nml" in attrs["command_line"]


def test_compression(ellroll, tmp_path):
    """&output compression = 4: shuffle + deflate, the same numbers."""
    text = PAPER_INPUT.read_text().replace("t_end = 30.0", "t_end = 2.0")
    plain = text.replace("file = 'legeza1990.h5'", "file = 'plain.h5'")
    packed = text.replace("file = 'legeza1990.h5'", "file = 'packed.h5', compression = 4")
    for name, content in [("plain.nml", plain), ("packed.nml", packed)]:
        (tmp_path / name).write_text(content)
        assert run(ellroll, "run", name, "-q", cwd=tmp_path).returncode == 0
    with h5py.File(tmp_path / "plain.h5", "r") as a, h5py.File(tmp_path / "packed.h5", "r") as b:
        for name in FIELDS:
            assert a["trajectory"][name].compression is None
            assert b["trajectory"][name].compression == "gzip" and b["trajectory"][name].shuffle
            assert b["trajectory"][name].compression_opts == 4
            # chunks of one case (at most 1 MiB): reading a case reads its chunks only
            assert b["trajectory"][name].chunks[0] == 1 and np.prod(b["trajectory"][name].chunks) * 8 <= 2**20
            assert a["trajectory"][name][()].tobytes() == b["trajectory"][name][()].tobytes()


def test_paper_case_results(paper_file):
    with h5py.File(paper_file, "r") as f:
        status = f["summary/status"]
        names = status.attrs["flag_meanings"].split()
        assert names[list(status.attrs["flag_values"]).index(status[0])] == "completed"
        assert f["summary/t_final"][0] == 30.0
        assert f["summary/n_steps"][0] == 30000
        assert f["summary/energy_drift"][0] < 1e-9
        assert f["summary/constraint_error_max"][0] < 1e-13
        theta = f["trajectory/nutation"][0]
        assert f["summary/theta_max"][0] >= np.max(theta)
        # stored fields are consistent with each other
        n = f["trajectory/normal"][0]
        np.testing.assert_allclose(theta, np.arctan2(np.hypot(n[:, 0], n[:, 1]), n[:, 2]), atol=1e-15)
        center, contact = f["trajectory/center"][0], f["trajectory/contact"][0]
        np.testing.assert_allclose(center - contact, 0.2 * n, atol=1e-15)
        energy = f["trajectory/energy"][0]
        # the summary's definition, max |E - E0| / |E0|, evaluated the same way
        assert np.max(np.abs(energy - energy[0]) / np.abs(energy[0])) <= f["summary/energy_drift"][0]


def test_xarray_reads_every_group(paper_file):
    xr = pytest.importorskip("xarray")
    pytest.importorskip("h5netcdf")
    traj = xr.open_dataset(paper_file, engine="h5netcdf", group="trajectory")
    assert traj["contact"].dims == ("case", "time", "xyz")
    assert traj["nutation"].dims == ("case", "time")
    assert traj["contact"].attrs["units"] == "m"
    summary = xr.open_dataset(paper_file, engine="h5netcdf", group="summary")
    assert summary["theta_max"].dims == ("case",)
    inputs = xr.open_dataset(paper_file, engine="h5netcdf", group="case")
    assert inputs["omega"].dims == ("case", "xyz")
    assert inputs["method"].values[0] == "rk4" and inputs["excitation_kind"].values[0] == "none"   # str


def write_input(folder, edits=(), name="case.nml"):
    text = PAPER_INPUT.read_text()
    for old, new in edits:
        assert old in text, old
        text = text.replace(old, new)
    path = folder / name
    path.write_text(text)
    return path


def test_fields_selects_what_is_stored(ellroll, tmp_path):
    write_input(tmp_path, [("interval = 0.01 /", "interval = 0.01, fields = 'nutation', 'contact' /")])
    assert run(ellroll, "run", "case.nml", "-o", "sel.h5", cwd=tmp_path).returncode == 0
    with h5py.File(tmp_path / "sel.h5", "r") as f:
        assert sorted(k for k in f["trajectory"] if k not in ("case", "time")) == ["contact", "nutation"]
        assert f["summary/theta_max"][0] > 0.2


def test_case_ended_at_rim_is_nan_filled(ellroll, tmp_path):
    write_input(tmp_path, [("radius = 0.2", "radius = 0.01"),
                           ("omega = -2.0, 2.0, 20.0", "omega = -400.0, 0.0, 0.0"),
                           ("t_end = 30.0", "t_end = 1.0")])
    result = run(ellroll, "run", "case.nml", "-o", "rim.h5", cwd=tmp_path)
    assert result.returncode == 0, result.stderr
    assert re.search(r"^  rim +1$", result.stdout, re.M), result.stdout
    with h5py.File(tmp_path / "rim.h5", "r") as f:
        t_final = f["summary/t_final"][0]
        assert 0.12 < t_final < 0.121
        contact = f["trajectory/contact"][0]
        inside = f["time"][:] <= t_final
        assert np.all(np.isfinite(contact[inside])) and np.all(np.isnan(contact[~inside]))
        assert np.all(contact[inside, 2] < 0.2)


def test_existing_output_needs_overwrite(ellroll, tmp_path):
    write_input(tmp_path)
    target = tmp_path / "legeza1990.h5"
    assert run(ellroll, "run", "case.nml", "-q", cwd=tmp_path).returncode == 0
    yesterday = target.read_bytes()
    result = run(ellroll, "run", "case.nml", cwd=tmp_path)
    assert result.returncode == 3
    assert "legeza1990.h5" in result.stderr and "--overwrite" in result.stderr
    assert target.read_bytes() == yesterday
    assert run(ellroll, "run", "case.nml", "--overwrite", cwd=tmp_path).returncode == 0
    assert h5py.is_hdf5(target)


def test_unwritable_output_is_an_output_error(ellroll, tmp_path):
    write_input(tmp_path)
    result = run(ellroll, "run", "case.nml", "-o", "no/such/folder/out.h5", cwd=tmp_path)
    assert result.returncode == 3
    assert "no/such/folder/out.h5" in result.stderr
    assert list(tmp_path.iterdir()) == [tmp_path / "case.nml"]


def test_check_prints_the_resolved_case_and_writes_nothing(ellroll, tmp_path):
    write_input(tmp_path)
    result = run(ellroll, "check", "case.nml", cwd=tmp_path)
    assert result.returncode == 0, result.stderr
    for words in ["mass = 267.07", "omega = -2, 2, 20 rad/s", "principal radii of curvature at the start = 0.8, 5 m",
                  "steps per case = 30000", "samples = 3001", "case.nml: ok"]:
        assert words in result.stdout
    assert list(tmp_path.iterdir()) == [tmp_path / "case.nml"]


def test_version_and_help(ellroll):
    version = run(ellroll, "--version")
    assert version.returncode == 0 and version.stdout.startswith("ellroll ")
    help_text = run(ellroll, "--help")
    assert help_text.returncode == 0 and "ellroll run FILE.nml" in help_text.stdout
    assert "exit codes" in help_text.stdout
    assert run(ellroll, "frobnicate", "x.nml").returncode == 2


def test_cf_root_attributes_and_trimmed_attribute_text(paper_file):
    """CF-1.10 global attributes; every text attribute as written (no blank
    padding, no long_name cut short)."""
    with h5py.File(paper_file, "r") as f:
        assert f.attrs["Conventions"] == "CF-1.10"
        assert f.attrs["title"].startswith("ellroll: ") and "Legeza (1990)" in f.attrs["references"]
        assert f.attrs["source"] == f"{f.attrs['program']} {f.attrs['version']}"
        assert f.attrs["history"] == f"{f.attrs['created']} {f.attrs['command_line']}"
        padded = []
        f.visititems(lambda name, obj: padded.extend(
            f"{name}@{key}" for key, value in obj.attrs.items() if isinstance(value, str) and value != value.strip()))
        assert padded == []
        assert f["case/a"].attrs["units"] == "m" and f["case/mu"].attrs["units"] == "1"
        assert f["summary/transmissibility"].attrs["long_name"].endswith("(NaN: n/a)")


def test_summary_command_formats(ellroll, paper_file):
    """`ellroll summary --format csv|json`: one row per case, the file's
    numbers (round-trip exact), strict JSON with NaN as null."""
    import csv
    import io
    import json
    rows = list(csv.DictReader(io.StringIO(run(ellroll, "summary", paper_file, "--format", "csv").stdout)))
    # the header's `name [units]` by name alone
    rows = [{key.split(" [")[0]: value for key, value in row.items()} for row in rows]
    text = run(ellroll, "summary", paper_file, "--format", "json").stdout
    data = json.loads(text, parse_constant=lambda token: pytest.fail(f"not strict JSON: {token}"))
    with h5py.File(paper_file, "r") as f:
        for name in ("theta_max", "displacement_max", "absolute_acceleration_max", "t_final"):
            assert float(rows[0][name]) == f["summary"][name][0] == data["cases"][0][name]
        assert np.isnan(f["summary/transmissibility"][0]) and data["cases"][0]["transmissibility"] is None
    assert rows[0]["status"] == data["cases"][0]["status"] == "completed"
    assert set(data["units"]) == set(rows[0]) and data["units"]["theta_max"] == "rad"
    bad = run(ellroll, "summary", paper_file, "--format", "xml")
    assert bad.returncode == 2 and "--format needs table, csv or json" in bad.stderr


SWEPT = """&sweep name = 'omega_z', start = 10, stop = 40, count = 2 /
&sweep name = 'radius', values = 0.1, 0.2 /
"""


@pytest.fixture(scope="module")
def swept_file(ellroll, tmp_path_factory):
    folder = tmp_path_factory.mktemp("swept")
    text = PAPER_INPUT.read_text().replace("t_end = 30.0", "t_end = 0.5").replace("interval = 0.01", "interval = 0.1")
    (folder / "swept.nml").write_text(text + SWEPT)
    result = run(ellroll, "run", "swept.nml", "-o", "swept.h5", "-q", cwd=folder)
    assert result.returncode == 0, result.stderr
    return folder / "swept.h5"


def test_varied_inputs_are_coordinates_of_the_cases(swept_file):
    """open_datatree gives time and the swept inputs as coordinates of
    /summary and /trajectory, with the values each case ran with."""
    xr = pytest.importorskip("xarray")
    tree = xr.open_datatree(swept_file, engine="h5netcdf")
    with h5py.File(swept_file, "r") as f:
        spin, radius = f["case/omega"][:, 2], f["case/radius"][:]
    for group in ("summary", "trajectory"):
        ds = tree[group].to_dataset()
        assert {"omega_z", "radius", "case"} <= set(ds.coords) and "time" in tree[group].coords
        np.testing.assert_array_equal(ds["omega_z"].values, spin)
        np.testing.assert_array_equal(ds["radius"].values, radius)
        assert ds["omega_z"].attrs["units"] == "rad/s"
    assert list(spin) == [10, 10, 40, 40] and list(radius) == [0.1, 0.2, 0.1, 0.2]
    theta = tree["summary"].to_dataset()["theta_max"]
    assert theta.sel(case=theta.radius == 0.2).omega_z.values.tolist() == [10, 40]
    assert tree["trajectory"].to_dataset()["nutation"].coords["radius"].dims == ("case",)


def summary_csv(ellroll, path):
    """The CSV summary rows of a file from `ellroll summary` and from `ellroll-plot summary`."""
    import csv
    import io
    fortran = run(ellroll, "summary", path, "--format", "csv").stdout
    python = subprocess.run([sys.executable, "-m", "ellroll_post.cli", "summary", str(path), "--format", "csv"],
                            capture_output=True, text=True).stdout
    return list(csv.reader(io.StringIO(fortran))), list(csv.reader(io.StringIO(python)))


def test_summary_rows_name_the_varied_inputs_alike_in_both_tools(ellroll, swept_file):
    import json
    fortran, python = summary_csv(ellroll, swept_file)
    assert fortran[0] == python[0] and fortran[0][:4] == ["case", "omega_z [rad/s]", "radius [m]", "status"]
    assert "linear_periods_2 [s]" in fortran[0] and len(fortran) == len(python) == 5
    for row_f, row_p in zip(fortran[1:], python[1:]):
        assert [float(v) for v in row_f[4:]] == pytest.approx([float(v) for v in row_p[4:]], rel=0, abs=0,
                                                                nan_ok=True)
        assert row_f[:4] == [row_p[0], *[str(float(v)).removesuffix(".0") for v in row_p[1:3]], row_p[3]]
    data = json.loads(run(ellroll, "summary", swept_file, "--format", "json").stdout)
    assert data["units"]["omega_z"] == "rad/s" and data["units"]["radius"] == "m"
    assert [c["omega_z"] for c in data["cases"]] == [10, 10, 40, 40]


# pieces of file names: (bytes, what a JSON reader must read back); invalid
# UTF-8 gives U+FFFD for each of its bytes
NAME_PIECES = [(b"a", "a"), (b"Z9", "Z9"), (b'"', '"'), (b"\\", "\\"), (b"\t", "\t"), (b"\x01", "\x01"),
               (b"\x1f", "\x1f"), (b"\x7f", "\x7f"), ("\u00e9".encode(), "\u00e9"), ("\u20ac".encode(), "\u20ac"),
               ("\U0001f600".encode(), "\U0001f600"), (b"\xff", "\ufffd"), (b"\xc0\xaf", "\ufffd" * 2),
               (b"\xed\xa0\x80", "\ufffd" * 3), (b"\xe2\x82", "\ufffd" * 2), (b"\xf4\x90\x80\x80", "\ufffd" * 4),
               (b"\x80", "\ufffd")]


def test_summary_json_of_any_file_name_is_valid_utf8_json(ellroll, swept_file, tmp_path):
    """`summary --format json` of files named with quotes, backslashes,
    control characters, UTF-8 of 1 to 4 bytes and bytes that are no UTF-8
    (seeded): the output is strict JSON in UTF-8, its "file" the name with
    each byte of a malformed sequence as U+FFFD."""
    import json
    import random
    rng = random.Random(41)
    for _ in range(12):
        pieces = [rng.choice(NAME_PIECES) for _ in range(rng.randint(1, 6))]
        name = b"".join(p for p, _ in pieces) + b".h5"
        target = bytes(tmp_path) + b"/" + name
        shutil.copyfile(swept_file, target)
        result = subprocess.run([str(ellroll), "summary", name, "--format", "json"], cwd=tmp_path,
                                capture_output=True)
        assert result.returncode == 0, (name, result.stderr)
        data = json.loads(result.stdout.decode("utf-8"), parse_constant=lambda token: pytest.fail(token))
        assert data["file"] == "".join(text for _, text in pieces) + ".h5", name
        assert len(data["cases"]) == 4


def test_summary_of_a_file_without_coordinates_or_a_figure(ellroll, swept_file, tmp_path):
    """A file another version wrote, without the coordinate datasets and
    without a summary figure, still gives its summary rows in both tools."""
    older = tmp_path / "older.h5"
    shutil.copy(swept_file, older)
    with h5py.File(older, "r+") as f:
        for group in ("summary", "trajectory"):
            for name in ("omega_z", "radius"):
                del f[f"{group}/{name}"]
            for item in f[group].values():
                if "coordinates" in item.attrs:
                    del item.attrs["coordinates"]
        del f["summary/horizontal_force_max"]
    fortran, python = summary_csv(ellroll, older)
    assert len(fortran) == len(python) == 5
    assert fortran[0][:2] == ["case", "status"] and "horizontal_force_max" not in fortran[0]
    assert python[0][:4] == ["case", "radius [m]", "omega_z [rad/s]", "status"] and "horizontal_force_max" not in python[0]


def test_ncdump_reads_the_file(swept_file):
    """The netCDF library reads the file as netCDF-4 (every group, the
    coordinates attribute, text attributes as strings)."""
    ncdump = shutil.which("ncdump")
    if ncdump is None:
        pytest.skip("ncdump (Debian netcdf-bin) is not installed; tests/run_all.sh installs it")
    result = subprocess.run([ncdump, "-h", str(swept_file)], capture_output=True, text=True)
    assert result.returncode == 0, result.stderr
    for line in ("double theta_max(case) ;", 'theta_max:coordinates = "omega_z radius" ;',
                 "double nutation(case, time) ;", 'string :Conventions = "CF-1.10" ;', "group: trajectory {"):
        assert line in result.stdout, line


def test_each_command_has_its_help(ellroll):
    for command, words in [("run", "--resume"), ("check", "writes nothing"), ("merge", "--shard I/N"),
                           ("summary", "table|csv|json"), ("modes", "small-oscillation"),
                           ("methods", "order"), ("inputs", "Markdown")]:
        result = run(ellroll, command, "--help")
        assert result.returncode == 0 and result.stdout.startswith(f"usage: ellroll {command}"), command
        assert words in result.stdout, command


def test_bash_completion_beside_the_binary(ellroll, tmp_path):
    """The script in the build folder completes commands, options and values."""
    script = pathlib.Path(ellroll).parent / "ellroll-completion.bash"
    (tmp_path / "case.nml").write_text("")
    (tmp_path / "out.h5").write_text("")

    def complete(*words):
        line = " ".join(f"'{w}'" for w in words)
        shell = (f"source '{script}'; COMP_WORDS=(ellroll {line}); COMP_CWORD={len(words)}; _ellroll; "
                 'printf "%s\\n" "${COMPREPLY[@]}"')
        result = subprocess.run(["bash", "-c", shell], cwd=tmp_path, capture_output=True, text=True)
        assert result.returncode == 0, result.stderr
        return sorted(result.stdout.split())
    assert complete("su") == ["summary"]
    assert complete("summary", "out.h5", "--format", "") == ["csv", "json", "table"]
    assert "--resume" in complete("run", "--") and complete("run", "ca") == ["case.nml"]
    assert complete("merge", "o") == ["out.h5"]


def test_undefined_values_are_nan_and_marked_missing(ellroll, tmp_path):
    """A case never run and the samples after an early end are NaN (a count
    of /summary -1), and CF's _FillValue (NaN, -1; of the dataset's type)
    marks them missing for netCDF readers: xarray gives NaN for them with
    each of its engines, and summary_frame <NA> for the counts."""
    import xarray as xr
    (tmp_path / "c.nml").write_text(
        "&geometry a = 1.0, b = 0.4, c = 0.2 /\n&ball radius = 0.2, weight = 2620.0 /\n"
        "&initial x = 0.0, y = 0.0, omega = -2.0, 2.0, 20.0 /\n&integration dt = 1.0e-3, t_end = 0.2 /\n"
        "&output file = 'out.h5', interval = 0.01 /\n&campaign invalid = 'skip' /\n"
        "&sweep name = 'x', values = 0.0, 1.5 /\n")
    assert run(ellroll, "run", "c.nml", "-q", cwd=tmp_path).returncode == 0
    with h5py.File(tmp_path / "out.h5") as f:
        for group in ("summary", "trajectory", "case"):
            for name, dataset in f[group].items():
                if dataset.dtype.kind == "f":
                    assert "_FillValue" in dataset.attrs and np.isnan(dataset.attrs["_FillValue"]), name
                    assert dataset.attrs["_FillValue"].dtype == dataset.dtype, name
        assert np.isnan(f["summary/theta_max"][1]) and np.all(np.isnan(f["trajectory/contact"][1]))
        counts = [name for name, dataset in f["summary"].items() if dataset.dtype.kind == "i"
                  and name not in ("case", "status", "checksum")]
        assert {"n_steps", "slip_episodes", "at_rest", "peaks_truncated"} <= set(counts)
        for name in counts:
            dataset = f[f"summary/{name}"]
            # (no reference run: n_rhs_reference is undefined for the case run too)
            assert dataset[1] == -1 and (dataset[0] >= 0) != (name == "n_rhs_reference"), name
            assert dataset.attrs["_FillValue"].dtype == dataset.dtype and list(dataset.attrs["_FillValue"]) == [-1]
            assert dataset.fillvalue == -1, name
        steps = f["summary/n_steps"][0]
    for engine in (None, "h5netcdf", "netcdf4"):
        tree = xr.open_datatree(tmp_path / "out.h5", engine=engine)
        summary = tree["summary"]
        assert np.isnan(summary["theta_max"].values[1]) and np.isfinite(summary["theta_max"].values[0]), engine
        for name in counts:
            assert np.isnan(summary[name].values[1]), (engine, name)
            assert (summary[name].values[0] >= 0) != (name == "n_rhs_reference"), (engine, name)
        assert summary["n_steps"].values[0] == steps
        assert list(summary["status"].values) == [1, 8]      # no fill value: never masked
        tree.close()
    frame = ellroll_post.summary_frame(tmp_path / "out.h5")
    for name in counts:
        assert frame[name].isna().tolist() == [name == "n_rhs_reference", True], name
    assert frame["n_steps"].iloc[0] == steps and frame["theta_max"].isna().tolist() == [False, True]


def test_case_datasets_name_their_inputs(ellroll, paper_file):
    """Every input of the parameter table (`ellroll inputs`) is named once by
    the `input_names` attribute of the /case dataset that holds it (a
    vector's one name per component), which the reader takes them from."""
    table = run(ellroll, "inputs").stdout.splitlines()[2:]
    names = [line.split("|")[1].strip().strip("`") for line in table]
    with h5py.File(paper_file, "r") as f:
        named = [(name, dataset) for dataset, values in f["case"].items()
                 for name in values.attrs.get("input_names", "").split()]
        assert sorted(n for n, _ in named) == sorted(names)
        assert f["case/omega"].attrs["input_names"] == "omega_x omega_y omega_z"
        assert dict(named)["excitation_amplitude_y"] == "excitation_amplitude"
        assert "input_names" not in f["case/t_end"].attrs
    with ellroll_post.open(paper_file) as runfile:
        assert list(runfile.inputs) == [n for n, _ in named]
        assert runfile.inputs["omega_z"] == ("omega", 2) and runfile.input_units("omega_z") == "rad/s"
