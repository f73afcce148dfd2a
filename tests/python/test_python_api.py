"""The Python API (post/ellroll over libellroll): a run in memory gives the
file's datasets bit for bit, with its names, units and statuses; a dict
gives what its namelist text gives; bad input raises with the program's
message; runs in threads at once, and on any thread count, agree."""
import concurrent.futures
import ctypes
import errno
import fractions
import gc
import os
import pathlib
import re
import subprocess
import sys
import tempfile
import threading
import time
import warnings

import h5py
import numpy as np
import pytest

from conftest import ROOT, PAPER_INPUT, SANITIZED, run

sys.path.insert(0, str(ROOT / "post"))
import ellroll  # noqa: E402  (the checkout's package, whatever .venv holds)

# every shipped input that runs in a second or two (long_run takes ten)
INPUTS = sorted(p.relative_to(ROOT) for p in [*ROOT.glob("input/*.nml"), *ROOT.glob("input/hard/*.nml")]
                if p.name != "long_run.nml")
PAPER = {
    "geometry": {"a": 1.0, "b": 0.4, "c": 0.2},
    "ball": {"radius": 0.2, "weight": 2620.0},
    "environment": {"g": 9.81},
    "initial": {"x": 0.0, "y": 0.0, "omega": [-2.0, 2.0, 20.0]},
    "integration": {"method": "rk4", "dt": 1.0e-3, "t_end": 30.0},
    "output": {"file": "legeza1990.h5", "interval": 0.01},
}


@pytest.fixture(scope="module", autouse=True)
def library():
    path = pathlib.Path(os.environ.get("ELLROLL_LIB", ROOT / "build" / "libellroll.so"))
    if not path.exists():
        pytest.skip(f"{path} not built")


@pytest.fixture(scope="session")
def program(ellroll):
    """The program (conftest's `ellroll` fixture; here `ellroll` is the package)."""
    return ellroll


def same_bits(a, b):
    a, b = np.asarray(a), np.asarray(b)
    if a.dtype.kind == "f":
        return a.shape == b.shape and b.dtype.kind == "f" and np.array_equal(a.view(np.int64), b.view(np.int64))
    return a.shape == b.shape and np.array_equal(a, b)


def text(value):
    return value.decode() if isinstance(value, bytes) else value


def file_values(dataset):
    if h5py.check_string_dtype(dataset.dtype) is not None:
        return np.asarray(dataset.asstr()[()], dtype=str)
    values = dataset[()]
    if dataset.dtype.kind == "S":
        return np.char.decode(values, "utf-8")
    return values


def assert_tree_is_file(tree, path):
    """Every dataset of the file's root, /case, /summary and /trajectory is
    in the tree with the same bits, units and long name (wall_time aside),
    and the tree has nothing the file lacks."""
    with h5py.File(path, "r") as f:
        assert sorted(tree.children) == sorted(name for name, item in f.items() if isinstance(item, h5py.Group))
        for group in ("", *tree.children):
            node = tree[group] if group else tree
            ds = node.to_dataset(inherit=False)
            # /trajectory/time: the file's own copy of the root's time scale,
            # which a DataTree holds once, at the root, inherited by the group
            inherited = node.to_dataset()
            held = f[group] if group else f
            # (/trajectory_label: the file's own address book for a resume)
            names = [n for n, item in held.items() if isinstance(item, h5py.Dataset) and n != "trajectory_label"]
            own = [n for n in names if not (group and n in inherited.coords and n not in ds.variables)]
            assert sorted(own) == sorted(ds.variables), (group, names, list(ds.variables))
            for name in names:
                stored, memory = held[name], inherited[name]
                assert memory.attrs["units"] == text(stored.attrs["units"]), (group, name)
                assert memory.attrs["long_name"] == text(stored.attrs["long_name"]), (group, name)
                for attribute in ("flag_values", "flag_meanings", "input_names", "_FillValue", "figure", "capacity",
                                  "capacity_units"):
                    # (a real dataset's NaN _FillValue is the file's alone: NaN is missing in memory)
                    if attribute in stored.attrs and (attribute != "_FillValue" or stored.dtype.kind == "i"):
                        expected = text(stored.attrs[attribute])
                        assert same_bits(memory.attrs[attribute], expected), (group, name, attribute)
                        if attribute in ("flag_values", "_FillValue"):
                            assert memory.attrs[attribute].dtype == expected.dtype
                if name == "wall_time":
                    assert memory.shape == stored.shape and memory.dtype == stored.dtype
                    continue
                # (a dimension scale is its own dimension)
                dims = (name,) if stored.is_scale else \
                    tuple(h5py.h5ds.get_scale_name(d[0].id).decode() if len(d) else "" for d in stored.dims)
                assert memory.dims == dims, (group, name, memory.dims, dims)
                assert same_bits(memory.values, file_values(stored)), (group, name)
                assert memory.dtype.kind == file_values(stored).dtype.kind, (group, name)


@pytest.mark.parametrize("relative", INPUTS, ids=str)
def test_a_run_in_memory_is_the_file_bit_for_bit(program, tmp_path, relative, monkeypatch):
    result = run(program, "run", relative, "-o", tmp_path / "out.h5", "-q", cwd=ROOT)
    assert result.returncode == 0, result.stderr
    monkeypatch.chdir(ROOT)              # records are relative to the input's folder, named from here
    tree = ellroll.run((ROOT / relative).read_text(), path=str(relative))
    assert_tree_is_file(tree, tmp_path / "out.h5")


def test_a_sweep_with_skipped_invalid_cases_is_the_file(program, tmp_path):
    """Invalid cases skipped: status 'invalid', NaN trajectories, as the file has them."""
    text = PAPER_INPUT.read_text().replace("t_end = 30.0", "t_end = 3.0")
    text += "&campaign invalid = 'skip' /\n&sweep name = 'radius', values = 0.2, 0.9, 0.5, 1.5 /\n"
    (tmp_path / "skip.nml").write_text(text)
    result = run(program, "run", "skip.nml", "-o", "skip.h5", "-q", cwd=tmp_path)
    assert result.returncode == 0, result.stderr
    tree = ellroll.run(text, threads=2)
    assert_tree_is_file(tree, tmp_path / "skip.h5")
    status = tree["summary"]["status"]
    meanings = status.attrs["flag_meanings"].split()
    assert [meanings[s] for s in status.values] == ["completed", "invalid", "no_fit", "invalid"]
    # an invalid case's counts: -1, the _FillValue, as in the file
    for name in ("n_steps", "slip_episodes", "at_rest", "peaks_truncated"):
        assert list(tree["summary"][name].values[[1, 3]]) == [-1, -1] and tree["summary"][name].values[0] >= 0
        assert list(tree["summary"][name].attrs["_FillValue"]) == [-1]
    arrays, attributes = ellroll.run_arrays(text, threads=2)
    assert list(arrays["summary"]["n_steps"][[1, 3]]) == [-1, -1]
    assert list(attributes["summary"]["n_steps"]["_FillValue"]) == [-1]
    assert np.all(np.isnan(tree["trajectory"]["nutation"].values[1]))
    assert list(tree["summary"]["radius"].values) == [0.2, 0.9, 0.5, 1.5]   # the sweep: a coordinate
    assert "radius" in tree["summary"].coords


