"""An input file larger than the stack (8 MiB by default): the whole text is
stored as the file's `input_namelist` attribute, and every command that
writes it (run, the shards' merge) takes it from the heap. Seeded sizes of
comment lines and values on either side of 8 MiB."""
import h5py
import numpy as np
import pytest

from conftest import run

CASE = ("&geometry a = 1.0, b = 0.4, c = 0.2 /\n&ball radius = 0.2, weight = 2620.0 /\n"
        "&initial x = 0.0, y = 0.0, omega = -2.0, 2.0, 20.0 /\n"
        "&integration method = 'rk4', dt = 1.0e-3, t_end = 0.05 /\n&output file = 'big.h5', interval = 0.01 /\n"
        "&sweep name = 'omega_z', values = 10.0, 20.0 /\n")


@pytest.mark.parametrize("mebibytes", [9, 24])
def test_an_input_past_the_stack_runs_shards_and_merges_whole(ellroll, tmp_path, mebibytes):
    rng = np.random.default_rng(mebibytes)
    width = int(rng.integers(60, 200))
    line = "! " + "x" * width + "\n"
    text = CASE + line * (mebibytes * 2**20 // len(line) + 1)
    (tmp_path / "big.nml").write_text(text)
    whole = run(ellroll, "run", "big.nml", "-q", cwd=tmp_path)
    assert whole.returncode == 0, whole.stderr
    for shard in range(2):
        result = run(ellroll, "run", "big.nml", "-q", "--shard", f"{shard}/2", "-o", f"s{shard}.h5", cwd=tmp_path)
        assert result.returncode == 0, result.stderr
    merged = run(ellroll, "merge", "m.h5", "s0.h5", "s1.h5", cwd=tmp_path)
    assert merged.returncode == 0, merged.stderr
    for name in ("big.h5", "m.h5"):
        with h5py.File(tmp_path / name, "r") as f:
            stored = f.attrs["input_namelist"]
            stored = stored.decode() if isinstance(stored, bytes) else stored
            assert stored == text, name
            assert list(f["summary/status"][:]) == [1, 1], name        # completed
    summary = run(ellroll, "summary", "m.h5", cwd=tmp_path)
    assert summary.returncode == 0 and "completed            2" in summary.stdout, summary.stdout
