"""The MPI build (-DELLROLL_MPI=ON): ranks run the shards and rank 0 merges;
the file equals a single-process run."""
import os
import pathlib
import shutil
import signal
import subprocess
import time

import pytest

from conftest import ROOT, in_turn, run
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


def test_a_resume_of_a_complete_mpi_run_has_nothing_to_do(tmp_path):
    name = write(tmp_path, SPIN_RADIUS, t_end=0.2)
    assert mpirun(2, "run", name, "-q", cwd=tmp_path).returncode == 0
    result = mpirun(2, "run", name, "--resume", cwd=tmp_path)
    assert result.returncode == 0 and "already complete; nothing to do" in result.stderr, result.stderr
    assert sorted(p.name for p in tmp_path.iterdir()) == ["camp.nml", "out.h5"]


@pytest.mark.skipif(shutil.which("strace") is None, reason="strace is not installed")
@pytest.mark.parametrize("when", in_turn([2, 4], 1), ids=str)
def test_a_resume_after_a_fault_past_the_move_into_place_leaves_only_the_output(ellroll, tmp_path, when):
    """EIO at a folder's fsync after a file moved into place (strace counts
    each process's: the 2nd, of each rank's shard; the 4th, of the merged
    output; one of the two in turn, both with ELLROLL_TEST_FULL): exit 3;
    the --resume that follows gives the whole output and removes the
    ranks' journals and shards left, nothing else there."""
    name = write(tmp_path, SPIN_RADIUS, t_end=0.2)
    assert run(ellroll, "run", name, "-q", "-o", "single.h5", cwd=tmp_path).returncode == 0
    env = dict(os.environ, OMPI_ALLOW_RUN_AS_ROOT="1", OMPI_ALLOW_RUN_AS_ROOT_CONFIRM="1", OMP_NUM_THREADS="1")
    faulted = subprocess.run(["strace", "-f", "-qq", "-o", os.devnull, "-e", "trace=fsync", "-e",
                              f"inject=fsync:error=EIO:when={when}", "mpirun", "--oversubscribe", "-n", "2",
                              str(MPI_EXE), "run", name, "-q"], cwd=tmp_path, env=env, capture_output=True, text=True,
                             timeout=300)
    assert faulted.returncode != 0 and "Input/output error" in faulted.stderr, faulted.stderr
    assert any(p.name.startswith("out.h5.rank") for p in tmp_path.iterdir())
    result = mpirun(2, "run", name, "-q", "--resume", cwd=tmp_path)
    assert result.returncode == 0, result.stderr
    assert sorted(p.name for p in tmp_path.iterdir()) == ["camp.nml", "out.h5", "single.h5"]
    assert_same_datasets(tmp_path / "single.h5", tmp_path / "out.h5")


def ranks_in(folder):
    """The process ids of the MPI build's processes working in folder."""
    found = []
    for entry in pathlib.Path("/proc").iterdir():
        try:
            command = (entry / "cmdline").read_bytes().split(b"\0")
            if command[0].decode() == str(MPI_EXE) and (entry / "cwd").resolve() == folder.resolve():
                found.append(int(entry.name))
        except (OSError, ValueError, IndexError):
            continue
    return found


def test_an_interrupted_mpi_run_names_the_mpi_command_that_finishes_it(ellroll, tmp_path):
    """SIGTERM to the ranks (as scancel sends it): each keeps its finished
    cases and names the MPI command that finishes the run; a resume on more
    or fewer ranks (or a serial one) is refused before it runs anything.
    (Each rank's own standard error is kept by a wrapper: mpirun drops what
    ranks that end with an error status write last.)"""
    name = write(tmp_path, SPIN_RADIUS, t_end=20000.0)
    (tmp_path / "camp.nml").write_text((tmp_path / "camp.nml").read_text().replace("interval = 0.01",
                                                                                 "interval = 10.0"))
    wrapper = tmp_path / "rank.sh"
    wrapper.write_text(f"#!/bin/sh\n{MPI_EXE} \"$@\" 2> \"rank$OMPI_COMM_WORLD_RANK.err\"\n")
    wrapper.chmod(0o755)
    env = dict(os.environ, OMPI_ALLOW_RUN_AS_ROOT="1", OMPI_ALLOW_RUN_AS_ROOT_CONFIRM="1", OMP_NUM_THREADS="1")
    process = subprocess.Popen(["mpirun", "--oversubscribe", "-n", "2", str(wrapper), "run", name, "-q"],
                               cwd=tmp_path, env=env, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    while not all((tmp_path / f"out.h5.rank{r}.h5.journal").exists() for r in (0, 1)):
        time.sleep(0.02)
        assert process.poll() is None, process.stderr.read()
    for rank in ranks_in(tmp_path):
        os.kill(rank, signal.SIGTERM)
    process.communicate(timeout=120)
    for r in (0, 1):
        message = (tmp_path / f"rank{r}.err").read_text()
        assert "interrupted by SIGTERM" in message, message
        assert "'mpirun -n 2 ellroll run camp.nml -q --resume' finishes the rest" in message, message
        (tmp_path / f"rank{r}.err").unlink()
    wrapper.unlink()
    more = mpirun(3, "run", name, "-q", "--resume", cwd=tmp_path)
    assert more.returncode != 0, more.stderr
    fewer = mpirun(1, "run", name, "-q", "--resume", cwd=tmp_path)
    assert fewer.returncode == 3 and "out.h5.rank1.h5" in fewer.stderr and "on at least 2 MPI ranks are here (this " \
        "run has 1); finish it on as many ranks as it was started on (mpirun -n 2 ... --resume)" in fewer.stderr, \
        fewer.stderr