def test_a_batched_campaign_is_the_file(program, tmp_path):
    """A sweep of more cases than SIMD lanes runs in batches, in memory as in the file."""
    text = PAPER_INPUT.read_text().replace("t_end = 30.0", "t_end = 2.0")
    text += "&sweep name = 'omega_z', start = 5, stop = 40, count = 19 /\n"
    (tmp_path / "batch.nml").write_text(text)
    result = run(program, "run", "batch.nml", "-o", "batch.h5", "-q", "--threads", "2", cwd=tmp_path)
    assert result.returncode == 0, result.stderr
    assert_tree_is_file(ellroll.run(text, threads=2), tmp_path / "batch.h5")


def test_the_tree_reads_as_the_file_does():
    tree = ellroll.run(PAPER)
    trajectory = tree["trajectory"].to_dataset()
    # time is a coordinate of the trajectories (inherited from the root)
    assert trajectory["nutation"].sel(time=5.0).shape == (1,)
    assert float(trajectory["time"][500]) == 500 * 0.01
    assert trajectory["contact"].dims == ("case", "time", "xyz")
    assert list(trajectory["xyz"].values) == ["x", "y", "z"]
    summary = tree["summary"]
    assert summary["status"].dtype == np.int64
    assert summary["theta_max"].attrs["units"] == "rad"
    assert summary["linear_periods"].dims == ("case", "mode")
    assert tree["case"]["method"].values[0] == "rk4"
    assert tree.attrs["Conventions"] == "CF-1.10"
    assert "&geometry" in tree.attrs["input_namelist"]


def test_a_dict_gives_what_its_text_gives():
    from_text = ellroll.run(PAPER_INPUT.read_text())
    from_dict = ellroll.run(PAPER)
    for group in ("case", "summary", "trajectory"):
        for name, variable in from_text[group].to_dataset().variables.items():
            if name != "wall_time":
                assert same_bits(variable.values, from_dict[group][name].values), (group, name)
    assert ellroll.namelist(PAPER).splitlines()[:3] == ["&geometry", "  a = 1.0", "  b = 0.4"]


def test_namelist_literals():
    text = ellroll.namelist({"output": {"interval": np.float64(0.1), "fields": ["contact", "it's"],
                                        "compression": np.int32(3)},
                             "integration": {"error_estimate": True, "t_end": 1e-3},
                             "sweep": [{"name": "a", "values": np.array([1.0, 2.5])}, {"name": "b", "count": 2}]})
    assert text == ("&output\n  interval = 0.1\n  fields = 'contact', 'it''s'\n  compression = 3\n/\n"
                    "&integration\n  error_estimate = .true.\n  t_end = 0.001\n/\n"
                    "&sweep\n  name = 'a'\n  values = 1.0, 2.5\n/\n&sweep\n  name = 'b'\n  count = 2\n/\n")
    with pytest.raises(ellroll.InputError, match="&geometry: a"):
        ellroll.namelist({"geometry": {"a": None}})


@pytest.mark.parametrize("old,new", [("b = 0.4", "b = -0.4"), ("radius = 0.2", "radus = 0.2"),
                                     ("dt = 1.0e-3", "dt = 'fast'"), ("&ball", "&bal"),
                                     ("&output      file = 'legeza1990.h5', interval = 0.01 /", "")])
def test_a_bad_input_raises_the_programs_message(program, tmp_path, old, new):
    text = PAPER_INPUT.read_text().replace(old, new)
    (tmp_path / "case.nml").write_text(text)
    result = run(program, "run", "case.nml", "-o", "new.h5", cwd=tmp_path)
    assert result.returncode == 2
    with pytest.raises(ellroll.InputError) as raised:
        ellroll.run(text, path="case.nml")
    assert raised.value.code == 2
    assert f"ellroll: error: {raised.value.message}\n" == result.stderr
    assert isinstance(raised.value, ellroll.Error) and isinstance(raised.value, ValueError)


def test_texts_of_megabytes_run_or_raise_on_the_run_thread():
    """The run's thread has the platform's default stack (8 MiB): a 20 MB
    comment runs, and a 12 MB sweep (600,000 values; 10,000 allowed)
    raises InputError with a short message, as the CLI does."""
    text = PAPER_INPUT.read_text().replace("t_end = 30.0", "t_end = 0.1")
    arrays, attributes = ellroll.run_arrays("! " + "x" * 20_000_000 + "\n" + text)
    assert attributes["summary"]["status"]["flag_meanings"].split()[arrays["summary"]["status"][0]] == "completed"
    values = ", ".join(repr(1 + k * 1e-6) for k in range(600_000))
    with pytest.raises(ellroll.InputError) as raised:
        ellroll.run_arrays(text + f"&sweep name = 'radius', values = {values} /\n")
    assert len(raised.value.message) < 400
    assert "characters): 600000 values given; values holds 10000" in raised.value.message


def test_invalid_cases_that_stop_raise_the_programs_message(program, tmp_path):
    text = PAPER_INPUT.read_text() + "&sweep name = 'radius', values = 0.2, 0.9 /\n"
    (tmp_path / "case.nml").write_text(text)
    result = run(program, "run", "case.nml", cwd=tmp_path)
    with pytest.raises(ellroll.InputError) as raised:
        ellroll.run(text, path="case.nml")
    assert "1 of 2 cases are invalid" in raised.value.message
    assert f"ellroll: error: {raised.value.message}\n" == result.stderr


def test_threads_give_the_same_bits():
    text = PAPER_INPUT.read_text().replace("t_end = 30.0", "t_end = 3.0")
    text += "&sweep name = 'omega_z', values = 5, 10, 15, 20, 30 /\n&sweep name = 'c', values = 0.2, 0.25 /\n"
    one, two = ellroll.run(text, threads=1), ellroll.run(text, threads=2)
    for group in ("case", "summary", "trajectory"):
        for name, variable in one[group].to_dataset().variables.items():
            if name != "wall_time":
                assert same_bits(variable.values, two[group][name].values), (group, name)
    with pytest.raises(ValueError):
        ellroll.run(text, threads=0)


def test_runs_in_threads_at_once_are_each_right():
    """Runs in two Python threads at the same time each get their own input's results."""
    texts = [PAPER_INPUT.read_text().replace("omega = -2.0, 2.0, 20.0", f"omega = -2.0, 2.0, {w}")
             .replace("t_end = 30.0", "t_end = 10.0") for w in (10.0, 20.0, 30.0, 40.0)]
    alone = [float(ellroll.run(t, threads=1)["summary"]["theta_max"][0]) for t in texts]
    with concurrent.futures.ThreadPoolExecutor(max_workers=2) as pool:
        together = list(pool.map(lambda text: float(ellroll.run(text, threads=1)["summary"]["theta_max"][0]),
                                 texts * 2))
    assert together == alone * 2
    assert len(set(alone)) == len(alone)


