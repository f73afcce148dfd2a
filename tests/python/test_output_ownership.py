"""--overwrite replaces only a file ellroll wrote: its root attribute
file_identity must match where its objects lie. Copies made by other
programs (h5py, an xarray round trip through h5netcdf) carry ellroll's root
attributes but not their layout, and are refused (exit 3) and left as they
were; a byte copy (cp) is the same file, and is replaced."""
import shutil

import h5py
import pytest

from conftest import run

CAMPAIGN = """&geometry a = 1.0, b = 0.4, c = 0.2 /
&ball radius = 0.2, weight = 2620.0 /
&initial x = 0.0, y = 0.0, omega = -2.0, 2.0, 20.0 /
&integration method = 'rk4', dt = 1.0e-3, t_end = 0.1 /
&output file = 'out.h5', interval = 0.01 /
&sweep name = 'omega_z', values = 5, 10, 20 /
"""


@pytest.fixture()
def folder(ellroll, tmp_path):
    (tmp_path / "camp.nml").write_text(CAMPAIGN)
    result = run(ellroll, "run", "camp.nml", "-q", "-o", "ref.h5", cwd=tmp_path)
    assert result.returncode == 0, result.stderr
    return tmp_path


def h5py_copy(source, target):
    with h5py.File(source) as src, h5py.File(target, "w") as dst:
        for name in src:
            src.copy(name, dst)
        for key, value in src.attrs.items():
            dst.attrs[key] = value


def xarray_copy(source, target):
    xarray = pytest.importorskip("xarray")
    pytest.importorskip("h5netcdf")
    xarray.open_datatree(source).to_netcdf(target, engine="h5netcdf")


def faked(source, target):
    with h5py.File(target, "w") as f:
        f.attrs["program"] = "ellroll"
        f["my_data"] = [1, 2, 3]


@pytest.mark.parametrize("make", [h5py_copy, xarray_copy, faked], ids=["h5py-copy", "xarray", "attribute"])
def test_overwrite_refuses_a_file_another_program_wrote(ellroll, folder, make):
    make(folder / "ref.h5", folder / "copy.h5")
    before = (folder / "copy.h5").read_bytes()
    result = run(ellroll, "run", "camp.nml", "-q", "-o", "copy.h5", "--overwrite", cwd=folder)
    assert result.returncode == 3, result.stderr
    assert "copy.h5: exists and is not an ellroll output file" in result.stderr
    assert "never replaced, even with --overwrite" in result.stderr
    assert (folder / "copy.h5").read_bytes() == before
    assert sorted(p.name for p in folder.iterdir() if p.name.startswith("copy.h5.")) == []
    # merge too
    for i in range(2):
        made = run(ellroll, "run", "camp.nml", "-q", "--shard", f"{i}/2", "-o", f"s{i}.h5", cwd=folder)
        assert made.returncode == 0, made.stderr
    result = run(ellroll, "merge", "copy.h5", "s0.h5", "s1.h5", "--overwrite", cwd=folder)
    assert result.returncode == 3 and "never replaced" in result.stderr, result.stderr
    assert (folder / "copy.h5").read_bytes() == before


def test_overwrite_replaces_ellrolls_file_and_a_byte_copy_of_it(ellroll, folder):
    shutil.copyfile(folder / "ref.h5", folder / "cp.h5")
    for name in ("ref.h5", "cp.h5"):
        result = run(ellroll, "run", "camp.nml", "-q", "-o", name, "--overwrite", cwd=folder)
        assert result.returncode == 0, result.stderr
    with h5py.File(folder / "cp.h5") as f:
        assert len(f.attrs["file_identity"]) == 8 and f.attrs["program"] == "ellroll"


@pytest.mark.parametrize("contents", [b"", b"ellroll lock\n", b"somebody's notes\n"], ids=["empty", "lock-like", "text"])
def test_a_file_with_other_names_at_the_lock_is_never_written(ellroll, folder, contents):
    """OUT.h5.lock as another name (a hard link) of somebody's file, empty,
    beginning as a lock note, or holding text: run and merge refuse it (exit
    3) naming it, and the file keeps its bytes and both names."""
    (folder / "notes.txt").write_bytes(contents)
    (folder / "out.h5.lock").hardlink_to(folder / "notes.txt")
    for i in range(2):
        made = run(ellroll, "run", "camp.nml", "-q", "--shard", f"{i}/2", "-o", f"s{i}.h5", cwd=folder)
        assert made.returncode == 0, made.stderr
    for command in (["run", "camp.nml", "-q"], ["merge", "out.h5", "s0.h5", "s1.h5"]):
        result = run(ellroll, *command, cwd=folder)
        assert result.returncode == 3, result.stderr
        assert "out.h5.lock: exists and is not" in result.stderr and "never replaced" in result.stderr, result.stderr
        assert (folder / "notes.txt").read_bytes() == contents and (folder / "out.h5.lock").stat().st_nlink == 2
        assert not (folder / "out.h5").exists()
