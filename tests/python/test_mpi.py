"""The MPI build (-DELLROLL_MPI=ON): ranks run the shards and rank 0 merges;
the file equals a single-process run."""
import os
import pathlib
import shutil
import subprocess

import pytest

from conftest import ROOT, run
from test_campaign import SPIN_RADIUS, assert_same_datasets, write

MPI_EXE = pathlib.Path(os.environ.get("ELLROLL_MPI_EXE", ROOT / "build-mpi" / "ellroll"))
pytestmark = pytest.mark.skipif(not (MPI_EXE.exists() and shutil.which("mpirun")),
                                reason="no MPI build (made by .ci/setup test)")


def mpirun(n, *args, cwd):
    env = dict(os.environ, OMPI_ALLOW_RUN_AS_ROOT="1", OMPI_ALLOW_RUN_AS_ROOT_CONFIRM="1", OMP_NUM_THREADS="1")
    return subprocess.run(["mpirun", "--oversubscribe", "-n", str(n), str(MPI_EXE), *args], cwd=cwd, env=env,
                          capture_output=True, text=True, timeout=300)


def test_two_ranks_equal_a_single_run(ellroll, tmp_path):
    name = write(tmp_path, SPIN_RADIUS)
    assert run(ellroll, "run", name, "-q", "-o", "single.h5", cwd=tmp_path).returncode == 0
    result = mpirun(2, "run", name, "-o", "mpi.h5", cwd=tmp_path)
    assert result.returncode == 0, result.stdout + result.stderr
    assert "completed           20" in result.stdout
    assert sorted(p.name for p in tmp_path.iterdir()) == ["camp.nml", "mpi.h5", "single.h5"]
    assert_same_datasets(tmp_path / "single.h5", tmp_path / "mpi.h5")


def test_bad_input_under_mpi(tmp_path):
    name = write(tmp_path, "&sweep name = 'radius', values = 0.2, 0.9 /\n")
    result = mpirun(2, "run", name, cwd=tmp_path)
    assert result.returncode == 2 and "1 of 2 cases are invalid" in result.stderr
    assert sorted(p.name for p in tmp_path.iterdir()) == ["camp.nml"]