def test_the_gil_is_released_while_the_cases_run():
    """ctypes releases the GIL for every call into the library: while one
    thread is in a run, this thread keeps running Python. (Were the GIL
    held, this loop would stop for the whole run.)"""
    text = PAPER_INPUT.read_text().replace("t_end = 30.0", "t_end = 600.0").replace("interval = 0.01", "interval = 1.0")
    lib = ellroll._lib()
    encoded = text.encode()
    handles, span = [], []

    def call():
        span.append(time.monotonic())
        handles.append(lib.ellroll_run(encoded, len(encoded), b"<input>", 7, 1))
        span.append(time.monotonic())

    worker = threading.Thread(target=call)
    ticks = []
    worker.start()
    while worker.is_alive():
        ticks.append(time.monotonic())
    worker.join()
    lib.ellroll_free(handles[0])
    inside = [t for t in ticks if span[0] <= t <= span[1]]
    duration = span[1] - span[0]
    assert duration > 0.05, duration               # long enough to tell
    gaps = np.diff([span[0], *inside, span[1]])
    assert gaps.max() < duration / 2, (gaps.max(), duration)


def test_run_arrays_are_the_trees_values():
    """run_arrays: the same values, dimensions and units as run's DataTree, without xarray."""
    text = PAPER_INPUT.read_text().replace("t_end = 30.0", "t_end = 2.0")
    tree = ellroll.run(text, threads=1)
    arrays, attributes = ellroll.run_arrays(text, threads=1)
    assert set(arrays) == {"", "case", "summary", "trajectory"}
    for group, values in arrays.items():
        node = tree[group] if group else tree
        for name, array in values.items():
            if name == "wall_time":
                continue
            assert same_bits(array, node[name].values), (group, name)
            assert attributes[group][name]["dims"] == node[name].dims, (group, name)
            assert attributes[group][name]["units"] == node[name].attrs["units"], (group, name)


def plain_tree(groups, root_attrs):
    """The DataTree as xarray's plain constructors make it: a Dataset(data_vars, coords) per
    group (its scales and its `coordinates` as coordinates), joined by DataTree.from_dict."""
    import xarray as xr
    datasets = {}
    for group in ("", "case", "summary", "trajectory", *(g for g in ("limit_state", "switches") if g in groups)):
        variables = groups.get(group, [])
        coordinates = {name for name, dims, _, _ in variables if dims == (name,)}
        for _, _, _, attrs in variables:
            coordinates.update(attrs.get("coordinates", "").split())
        made = {name: xr.Variable(dims, values, {k: v for k, v in attrs.items() if k != "coordinates"})
                for name, dims, values, attrs in variables}
        datasets["/" + group] = xr.Dataset({n: v for n, v in made.items() if n not in coordinates},
                                           {n: v for n, v in made.items() if n in coordinates})
    datasets["/"].attrs.update(root_attrs)
    return xr.DataTree.from_dict(datasets)


@pytest.mark.parametrize("relative", ["input/legeza1990.nml", "input/spin_sweep.nml", "input/isolator_suite.nml",
                                      "input/hard/slip.nml", "input/isolator_slide.nml"])
def test_the_tree_is_what_xarrays_plain_constructors_make(relative, monkeypatch):
    """run()'s DataTree, made without xarray's merges, is identical() to the one
    Dataset(data_vars, coords) and DataTree.from_dict make of the same run's datasets:
    values, attributes, coordinates, indexes, and the order of variables and dimensions."""
    xr = pytest.importorskip("xarray")
    if not hasattr(xr, "DataTree"):
        pytest.skip("xarray without DataTree")
    monkeypatch.chdir(ROOT)              # records are relative to the input's folder, named from here
    lib, encoded, label = ellroll._lib(), (ROOT / relative).read_text().encode(), relative.encode()
    handle = lib.ellroll_run(encoded, len(encoded), label, len(label), 2)
    try:
        assert lib.ellroll_error_code(handle) == 0
        groups, root_attrs = ellroll._datasets(lib, handle)
    finally:
        lib.ellroll_free(handle)
    expected = plain_tree(groups, root_attrs)
    tree = ellroll._tree({g: [(n, d, v, dict(a)) for n, d, v, a in vs] for g, vs in groups.items()}, root_attrs)
    assert tree.identical(expected)
    assert repr(tree) == repr(expected)
    for node, other in zip(tree.subtree, expected.subtree, strict=True):
        assert node.path == other.path
        assert list(node.variables) == list(other.variables), node.path
        assert list(node.dims) == list(other.dims), node.path
        assert list(node.xindexes) == list(other.xindexes), node.path
        assert all(type(node.variables[n]) is type(other.variables[n]) for n in node.variables), node.path
    assert "case" in tree["summary"].xindexes and list(tree.xindexes) == ["time", "xyz", "mode"]


def run_groups(text):
    """A run's datasets as run() reads them (ellroll._datasets), and its root attributes."""
    lib, encoded = ellroll._lib(), text.encode()
    handle = lib.ellroll_run(encoded, len(encoded), b"<input>", 7, 1)
    try:
        assert lib.ellroll_error_code(handle) == 0
        return ellroll._datasets(lib, handle)
    finally:
        lib.ellroll_free(handle)


def assert_same_attributes(a, b, where):
    """The same attribute names in the same order, each of the same type (and dtype) and value."""
    assert list(a) == list(b), where
    for key, value in a.items():
        assert type(value) is type(b[key]), (where, key)
        if isinstance(value, np.ndarray):
            assert value.dtype == b[key].dtype and same_bits(value, b[key]), (where, key)
        else:
            assert value == b[key], (where, key)


def test_runs_of_one_layout_each_get_their_own_tree():
    """run() makes the nodes of a layout of datasets once and puts each
    call's values into copies of them: runs with the same datasets, shapes
    and attributes but other values (other initial spins; a time scale of
    as many samples at another interval, so other index values) each give
    the tree xarray's plain constructors make of their own datasets, with
    its indexes and the types of its attributes; a tree changed in place
    (values, attributes, a scale's attributes) leaves the next run's as it
    was."""
    xr = pytest.importorskip("xarray")
    if not hasattr(xr, "DataTree"):
        pytest.skip("xarray without DataTree")
    base = PAPER_INPUT.read_text().replace("t_end = 30.0", "t_end = 2.0")
    other = base.replace("omega = -2.0, 2.0, 20.0", "omega = 3.0, -1.0, 15.0")
    stretched = base.replace("t_end = 2.0", "t_end = 4.0").replace("interval = 0.01", "interval = 0.02")
    layouts = set()
    for text in (base, other, stretched, base):
        groups, root_attrs = run_groups(text)
        layouts.add(id(groups.layout))
        expected = plain_tree(groups, root_attrs)
        tree = ellroll._tree(groups, root_attrs)
        assert tree.identical(expected)
        for node, plain in zip(tree.subtree, expected.subtree, strict=True):
            assert list(node.variables) == list(plain.variables), node.path
            assert list(node.xindexes) == list(plain.xindexes), node.path
            for name, variable in node.variables.items():
                assert variable.dtype == plain.variables[name].dtype, (node.path, name)
                assert same_bits(variable.values, plain.variables[name].values), (node.path, name)
                assert_same_attributes(variable.attrs, plain.variables[name].attrs, (node.path, name))
        assert_same_attributes(tree.attrs, expected.attrs, "/")
        end = float(groups[""][0][2][-1])
        last = float(expected["trajectory"]["nutation"][0, -1])
        assert float(tree["trajectory"]["nutation"].sel(time=end)[0]) == last      # (the index of this run's time)
    assert len(layouts) == 1                      # (one layout: each run after the first reuses its nodes)

    arrays, attributes = ellroll.run_arrays(base, threads=1)
    first = ellroll.run(base, threads=1)
    first["summary"]["status"].attrs["flag_values"][:] = -7
    first["summary"]["theta_max"].attrs["units"] = "deg"
    first["summary"]["case"].attrs["long_name"] = "changed"
    first["trajectory"]["nutation"].values[:] = 0.0
    first.attrs["n_cases_total"][:] = 9
    second = ellroll.run(base, threads=1)
    summary = second["summary"]
    assert same_bits(summary["status"].attrs["flag_values"], attributes["summary"]["status"]["flag_values"])
    assert summary["theta_max"].attrs["units"] == "rad"
    assert summary["case"].attrs["long_name"] == attributes["summary"]["case"]["long_name"]
    assert same_bits(second["trajectory"]["nutation"].values, arrays["trajectory"]["nutation"])
    assert list(second.attrs["n_cases_total"]) == [1]


