"""Threads never change a result, and the parallel loop has no data race.

Stress: `check` and `run` of mixed campaigns (valid, invalid and warned cases,
model limits, SIMD batches, a record suite with rolling resistance) repeated
on 2 and 3 threads; every output equals the 1-thread run's, bit for bit (the
check's text, every dataset and attribute of the file but the wall times and
the time stamps). ELLROLL_STRESS_REPEATS sets the repeats per thread count
(default 10: 20 runs of each campaign and command in CI).

Races: the ThreadSanitizer build (build-tsan, -DELLROLL_TSAN=ON) runs the same
campaigns under LLVM's OpenMP runtime with its Archer tool, which tells the
sanitizer about OpenMP's synchronisation; any report fails the test. A
deliberately racy program (gfortran 12's static length of a deferred-length
function result, the bug that once corrupted `check`'s messages) shows the
detector finds what it looks for."""
import os
import pathlib
import shutil
import subprocess

import h5py
import numpy as np
import pytest

from conftest import ROOT, run

REPEATS = int(os.environ.get("ELLROLL_STRESS_REPEATS", "10"))
TIME_ATTRIBUTES = {"created", "history", "command_line"}
# HDF5 object references: file addresses, not data
REFERENCES = {"DIMENSION_LIST", "REFERENCE_LIST"}

# fixed cup: 40 sampled starts, some outside the cup (skipped as invalid), some
# slipping or leaving the fit, some spinning too fast for dt (warned); 8 or
# more cases run in SIMD batches
FIXED_CUP = """\
&geometry a = 1.0, b = 0.4, c = 0.2 /
&ball radius = 0.2, weight = 2620.0, mu = 0.6 /
&initial x = 0.0, y = 0.0, omega = -2.0, 2.0, 20.0 /
&integration method = '{method}', dt = 1.0e-3, t_end = 0.3 /
&output file = 'fixed.h5', interval = 0.01, fields = 'contact', 'nutation', 'reaction' /
&campaign samples = 40, seed = 7, invalid = 'skip' /
&sample name = 'x', low = -1.05, high = 1.05 /
&sample name = 'omega_x', low = -8, high = 8 /
&sample name = 'omega_z', low = 5, high = 3000 /
"""

# a record suite with rolling resistance (one case at a time), an invalid scale
SUITE = """\
&geometry a = 1.0, b = 0.4, c = 0.2 /
&ball radius = 0.2, weight = 2620.0 /
&initial x = 0.05, y = 0.0, omega = 0.0, 0.0, 0.0 /
&integration method = 'rk4', dt = 1.0e-3, t_end = 0.5 /
&excitation kind = 'record' /
&record name = 'SYN1', record_file = 'records/SYN1_H1.AT2', 'records/SYN1_H2.AT2' /
&record name = 'SYN3', record_file = 'records/SYN3_H1.AT2', 'records/SYN3_H2.AT2', factor = 1.5 /
&sweep name = 'rolling_resistance', values = 0.0, 1.0e-4, 1.0e-3 /
&sweep name = 'x', values = 0.05, 0.3, 1.5 /
&campaign invalid = 'skip' /
&output file = 'suite.h5', interval = 0.05, fields = 'center', 'reaction', 'base_acceleration' /
"""

# the check alone of many sampled starts, a third of them outside the cup: every
# case is checked in parallel, each invalid one building its message
MANY_STARTS = FIXED_CUP.format(method="rk4").replace("samples = 40", "samples = 2000")

CAMPAIGNS = {"fixed_rk4": FIXED_CUP.format(method="rk4"), "fixed_dop853": FIXED_CUP.format(method="dop853"),
             "suite": SUITE}


def campaign_folder(tmp_path, name):
    folder = tmp_path / name
    folder.mkdir()
    shutil.copytree(ROOT / "input" / "records", folder / "records")
    (folder / "c.nml").write_text(CAMPAIGNS[name])
    return folder


