"""An output whose per-case tables another program changed (h5py rewrote a
/summary, /case or /limit_state dataset with fewer or more rows than
/summary/status): `ellroll summary`, in every format and with --suite,
refuses it in one line naming the file and the dataset (exit 2) or, where
it does not read that dataset, prints as usual; it never reads or writes
past the rows it expects (no signal, no runtime error on the Debug build).
A dataset rewritten as text where ellroll writes numbers (or the other way)
is refused by ellroll_post.open and ellroll-plot in one line (exit 2), not
with a traceback from the figure. Seeded choices of the datasets and their
lengths."""
import h5py
import numpy as np
import pytest

from conftest import run

INPUT = """&geometry a = 1.0, b = 0.4, c = 0.2 /
&ball radius = 0.2, mass = 1.0 /
&initial x = 0.0, y = 0.0, omega = -2.0, 2.0, 20.0 /
&integration method = 'rk4', dt = 1e-3, t_end = 0.2 /
&output file = 'out.h5', interval = 0.05 /
&sweep name = 'omega_z', values = 5, 10, 15, 20, 25, 30 /
&limit_state name = 'drift', figure = 'displacement_max', capacity = 0.01 /
"""
COMMANDS = ([], ["--format", "csv"], ["--format", "json"], ["--suite"])
MESSAGE = "not laid out as ellroll writes its files"


@pytest.fixture(scope="module")
def original(ellroll, tmp_path_factory):
    folder = tmp_path_factory.mktemp("edited")
    (folder / "case.nml").write_text(INPUT)
    result = run(ellroll, "run", "case.nml", "-q", cwd=folder)
    assert result.returncode == 0, result.stderr
    return folder / "out.h5"


def tables(path):
    names = []
    with h5py.File(path, "r") as f:
        for group in ("summary", "case", "limit_state"):
            names += [f"{group}/{name}" for name, item in f[group].items() if isinstance(item, h5py.Dataset)]
    return sorted(names)


def edited(original, folder, name, rows):
    """A copy of the output with dataset `name` cut or stretched to `rows`
    along its case dimension, its attributes kept."""
    path = folder / f"{name.replace('/', '_')}_{rows}.h5"
    path.write_bytes(original.read_bytes())
    with h5py.File(path, "r+") as f:
        old = f[name]
        attrs = {k: v for k, v in old.attrs.items() if k not in ("DIMENSION_LIST", "REFERENCE_LIST")}
        data = old[()]
        data = np.resize(data, (rows,) + data.shape[1:])
        del f[name]
        f[name] = data
        for key, value in attrs.items():
            f[name].attrs[key] = value
    return path


@pytest.mark.parametrize("seed", range(4))
def test_a_table_of_another_length_is_refused_or_not_read(ellroll, ellroll_debug, original, tmp_path, seed):
    rng = np.random.default_rng(9100 + seed)
    names = tables(original)
    n_cases = 6
    for name in rng.choice(names, size=6, replace=False):
        rows = int(rng.choice([0, 1, n_cases - 1, n_cases + 1, 5000]))
        path = edited(original, tmp_path, str(name), rows)
        for options in COMMANDS:
            for exe in (ellroll, ellroll_debug):
                result = run(exe, "summary", path.name, *options, cwd=tmp_path)
                label = (str(name), rows, options, str(exe), result.stderr[-400:])
                assert result.returncode in (0, 2), label
                if result.returncode == 2:
                    lines = result.stderr.strip().splitlines()
                    assert len(lines) == 1 and path.name in lines[0], label
                    assert MESSAGE in lines[0] or "cannot read" in lines[0], label
                # csv and json print every dataset of /summary: none is left unread
                if name.startswith("summary/") and options in (["--format", "csv"], ["--format", "json"]):
                    assert result.returncode == 2 and f"/{name} holds {rows} rows" in result.stderr, label


def retyped(original, folder, name):
    """A copy with dataset `name` rewritten in the other kind: text where
    ellroll writes numbers, numbers where it writes text."""
    path = folder / f"{name.replace('/', '_')}_retyped.h5"
    path.write_bytes(original.read_bytes())
    with h5py.File(path, "r+") as f:
        old = f[name]
        numbers = old.dtype.kind in "fiu"
        data = np.full(old.shape, b"a") if numbers else np.zeros(old.shape)
        del f[name]
        f[name] = data
    return path, "text" if numbers else "numbers"


@pytest.mark.parametrize("seed", range(2))
def test_a_table_of_another_kind_is_refused_by_the_python_readers(ellroll, original, tmp_path, seed):
    import ellroll_post
    from ellroll_post.cli import main
    from ellroll_post.reader import NotAnEllrollFile
    rng = np.random.default_rng(9200 + seed)
    names = [name for name in tables(original) if not name.startswith("limit_state/")]
    names += ["case/method", "case/record"]
    for name in rng.choice(names, size=5, replace=False):
        path, holds = retyped(original, tmp_path, str(name))
        with pytest.raises(NotAnEllrollFile, match=f"/{name} holds {holds}, where ellroll writes"):
            ellroll_post.open(path)
        for command in (["summary"], ["sweep", "--out", str(tmp_path)], ["trace", "--out", str(tmp_path)]):
            assert main([command[0], str(path), *command[1:]]) == 2, (name, command)