def test_a_record_given_as_arrays_runs_as_its_csv(program, tmp_path):
    """ellroll.Record: arrays in a dict input give the results of the same
    record read from its CSV file by `ellroll run`, bit for bit; a single
    record and a suite of two; the private files are gone after the run."""
    rng = np.random.default_rng(7)
    time = np.arange(0, 4.0, 0.01)
    accelerations = [rng.normal(0, 0.3, (time.size, 3)), rng.normal(0, 0.5, (time.size, 2))]
    records = [ellroll.Record(time, a, name=f"r{k}") for k, a in enumerate(accelerations)]
    for k, record in enumerate(records):
        (tmp_path / f"r{k}.csv").write_text(record.csv_text())
    base = {"geometry": {"a": 1.0, "b": 0.4, "c": 0.2}, "ball": {"radius": 0.2, "weight": 2620.0},
            "initial": {"x": 0.0, "y": 0.0, "omega": [0.0, 0.0, 0.0]},
            "integration": {"method": "rk4", "dt": 1e-3, "t_end": 5.0}, "output": {"file": "out.h5", "interval": 0.01}}
    single = dict(base, excitation={"kind": "record", "record_file": records[0]})
    suite = dict(base, excitation={"kind": "record"},
                 record=[{"name": f"r{k}", "record_file": r, "factor": 1.0 + k} for k, r in enumerate(records)])
    for inputs in (single, suite):
        by_name = _with_names(inputs, {id(r): f"r{k}.csv" for k, r in enumerate(records)})
        (tmp_path / "in.nml").write_text(ellroll.namelist(by_name))
        result = run(program, "run", "in.nml", "-o", "out.h5", "-q", "--overwrite", cwd=tmp_path)
        assert result.returncode == 0, result.stderr
        before = set(pathlib.Path(tempfile.gettempdir()).glob("ellroll-records-*"))
        tree = ellroll.run(inputs, threads=1)
        assert set(pathlib.Path(tempfile.gettempdir()).glob("ellroll-records-*")) <= before
        with h5py.File(tmp_path / "out.h5", "r") as f:
            assert f["summary/status"][0] == 1 and f["summary/displacement_max"][0] > 0
            for group in ("summary", "trajectory"):
                for name, stored in f[group].items():
                    if name in ("wall_time", "record") or not isinstance(stored, h5py.Dataset):
                        continue
                    assert same_bits(tree[group][name].values, file_values(stored)), (group, name)
    with pytest.raises(ellroll.InputError, match="2 or 3"):
        ellroll.Record(time, accelerations[0][:, :1])
    # a record the program refuses: named once, as the Record
    with pytest.raises(ellroll.InputError, match="fewer than two samples") as refused:
        ellroll.run(dict(base, excitation={"kind": "record", "record_file": ellroll.Record([], np.zeros((0, 2)))}))
    assert str(refused.value).count("Record 'record'") == 1, str(refused.value)


@pytest.mark.parametrize("fault", ["folder", "write"])
def test_a_record_file_that_cannot_be_written_raises_ellroll_error(monkeypatch, fault):
    """A private folder that cannot be made, or a Record's file that cannot
    be written (a full disk), is an ellroll.Error naming the place and the
    system's reason (code 3), as any failure that is not the input's."""
    record = ellroll.Record(np.arange(0, 1.0, 0.1), np.zeros((10, 2)))
    inputs = {"geometry": {"a": 1.0, "b": 0.4, "c": 0.2}, "ball": {"radius": 0.2, "weight": 2620.0},
              "initial": {"x": 0.0, "y": 0.0, "omega": [0.0, 0.0, 0.0]},
              "integration": {"method": "rk4", "dt": 1e-3, "t_end": 0.1},
              "excitation": {"kind": "record", "record_file": record}}
    if fault == "folder":
        monkeypatch.setattr(tempfile, "tempdir", "/nonexistent/ellroll-test")
        words = "cannot make a private folder for the Records' files in /nonexistent/ellroll-test"
    else:
        def full(self, path):
            raise OSError(errno.ENOSPC, os.strerror(errno.ENOSPC), str(path))
        monkeypatch.setattr(ellroll.Record, "write_csv", full)
        words = "cannot write a Record's file: No space left on device"
    with pytest.raises(ellroll.Error, match=re.escape(words)) as failed:
        ellroll.run(inputs, threads=1)
    assert failed.value.code == 3 and not isinstance(failed.value, ellroll.InputError)


@pytest.mark.parametrize("rows", [40, 400])
def test_a_record_beyond_what_a_record_file_may_hold_is_refused_as_it_is_written(monkeypatch, tmp_path, rows):
    """A Record whose CSV text passes the record files' limit (1 GiB, here
    made 1000 bytes) is an InputError naming it, raised once the text passes
    the limit (40 rows of about 50 bytes: after the first piece), or before
    any is written where its rows could not fit even at their shortest (400
    rows of at least 14 bytes); the private folder is gone after it."""
    monkeypatch.setattr(ellroll, "RECORD_FILE_LIMIT", 1000)
    record = ellroll.Record(np.arange(rows) * 0.0123456789, np.full((rows, 2), 0.987654321), name="long")
    monkeypatch.setattr(tempfile, "tempdir", str(tmp_path))
    inputs = {"geometry": {"a": 1.0, "b": 0.4, "c": 0.2}, "ball": {"radius": 0.2, "weight": 2620.0},
              "initial": {"x": 0.0, "y": 0.0, "omega": [0.0, 0.0, 0.0]},
              "integration": {"method": "rk4", "dt": 1e-3, "t_end": 0.1},
              "excitation": {"kind": "record", "record_file": record}}
    words = "its CSV text passes 1000 bytes" if rows == 40 else f"{rows} rows of 3 numbers take at least 5600 bytes"
    with pytest.raises(ellroll.InputError, match=re.escape(f"Record 'long': {words}")):
        ellroll.run(inputs, threads=1)
    assert list(tmp_path.iterdir()) == []
    assert len(record.csv_text()) > 1000