def file_contents(path):
    """Every dataset and attribute of a file, wall times and time stamps aside."""
    contents = {}
    with h5py.File(path) as f:
        def visit(name, obj):
            for key, value in obj.attrs.items():
                if key in REFERENCES:
                    continue
                contents[f"{name}@{key}"] = np.asarray(value).tobytes() if not isinstance(value, str) else value
            if isinstance(obj, h5py.Dataset) and not name.endswith("wall_time"):
                contents[name] = (str(obj.asstr()[()]) if h5py.check_string_dtype(obj.dtype)
                                  else obj[()].tobytes())
        f.visititems(visit)
        for key, value in f.attrs.items():
            if key not in TIME_ATTRIBUTES:
                contents[f"@{key}"] = str(value)
    return contents


def without_progress(text):
    return "\n".join(line for line in text.splitlines() if "cases/s" not in line and "integration time" not in line
                     and "slowest case" not in line)


@pytest.mark.parametrize("name", sorted(CAMPAIGNS))
def test_threads_give_bitwise_the_same_check_and_run(ellroll, tmp_path, name):
    folder = campaign_folder(tmp_path, name)
    checked = run(ellroll, "check", "c.nml", "--threads", 1, cwd=folder)
    assert checked.returncode == 0, checked.stderr
    reference = run(ellroll, "run", "c.nml", "-o", "one.h5", "--threads", 1, "-q", cwd=folder)
    assert reference.returncode == 0, reference.stderr
    expected = file_contents(folder / "one.h5")
    with h5py.File(folder / "one.h5") as f:
        statuses = set(f["summary/status"][:])
    assert len(statuses) >= 2, f"{name}: the campaign should end its cases in several ways, not {statuses}"
    for repeat in range(REPEATS):
        for threads in (2, 3):
            again = run(ellroll, "check", "c.nml", "--threads", threads, cwd=folder)
            assert again.returncode == 0, f"repeat {repeat}, {threads} threads:\n{again.stderr}"
            assert (again.stdout, again.stderr) == (checked.stdout, checked.stderr), f"repeat {repeat}, {threads}"
            result = run(ellroll, "run", "c.nml", "-o", "many.h5", "--threads", threads, "-q", "--overwrite",
                         cwd=folder)
            assert result.returncode == 0, f"repeat {repeat}, {threads} threads:\n{result.stderr}"
            assert without_progress(result.stdout.replace("many.h5", "one.h5")) == without_progress(reference.stdout)
            got = file_contents(folder / "many.h5")
            differing = sorted(k for k in expected if got.get(k) != expected[k])
            assert differing == [] and set(got) == set(expected), \
                f"repeat {repeat}, {threads} threads: {differing[:10]}"


@pytest.mark.parametrize("how", ["option", "environment"])
def test_a_huge_thread_count_is_capped_and_gives_the_same_bits(ellroll, tmp_path, how):
    """--threads or OMP_NUM_THREADS far beyond the machine (100,000 threads'
    stacks exhaust the memory): each loop takes at most its units of work
    and 16 threads per processor; the file is the one thread's."""
    folder = campaign_folder(tmp_path, "fixed_rk4")
    reference = run(ellroll, "run", "c.nml", "-o", "one.h5", "--threads", 1, "-q", cwd=folder)
    assert reference.returncode == 0, reference.stderr
    if how == "option":
        for threads in (100000, 2**31 - 1):
            result = run(ellroll, "run", "c.nml", "-o", "many.h5", "--threads", threads, "-q", "--overwrite",
                         cwd=folder)
            assert result.returncode == 0, result.stderr
    else:
        result = subprocess.run([str(ellroll), "run", "c.nml", "-o", "many.h5", "-q"], cwd=folder, capture_output=True,
                                text=True, timeout=120, env=dict(os.environ, OMP_NUM_THREADS="100000"))
        assert result.returncode == 0, result.stderr
    assert file_contents(folder / "many.h5") == file_contents(folder / "one.h5")


def test_threads_give_the_same_check_of_many_cases(ellroll, tmp_path):
    (tmp_path / "c.nml").write_text(MANY_STARTS)
    checked = run(ellroll, "check", "c.nml", "--threads", 1, cwd=tmp_path)
    assert checked.returncode == 0 and "invalid cases will be skipped" in checked.stdout, checked.stderr
    for repeat in range(2 * REPEATS):
        for threads in (2, 3):
            again = run(ellroll, "check", "c.nml", "--threads", threads, cwd=tmp_path)
            assert (again.returncode, again.stdout, again.stderr) == (0, checked.stdout, checked.stderr), \
                f"repeat {repeat}, {threads} threads:\n{again.stderr[-3000:]}"


