"""The Python API (post/ellroll over libellroll): a run in memory gives the
file's datasets bit for bit, with its names, units and statuses; a dict
gives what its namelist text gives; bad input raises with the program's
message; runs in threads at once, and on any thread count, agree."""
import concurrent.futures
import os
import pathlib
import sys
import threading
import time

import h5py
import numpy as np
import pytest

from conftest import ROOT, PAPER_INPUT, run

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
        for group in ("", "case", "summary", "trajectory"):
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
                for attribute in ("flag_values", "flag_meanings", "input_names"):
                    if attribute in stored.attrs:
                        expected = text(stored.attrs[attribute])
                        assert same_bits(memory.attrs[attribute], expected), (group, name, attribute)
                        if attribute == "flag_values":
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