def _with_names(groups, names):
    """groups with each Record replaced by its file name in names."""
    def value(v):
        return names[id(v)] if isinstance(v, ellroll.Record) else v

    def members(group):
        return {k: value(v) for k, v in group.items()}
    return {g: ([members(x) for x in c] if isinstance(c, list) else members(c)) for g, c in groups.items()}


# A case whose trajectories (1001 samples of 3 components, 24 kB each) the
# package reads in place, where the library holds them, rather than copying.
VIEWED = PAPER_INPUT.read_text().replace("t_end = 30.0", "t_end = 1.0").replace("interval = 0.01", "interval = 0.001")


def resident_bytes():
    return int(pathlib.Path("/proc/self/statm").read_text().split()[1]) * os.sysconf("SC_PAGE_SIZE")


def read_one(text, group, name):
    """Dataset group/name of a run of text, copied out of the library alone (ellroll_dataset_read)."""
    lib, encoded = ellroll._lib(), text.encode()
    handle = lib.ellroll_run(encoded, len(encoded), b"<input>", 7, 1)
    try:
        for i in range(lib.ellroll_dataset_count(handle)):
            if (ellroll._text(lib.ellroll_dataset_text, handle, i, 0),
                    ellroll._text(lib.ellroll_dataset_text, handle, i, 1)) == (group, name):
                kind, itemsize, ndim = ctypes.c_int(), ctypes.c_int(), ctypes.c_int()
                shape = (ctypes.c_int64 * 3)()
                assert lib.ellroll_dataset_info(handle, i, kind, itemsize, ndim, shape) == 0 and kind.value == 1
                values = np.empty(tuple(shape[:ndim.value]))
                assert lib.ellroll_dataset_read(handle, i, values.ctypes.data, values.nbytes) == 0
                return values
    finally:
        lib.ellroll_free(handle)
    raise KeyError((group, name))


def test_one_call_reads_what_a_read_per_dataset_gives():
    """run_arrays (one call for the small datasets, the large ones read in
    place) gives each dataset's values as ellroll_dataset_read copies them
    one by one, texts without their padding."""
    # (the trajectories of one case are read in place; of several, copied)
    for text, in_place in ((VIEWED, True), (VIEWED + "&sweep name = 'omega_z', values = 5, 10, 15 /\n", False)):
        arrays, attributes = ellroll.run_arrays(text, threads=1)
        assert isinstance(arrays["trajectory"]["contact"].base, ellroll._Values) == in_place
        lib, encoded = ellroll._lib(), text.encode()
        handle = lib.ellroll_run(encoded, len(encoded), b"<input>", 7, 1)
        try:
            for i in range(lib.ellroll_dataset_count(handle)):
                group = ellroll._text(lib.ellroll_dataset_text, handle, i, 0)
                name = ellroll._text(lib.ellroll_dataset_text, handle, i, 1)
                kind, itemsize, ndim = ctypes.c_int(), ctypes.c_int(), ctypes.c_int()
                shape = (ctypes.c_int64 * 3)()
                assert lib.ellroll_dataset_info(handle, i, kind, itemsize, ndim, shape) == 0
                dtype = {1: np.float64, 2: np.int64, 3: f"S{itemsize.value}"}[kind.value]
                values = np.empty(tuple(shape[:ndim.value]), dtype=dtype)
                assert lib.ellroll_dataset_read(handle, i, values.ctypes.data, values.nbytes) == 0
                if kind.value == 3:
                    values = np.char.rstrip(values).astype(str)
                if name != "wall_time":
                    assert same_bits(arrays[group][name], values), (group, name)
                assert arrays[group][name].dtype == values.dtype and attributes[group][name]["dims"]
        finally:
            lib.ellroll_free(handle)


def test_arrays_outlive_their_run_and_later_runs():
    """An array read in place stays whole after the rest of its results are
    dropped and the library has run other inputs (which reuse the memory
    freed), in run_arrays' dicts and in run's DataTree."""
    expected, expected_center = (read_one(VIEWED, "trajectory", name) for name in ("contact", "center"))
    arrays, _ = ellroll.run_arrays(VIEWED, threads=1)
    contact = arrays["trajectory"]["contact"]
    assert isinstance(contact.base, ellroll._Values)          # read in place
    tree = ellroll.run(VIEWED, threads=1)
    center = tree["trajectory"]["center"].values
    del arrays, tree
    gc.collect()
    other = VIEWED.replace("omega = -2.0, 2.0, 20.0", "omega = 3.0, -1.0, 15.0")
    for _ in range(20):
        again, _ = ellroll.run_arrays(other, threads=1)
        assert not np.array_equal(again["trajectory"]["contact"], expected)
    del again
    gc.collect()
    assert same_bits(contact, expected) and same_bits(center, expected_center)
    view = contact[:, 10:20]                                # a view of the view keeps it too
    del contact
    gc.collect()
    ellroll.run_arrays(other, threads=1)
    assert same_bits(view, expected[:, 10:20])


def test_memory_stays_bounded_over_many_calls():
    """2000 calls, each dropping its results, keep the resident memory
    within a few MB (a run's handle or its trajectories not freed would add
    some 200 kB per call here: 400 MB); keeping one trajectory of each of
    300 runs keeps that dataset alone (24 kB each), not its run (some
    250 kB with its other trajectories and its handle). (On a library
    built with the address sanitizer, which keeps freed memory aside to
    find its later use, the calls run and the sizes are not judged.)"""
    for _ in range(100):
        ellroll.run_arrays(VIEWED, threads=1)
    gc.collect()
    before = resident_bytes()
    for _ in range(200 if SANITIZED else 2000):
        arrays, attributes = ellroll.run_arrays(VIEWED, threads=1)
        assert arrays["summary"]["status"][0] == 1
    del arrays, attributes
    gc.collect()
    grown = resident_bytes() - before
    kept = [ellroll.run_arrays(VIEWED, threads=1)[0]["trajectory"]["contact"] for _ in range(300)]
    gc.collect()
    held = resident_bytes() - before - grown
    assert all(isinstance(k.base, ellroll._Values) for k in kept)
    if not SANITIZED:
        assert grown < 8e6, grown
        assert held < 300 * 2 * kept[0].nbytes, (held, kept[0].nbytes)


def test_runs_in_threads_read_in_place_are_each_right():
    """Several threads run and drop results at once, arrays made in one
    thread freed in another: each run's arrays equal the same input's
    run alone, bit for bit."""
    texts = [VIEWED.replace("omega = -2.0, 2.0, 20.0", f"omega = -2.0, 2.0, {w}") for w in (10.0, 20.0, 30.0)]
    alone = [ellroll.run_arrays(t, threads=1)[0]["trajectory"] for t in texts]
    handed = []

    def work(k):
        for j in range(12):
            arrays, _ = ellroll.run_arrays(texts[(k + j) % 3], threads=1)
            trajectory = arrays["trajectory"]
            for name, values in alone[(k + j) % 3].items():
                assert same_bits(trajectory[name], values), (k, j, name)
            handed.append(trajectory)                     # dropped by another thread
            if len(handed) > 4:
                handed.pop(0)
        return k

    with concurrent.futures.ThreadPoolExecutor(max_workers=4) as pool:
        assert sorted(pool.map(work, range(4))) == [0, 1, 2, 3]