# ---- the race detector

ARCHER = pathlib.Path("/usr/lib/llvm-14/lib/libarcher.so")
LLVM_OPENMP = pathlib.Path("/usr/lib/llvm-14/lib/libomp.so.5")
SUPPRESSIONS = """\
# inside the OpenMP runtimes and the Fortran runtime's own unit locks
called_from_lib:libgomp.so.1
called_from_lib:libarcher.so
mutex:libarcher.so
deadlock:libgfortran.so.5
"""

RACY = """\
module racy
contains
  function text(i) result(s)
    integer, intent(in) :: i
    character(len=:), allocatable :: s
    character(len=12) :: buffer
    write (buffer, '(i0)') i
    s = trim(buffer)
  end function text
  logical function cut_short(i)
    integer, intent(in) :: i
    character(len=:), allocatable :: t
    t = '(' // text(mod(i, 10)) // ')'
    cut_short = len(t) /= 3
  end function cut_short
end module racy
program main
  use racy
  implicit none
  integer :: i, bad
  bad = 0
  !$omp parallel do reduction(+:bad)
  do i = 1, 20000
    if (cut_short(i)) bad = bad + 1
  end do
  !$omp end parallel do
  print '(i0)', bad
end program main
"""


@pytest.fixture(scope="module")
def sanitized_environment(tmp_path_factory):
    if not (ARCHER.exists() and LLVM_OPENMP.exists()):
        pytest.skip("LLVM's OpenMP runtime and Archer (Debian: libomp-14-dev) are not installed")
    folder = tmp_path_factory.mktemp("tsan")
    # gfortran's code calls libgomp's entry points; LLVM's runtime provides them
    (folder / "libgomp.so.1").symlink_to(LLVM_OPENMP)
    (folder / "suppressions.txt").write_text(SUPPRESSIONS)
    env = dict(os.environ, LD_LIBRARY_PATH=str(folder), OMP_TOOL_LIBRARIES=str(ARCHER),
               TSAN_OPTIONS=f"halt_on_error=0 exitcode=66 suppressions={folder / 'suppressions.txt'}")
    return env


def test_the_race_detector_finds_a_race(sanitized_environment, tmp_path):
    if shutil.which("gfortran") is None:
        pytest.skip("gfortran not found")
    (tmp_path / "racy.f90").write_text(RACY)
    built = subprocess.run(["gfortran", "-fopenmp", "-fsanitize=thread", "-g", "racy.f90", "-o", "racy"],
                           cwd=tmp_path, capture_output=True, text=True)
    assert built.returncode == 0, built.stderr
    result = subprocess.run(["./racy"], cwd=tmp_path, capture_output=True, text=True, timeout=120,
                            env=dict(sanitized_environment, OMP_NUM_THREADS="2"))
    assert "WARNING: ThreadSanitizer: data race" in result.stderr and "racy.f90" in result.stderr, result.stderr


@pytest.mark.parametrize("name", sorted(CAMPAIGNS))
def test_no_data_race_in_check_and_run(sanitized_environment, tmp_path, name):
    exe = ROOT / "build-tsan" / "ellroll"
    if not exe.exists():
        pytest.skip(f"{exe} not built")
    folder = campaign_folder(tmp_path, name)
    for threads in (2, 3):
        for command in (["check", "c.nml"], ["run", "c.nml", "-o", "out.h5", "-q", "--overwrite"]):
            result = subprocess.run([str(exe), *command, "--threads", str(threads)], cwd=folder, capture_output=True,
                                    text=True, timeout=300, env=sanitized_environment)
            detail = f"{name}, {' '.join(command)} on {threads} threads:\n{result.stderr[-6000:]}"
            assert "ThreadSanitizer" not in result.stderr, detail
            assert result.returncode == 0, detail