def test_values_taken_out_of_a_run_outlive_it():
    """The C interface: a dataset's values taken out of its run
    (ellroll_take) stay readable after the run's handle is freed, until
    freed on their own; the dataset then cannot be copied out of the run
    (-1), while its other datasets can; texts are never taken."""
    lib, encoded = ellroll._lib(), VIEWED.encode()
    handle = lib.ellroll_run(encoded, len(encoded), b"<input>", 7, 1)
    n = lib.ellroll_dataset_count(handle)
    names = [(ellroll._text(lib.ellroll_dataset_text, handle, i, 0), ellroll._text(lib.ellroll_dataset_text, handle, i, 1))
             for i in range(n)]
    contact, center, xyz = names.index(("trajectory", "contact")), names.index(("trajectory", "center")), \
        names.index(("", "xyz"))
    expected = np.empty((1, 1001, 3))
    assert lib.ellroll_dataset_read(handle, contact, expected.ctypes.data, expected.nbytes) == 0
    want = (ctypes.c_int * n)()
    want[contact] = want[xyz] = 1
    owners, addresses = (ctypes.c_void_p * n)(), (ctypes.c_void_p * n)()
    assert lib.ellroll_take(handle, n, want, owners, addresses) == 0
    assert owners[contact] and addresses[contact] and not owners[xyz] and not owners[center]
    owner = owners[contact]
    values = np.empty((1, 1001, 3))
    assert lib.ellroll_dataset_read(handle, contact, values.ctypes.data, values.nbytes) == -1
    copies = (ctypes.c_void_p * n)()
    copies[contact] = values.ctypes.data
    assert lib.ellroll_read_all(handle, n, copies) == -1
    assert lib.ellroll_take(handle, n, want, owners, (ctypes.c_void_p * n)()) == 0 and not owners[contact]
    assert lib.ellroll_dataset_read(handle, center, values.ctypes.data, values.nbytes) == 0
    assert np.all(np.isfinite(values)) and not np.array_equal(values, expected)
    lib.ellroll_free(handle)
    taken = np.ctypeslib.as_array((ctypes.c_double * expected.size).from_address(addresses[contact]))
    assert same_bits(taken, expected.ravel())
    del taken
    lib.ellroll_free_values(owner)


INTERRUPTED = """
import sys, threading, time
sys.path.insert(0, sys.argv[1])
import ellroll
SHORT = sys.argv[2]
LONG = SHORT.replace("t_end = 1.0", "t_end = 3000.0").replace("dt = 1.0e-3", "dt = 1.0e-4")
run = ellroll.run_arrays if sys.argv[3] == "run_arrays" else ellroll.run
before = ellroll.run_arrays(SHORT)[0]["summary"]["theta_max"].copy()
print("started", flush=True)
try:
    run(LONG)
    print("finished", flush=True)
except KeyboardInterrupt:
    print(f"interrupted {time.monotonic():.6f}", flush=True)
after = ellroll.run_arrays(SHORT)[0]["summary"]["theta_max"]
print("usable", bool(after.tobytes() == before.tobytes()), flush=True)
"""


@pytest.mark.parametrize("function", ["run_arrays", "run"])
def test_ctrl_c_stops_a_run_promptly_and_leaves_the_library_usable(tmp_path, function):
    """SIGINT during a run of some 30 s (3e7 rk4 steps): KeyboardInterrupt
    within 0.5 s, and the next run gives the same bits as before."""
    import signal
    import subprocess
    short = ("&geometry a = 1.0, b = 0.4, c = 0.2 /\n&ball radius = 0.2, weight = 2620.0 /\n"
             "&initial omega = -2.0, 2.0, 20.0 /\n&integration method = 'rk4', dt = 1.0e-3, t_end = 1.0 /\n"
             "&output interval = 1.0 /\n")
    (tmp_path / "interrupted.py").write_text(INTERRUPTED)
    child = subprocess.Popen([sys.executable, "interrupted.py", str(ROOT / "post"), short, function], cwd=tmp_path,
                             stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
                             env=dict(os.environ, ELLROLL_LIB=str(ellroll.library_path())))
    try:
        assert child.stdout.readline().strip() == "started"
        time.sleep(1.0)
        sent = time.monotonic()
        child.send_signal(signal.SIGINT)
        line = child.stdout.readline().split()
        assert line and line[0] == "interrupted", (line, child.stderr.read() if not line else "")
        delay = float(line[1]) - sent
        assert delay < 0.5, delay
        assert child.stdout.readline().split() == ["usable", "True"]
        assert child.wait(timeout=60) == 0
    finally:
        child.kill()


GOOD_GROUPS = {
    "geometry": {"a": 1.0, "b": 0.4, "c": 0.2}, "ball": {"radius": 0.2, "weight": 2620.0},
    "initial": {"omega": [-2.0, 2.0, 20.0]}, "integration": {"method": "rk4", "dt": 1e-3, "t_end": 0.1},
    "output": {"interval": 0.01},
}


@pytest.mark.parametrize("inputs", [42, 4.2, b"&geometry a = 1.0 /\n", None, ["&geometry"], ("a",), {1, 2}])
def test_an_input_neither_text_nor_dict_is_an_input_error_naming_its_type(inputs):
    for function in (ellroll.run, ellroll.run_arrays, ellroll.namelist):
        with pytest.raises(ellroll.InputError) as raised:
            function(inputs)
        assert type(inputs).__name__ in raised.value.message and raised.value.code == 2


def bad_names(rng):
    """Keys that are not namelist names (seeded): text that would be pasted
    into the namelist as something else, non-ASCII letters, non-str keys."""
    fixed = ["a=2, b", "a b", "ä", "", "1a", "_a", "a,", "a/", "a!", "a'", "a(0)", "a(", "a()", "a(1", "a)",
             "a(-1)", "a(1,2)", " a", "a ", "a\n", "&a", 3, None, 1.5, ("a",)]
    pieces = "= ,/!&'\"()$\t\n-+.*"
    drawn = []
    while len(drawn) < 20:
        name = list("omega")
        name.insert(rng.randrange(len(name) + 1), rng.choice(pieces))
        drawn.append("".join(name))
    return fixed + drawn


def test_dict_group_and_variable_names_must_be_names(tmp_path):
    import random
    rng = random.Random(11)
    for bad in bad_names(rng):
        groups = {g: dict(v) for g, v in GOOD_GROUPS.items()}
        groups["geometry"][bad] = 1.0
        with pytest.raises(ellroll.InputError) as raised:
            ellroll.namelist(groups)
        assert "&geometry: variable name " + repr(bad) in raised.value.message, (bad, raised.value.message)
        groups = {g: dict(v) for g, v in GOOD_GROUPS.items()}
        groups[bad] = {"a": 1.0}
        with pytest.raises(ellroll.InputError) as raised:
            ellroll.run_arrays(groups)
        assert "group name " + repr(bad) in raised.value.message, (bad, raised.value.message)
    # a name and one element of a vector are taken
    groups = {g: dict(v) for g, v in GOOD_GROUPS.items()}
    groups["initial"] = {"omega(1)": -2.0, "omega(2)": 2.0, "omega(3)": 20.0}
    assert ellroll.run_arrays(groups)[0]["summary"]["status"].shape == (1,)


@pytest.mark.parametrize("threads", [0, -1, 2**31, 2**40, 1.0, "2", True, None])
def test_threads_within_the_programs_bounds(threads):
    if threads is None:
        assert ellroll.run_arrays(GOOD_GROUPS, threads=threads)[0]["summary"]["status"].shape == (1,)
        return
    with pytest.raises(ellroll.InputError) as raised:
        ellroll.run_arrays(GOOD_GROUPS, threads=threads)
    assert f"threads = {threads!r}: give a count from 1 to 2147483647" in raised.value.message


def test_text_and_path_the_library_cannot_take_are_input_errors():
    """A text with a lone surrogate (Python's stand-in for a byte that was not
    UTF-8) and a path that is not a file name raise InputError with a message;
    a name read with os.fsdecode is taken."""
    text = ellroll.namelist(GOOD_GROUPS)
    with pytest.raises(ellroll.InputError) as raised:
        ellroll.run_arrays("! a comment \udcff\n" + text)
    assert "line 1: the text holds '\\udcff', a lone surrogate" in raised.value.message and raised.value.code == 2
    for path in (5, 1.5, ["a.nml"], b"a.nml"):
        with pytest.raises(ellroll.InputError) as raised:
            ellroll.run_arrays(text, path=path)
        assert f"path = {path!r} ({type(path).__name__}): give a file name" in raised.value.message
    with tempfile.TemporaryDirectory() as folder:
        named = os.fsdecode(os.path.join(os.fsencode(folder), b"in\xff.nml"))
        assert ellroll.run_arrays(text, path=named)[0]["summary"]["status"].shape == (1,)
        assert ellroll.run_arrays(text, path=pathlib.Path(named))[0]["summary"]["status"].shape == (1,)


def test_a_ragged_nested_list_is_an_input_error():
    """[[0, 0], [1]] is not three values: refused, where rows of one length
    (or a 2-d array) give their values row by row."""
    for ragged in ([[0.0, 0.0], [1.0]], [[0.0], 1.0, 2.0], ([0.0, 0.0], (1.0,))):
        groups = {g: dict(v) for g, v in GOOD_GROUPS.items()}
        groups["initial"] = {"omega": ragged}
        for function in (ellroll.namelist, ellroll.run_arrays):
            with pytest.raises(ellroll.InputError) as raised:
                function(groups)
            assert "ragged nested list" in raised.value.message and "&initial" in raised.value.message
    groups = {g: dict(v) for g, v in GOOD_GROUPS.items()}
    groups["sweep"] = {"name": "omega_z", "values": [[10.0, 20.0], [30.0, 40.0]]}
    assert "values = 10.0, 20.0, 30.0, 40.0" in ellroll.namelist(groups)
    groups["sweep"]["values"] = np.array([[10.0, 20.0], [30.0, 40.0]])
    assert "values = 10.0, 20.0, 30.0, 40.0" in ellroll.namelist(groups)


def test_a_vector_in_a_table_of_one_row_or_column_is_an_input_error():
    """omega as an array of shape (1, 3) (numpy's keepdims, a slice
    [i:i+1]) or (3, 1), or the nested list [[x, y, z]]: a table with a row or
    column of one, refused naming its shape, as a ragged list is, by
    namelist() and run_arrays() alike."""
    for table in (np.array([[1.0, 2.0, 3.0]]), np.array([[1.0], [2.0], [3.0]]), [[1.0, 2.0, 3.0]],
                  np.zeros((1, 1, 3))):
        groups = {g: dict(v) for g, v in GOOD_GROUPS.items()}
        groups["initial"] = {"omega": table}
        for function in (ellroll.namelist, ellroll.run_arrays):
            with pytest.raises(ellroll.InputError) as raised:
                function(groups)
            assert "&initial" in raised.value.message and "omega" in raised.value.message
            assert f"of shape {np.shape(table)} is a table with a row or column of one" in raised.value.message
    groups = {g: dict(v) for g, v in GOOD_GROUPS.items()}
    groups["initial"] = {"omega": np.array([1.0, 2.0, 3.0])}
    assert "omega = 1.0, 2.0, 3.0" in ellroll.namelist(groups)


def test_record_names_as_record_groups():
    time = np.arange(5) * 0.01
    acceleration = np.zeros((5, 2))
    for name in ["r", "a" * 32, "SYN1_H1.x-y"]:
        assert ellroll.Record(time, acceleration, name=name).name == name
    for name in ["", "a" * 33, "a b", "ä", "a/b"]:
        with pytest.raises(ellroll.InputError, match="1 to 32"):
            ellroll.Record(time, acceleration, name=name)
    for name in [None, 3, b"r"]:
        with pytest.raises(ellroll.InputError, match="give a text"):
            ellroll.Record(time, acceleration, name=name)


@pytest.mark.parametrize("argument, values, words", [
    ("acceleration", np.zeros((5, 2)) + 0.5j, "acceleration must be real numbers, not complex"),
    ("acceleration", [[0.1, 0.2 + 1e-30j]] * 5, "acceleration must be real numbers, not complex"),
    ("time", np.arange(5) * (0.01 + 0j), "time must be real numbers, not complex"),
    ("acceleration", np.zeros((5, 2), dtype=bool), "acceleration must be real numbers, not logicals"),
    ("acceleration", [["0.1", "0.2"]] * 5, "acceleration must be real numbers, not text"),
    ("acceleration", [[0.1, None]] * 5, "acceleration must be real numbers, not NoneType (None)"),
    ("time", [0.0, 0.01, 0.02, 0.03, "later"], "time must be real numbers, not text"),
    ("acceleration", [[0.1, True]] + [[0.1, 0.2]] * 4, "acceleration must be real numbers, not bool (True)"),
    ("time", [0.0, 0.01, False, 0.03, 0.04], "time must be real numbers, not bool (False)"),
])
def test_a_record_of_numbers_that_are_not_real_is_refused(argument, values, words):
    """Complex, logical, text or missing values in a Record are refused by
    argument, not converted (numpy would drop an imaginary part with only a
    warning); integers and fractions are real numbers."""
    arrays = {"time": np.arange(5) * 0.01, "acceleration": np.zeros((5, 2))}
    arrays[argument] = values
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        with pytest.raises(ellroll.InputError) as raised:
            ellroll.Record(arrays["time"], arrays["acceleration"], name="quake")
    assert isinstance(raised.value, ValueError) and f"Record 'quake': {words}" in raised.value.message
    whole = ellroll.Record([0, 1, 2], [[1, 0], [fractions.Fraction(1, 4), 0], [-1, 0]])
    assert whole.time.dtype == np.float64 and whole.acceleration[1, 0] == 0.25


def test_a_bad_record_array_is_named_by_its_record_and_row():
    """The message names the Record and the row of the bad value, not its temporary file."""
    import random
    rng = random.Random(10)
    for _ in range(3):
        n = rng.randint(20, 60)
        time = np.arange(n) * 0.01
        acceleration = np.array([[rng.uniform(-1, 1), rng.uniform(-1, 1)] for _ in range(n)])
        row = rng.randrange(n)
        acceleration[row, rng.randrange(2)] = rng.choice([np.nan, np.inf])
        groups = {g: dict(v) for g, v in GOOD_GROUPS.items()}
        groups["excitation"] = {"kind": "record", "record_file": ellroll.Record(time, acceleration, name="quake")}
        with pytest.raises(ellroll.InputError) as raised:
            ellroll.run_arrays(groups)
        message = raised.value.message
        assert f"Record 'quake' row {row}" in message and "ellroll-records-" not in message, message


def test_a_closed_file_says_it_is_closed(paper_file):
    """Every read of an EllrollFile after close() (or its with block):
    NotAnEllrollFile naming the file as closed, never 'no dataset' nor
    h5py's own error."""
    import ellroll_post
    reads = [lambda r: r.summary("theta_max"), lambda r: r.summary("theta_max", 0),
             lambda r: r.trajectory("nutation"), lambda r: r.n_cases, lambda r: r.fields, lambda r: r.time,
             lambda r: r.status_names(), lambda r: r.status_name(0), lambda r: r.attrs, lambda r: r.summary_names,
             lambda r: r.case_input("radius"), lambda r: r.input_column("radius"), lambda r: r.units("time"),
             lambda r: r.record_names(), lambda r: r.swept_inputs()]
    with ellroll_post.open(paper_file) as run_:
        pass
    for read in reads:
        with pytest.raises(ellroll_post.NotAnEllrollFile) as raised:
            read(run_)
        assert str(raised.value) == f"{paper_file}: closed; ellroll_post.open it again to read it"


def test_runs_in_forked_children_after_the_parent_ran(tmp_path):
    """A fork-based multiprocessing pool (Linux's default) after the parent's
    own ellroll.run: each child has only the thread that forked, not the
    parent's worker thread; its runs finish with the results the parent gets
    for the same texts, bitwise."""
    script = tmp_path / "pool.py"
    script.write_text(f"""
import multiprocessing, sys
sys.path.insert(0, {str(ROOT / 'post')!r})
import ellroll, numpy as np
text = open({str(ROOT / 'input' / 'legeza1990.nml')!r}).read().replace("t_end = 30.0", "t_end = 1.0")
def theta_max(wz):
    out = ellroll.run(text.replace("omega = -2.0, 2.0, 20.0", f"omega = -2.0, 2.0, {{wz}}"), threads=1)
    return np.asarray(out["summary"]["theta_max"]).tobytes().hex()
if __name__ == "__main__":
    parent = [theta_max(wz) for wz in (10.0, 20.0, 30.0)]
    with multiprocessing.get_context("fork").Pool(2) as pool:
        children = pool.map(theta_max, [10.0, 20.0, 30.0])
    print(parent == children, parent)
""")
    result = run(sys.executable, str(script), cwd=tmp_path, timeout=30)
    assert result.returncode == 0, result.stderr
    assert result.stdout.startswith("True"), result.stdout


def test_a_record_s_file_that_cannot_be_written_names_its_folder(tmp_path):
    """A Record's CSV that the disk refuses part way (here the file size
    limit, as a full TMPDIR would): Error 3 naming the private folder in
    TMPDIR and the system's reason, and the folder removed."""
    script = tmp_path / "record.py"
    script.write_text(f"""
import resource, signal, sys
sys.path.insert(0, {str(ROOT / 'post')!r})
import ellroll, numpy as np
signal.signal(signal.SIGXFSZ, signal.SIG_IGN)
resource.setrlimit(resource.RLIMIT_FSIZE, (100 * 1024, resource.getrlimit(resource.RLIMIT_FSIZE)[1]))
t = np.arange(0, 60, 0.001)
try:
    ellroll.run({{"geometry": {{"a": 1.0, "b": 0.4, "c": 0.2}}, "ball": {{"radius": 0.2, "weight": 2620.0}},
                 "initial": {{"x": 0.0, "y": 0.0, "omega": [0.0, 0.0, 0.0]}},
                 "integration": {{"method": "rk4", "dt": 1e-3, "t_end": 0.1}},
                 "excitation": {{"kind": "record", "record_file": ellroll.Record(t, np.zeros((t.size, 2)))}}}})
except ellroll.Error as error:
    print(error.code, error.message)
""")
    result = subprocess.run([sys.executable, str(script)], cwd=tmp_path, capture_output=True, text=True, timeout=60,
                            env={**os.environ, "TMPDIR": str(tmp_path)})
    private = str(tmp_path / "ellroll-records-")
    assert result.returncode == 0 and result.stdout.startswith(f"3 {private}"), (result.stdout, result.stderr)
    assert "cannot write a Record's file: File too large" in result.stdout
    assert not list(tmp_path.glob("ellroll-records-*"))


@pytest.mark.skipif(SANITIZED, reason="the sanitizer's shadow memory takes more address space than the limit")
def test_results_beyond_the_processs_memory_raise_before_any_is_taken(tmp_path):
    """3000 cases of 10,001 samples of every field (about 8 GiB held) in a
    process limited to 3 GiB (ulimit -v): ellroll.InputError (code 2) naming the
    input, the sizes and the way out, at once; the process lives on and runs
    the next input. A failed allocation would end the calling process."""
    script = tmp_path / "room.py"
    script.write_text(f"""
import resource, sys
resource.setrlimit(resource.RLIMIT_AS, (3 << 30, 3 << 30))
sys.path.insert(0, {str(ROOT / 'post')!r})
import ellroll
paper = open({str(ROOT / 'input' / 'legeza1990.nml')!r}).read()
big = paper.replace("t_end = 30.0", "t_end = 10.0").replace("interval = 0.01", "interval = 1.0e-3") + \\
    "&campaign samples = 3000, seed = 1 /\\n&sample name = 'omega_z', low = 5, high = 50 /\\n"
try:
    ellroll.run(big, threads=1, path="big.nml")
except ellroll.InputError as e:
    print(e.code, e)
out = ellroll.run(paper.replace("t_end = 30.0", "t_end = 1.0"), threads=1)
print("then", int(out["summary"]["status"][0]))
""")
    result = run(sys.executable, str(script), cwd=tmp_path, timeout=60)
    assert result.returncode == 0, result.stderr
    lines = result.stdout.splitlines()
    assert lines[0].startswith("2 big.nml: the results of 3000 cases, 10001 samples of 17 values each, need about "
                               "8 GiB of memory, more than this process may hold (3 GiB)"), result.stdout
    assert lines[1] == "then 1", result.stdout
