"""Campaigns: expansion, thread-count invariance, shards and merge, kill -9
and resume, refusals, invalid cases, progress."""
import os
import random
import re
import resource
import signal
import struct
import subprocess
import time

import h5py
import numpy as np
import pytest

from conftest import FULL, ROOT, run, run_shards_and_merge

BASE = """&geometry    a = 1.0, b = 0.4, c = 0.2 /
&ball        radius = 0.2, weight = 2620.0 /
&initial     x = 0.0, y = 0.0, omega = -2.0, 2.0, 20.0 /
&integration dt = 1.0e-3, t_end = {t_end} /
&output      file = 'out.h5', interval = 0.01 /
"""
SPIN_RADIUS = """&sweep name = 'omega_z', values = 5, 10, 20, 40, 80 /
&sweep name = 'radius', start = 0.05, stop = 0.2, count = 4, spacing = 'linear' /
"""


def write(folder, extra, t_end=1.0, name="camp.nml"):
    (folder / name).write_text(BASE.format(t_end=t_end) + extra)
    return name


def datasets(path):
    """Every dataset's content (VL strings decoded), except wall_time."""
    out = {}
    with h5py.File(path, "r") as f:
        def visit(name, obj):
            if isinstance(obj, h5py.Dataset) and name != "summary/wall_time":
                out[name] = obj.asstr()[()] if h5py.check_string_dtype(obj.dtype) else obj[()]
        f.visititems(visit)
    return out


def assert_same_datasets(a, b):
    da, db = datasets(a), datasets(b)
    assert sorted(da) == sorted(db)
    for name in da:
        if isinstance(da[name], str):                 # /trajectory_label
            assert da[name] == db[name], name
        elif da[name].dtype.kind == "O":
            assert list(da[name]) == list(db[name]), name
        else:
            assert da[name].tobytes() == db[name].tobytes(), f"{name} differs"


@pytest.mark.parametrize("start, stop, count, expected", [
    (0.01, 10.0, 4, [0.01, 0.1, 1.0, 10.0]), (0.001, 100.0, 6, [0.001, 0.01, 0.1, 1.0, 10.0, 100.0]),
    (10.0, 1e4, 7, [10.0, 10**1.5, 100.0, 10**2.5, 1000.0, 10**3.5, 1e4])])
def test_a_log_sweep_over_decades_gives_them_exactly(ellroll, tmp_path, start, stop, count, expected):
    name = write(tmp_path, f"&sweep name = 'omega_z', start = {start!r}, stop = {stop!r}, count = {count}, "
                 "spacing = 'log' /\n", t_end=0.01)
    assert run(ellroll, "run", name, "-q", cwd=tmp_path).returncode == 0
    with h5py.File(tmp_path / "out.h5", "r") as f:
        assert list(f["case/omega"][:, 2]) == expected


def test_samples_are_the_same_in_every_build(ellroll, ellroll_debug, tmp_path):
    """A campaign's random samples (linear and log spacing) are the same
    numbers, bitwise, in the Release build (-march=native, where a fused
    multiply-add could move low + (high - low) u by an ulp) and the Debug
    build: the same campaign on a laptop and a cluster runs the same cases."""
    name = write(tmp_path, "&campaign samples = 200, seed = 11 /\n"
                           "&sample name = 'x', low = -0.1, high = 0.1 /\n"
                           "&sample name = 'omega_z', low = 1.0, high = 40.0 /\n"
                           "&sample name = 'radius', low = 0.05, high = 0.2, spacing = 'log' /\n", t_end=0.01)
    for exe, out in ((ellroll, "release.h5"), (ellroll_debug, "debug.h5")):
        assert run(exe, "run", name, "-q", "-o", out, cwd=tmp_path).returncode == 0
    with h5py.File(tmp_path / "release.h5", "r") as a, h5py.File(tmp_path / "debug.h5", "r") as b:
        for dataset in ("x", "omega", "radius"):
            assert a[f"case/{dataset}"][()].tobytes() == b[f"case/{dataset}"][()].tobytes(), dataset


def test_grid_expansion_order_and_spacing(ellroll, tmp_path):
    name = write(tmp_path, SPIN_RADIUS + "&sweep name = 'mass', start = 1, stop = 100, count = 3, spacing = 'log' /\n"
                 .replace("mass", "weight").replace("start = 1, stop = 100", "start = 100, stop = 10000"))
    result = run(ellroll, "check", name, cwd=tmp_path)
    assert result.returncode == 0, result.stderr
    assert "campaign: 60 cases" in result.stdout
    assert run(ellroll, "run", name, "-q", cwd=tmp_path).returncode == 0
    with h5py.File(tmp_path / "out.h5", "r") as f:
        spin, radius, weight = f["case/omega"][:, 2], f["case/radius"][:], f["case/weight"][:]
        assert list(f["case/index"][:]) == list(range(60))
        # the first sweep varies slowest, the last fastest
        np.testing.assert_array_equal(spin, np.repeat([5, 10, 20, 40, 80], 12))
        np.testing.assert_allclose(radius, np.tile(np.repeat([0.05, 0.1, 0.15, 0.2], 3), 5), rtol=1e-15)
        np.testing.assert_array_equal(weight, np.tile([100, 1000, 10000], 20))     # decades exactly
        assert f.attrs["n_cases_total"] == 60 and f.attrs["shard"] == "0/1"
        assert np.all(f["summary/status"][:] == 1)


def test_zip_pairs_sweeps(ellroll, tmp_path):
    name = write(tmp_path, "&campaign combine = 'zip' /\n&sweep name = 'omega_z', values = 5, 10, 20 /\n"
                 "&sweep name = 'x', values = 0.0, 0.1, 0.2 /\n")
    assert run(ellroll, "run", name, "-q", cwd=tmp_path).returncode == 0
    with h5py.File(tmp_path / "out.h5", "r") as f:
        np.testing.assert_array_equal(f["case/omega"][:, 2], [5, 10, 20])
        np.testing.assert_array_equal(f["case/x"][:], [0.0, 0.1, 0.2])


def test_samples_are_reproducible_and_in_range(ellroll, tmp_path):
    sample = ("&campaign samples = 40, seed = {seed} /\n&sample name = 'omega_z', low = 5, high = 100 /\n"
              "&sample name = 'radius', low = 0.01, high = 0.2, spacing = 'log' /\n")
    for seed, out in [(7, "a.h5"), (7, "b.h5"), (8, "c.h5")]:
        name = write(tmp_path, sample.format(seed=seed), t_end=0.1)
        assert run(ellroll, "run", name, "-q", "-o", out, "--threads", "2" if out == "b.h5" else "1",
                   cwd=tmp_path).returncode == 0
    a, b, c = (h5py.File(tmp_path / n, "r") for n in ("a.h5", "b.h5", "c.h5"))
    spin, radius = a["case/omega"][:, 2], a["case/radius"][:]
    assert np.all((spin >= 5) & (spin < 100)) and np.all((radius >= 0.01) & (radius < 0.2))
    assert len(set(spin)) == 40
    np.testing.assert_array_equal(spin, b["case/omega"][:, 2])
    np.testing.assert_array_equal(radius, b["case/radius"][:])
    assert not np.any(spin == c["case/omega"][:, 2])


@pytest.mark.parametrize("integration, extra", [
    ("dt = 1.0e-3", SPIN_RADIUS),                                                  # SIMD batches of 8
    ("method = 'vern9', rtol = 1e-10", SPIN_RADIUS),                              # the same, adaptive
    ("dt = 1.0e-3", "&sweep name = 'omega_z', values = 5, 80 /\n"),               # 2 cases, one a block
    ("dt = 1.0e-3", "&excitation kind = 'harmonic', amplitude = 0.05, 0.0, 0.0, frequency = 0.3 /\n"
     + SPIN_RADIUS)])                                                             # 20 cases, one a block
def test_thread_count_does_not_change_any_dataset(ellroll, tmp_path, integration, extra):
    name = write(tmp_path, extra)
    text = (tmp_path / name).read_text()
    (tmp_path / name).write_text(text.replace("dt = 1.0e-3", integration))
    for threads, out in [("1", "t1.h5"), ("2", "t2.h5"), ("3", "t3.h5")]:
        assert run(ellroll, "run", name, "-q", "--threads", threads, "-o", out, cwd=tmp_path).returncode == 0
    assert_same_datasets(tmp_path / "t1.h5", tmp_path / "t2.h5")
    assert_same_datasets(tmp_path / "t1.h5", tmp_path / "t3.h5")


# What the batch (SIMD lanes) and the one-case path share to round-off, per
# method: RK4 takes the same steps on both; the pairs' steps carry the
# round-off of their error estimates (eps / rtol relative for DOP853, 5.9 eps /
# rtol for Verner's, whose estimate cancels k_8 against k_12), so figures at
# step ends (the maxima of forces and displacement) move at that level, while
# samples at fixed times, Theta's maxima located on the dense output and the
# periods do not.
BATCH_AGREEMENT = {
    "rk4": ("dt = 1.0e-3", 1e-13, 1e-13),
    "dop853": ("method = 'dop853', rtol = 1.0e-9, atol = 1.0e-12, dt = 0.5", 1e-12, 1e-6),
    "vern9": ("method = 'vern9', rtol = 1.0e-9, atol = 1.0e-12, dt = 0.5", 1e-12, 1e-5),
}


@pytest.mark.parametrize("method", sorted(BATCH_AGREEMENT))
def test_batched_cases_equal_the_same_cases_run_alone(ellroll, tmp_path, method):
    """A campaign of >= 8 cases runs them across SIMD lanes; each result
    equals the one-case path (the case alone in its own input)."""
    integration, rtol, rtol_step_ends = BATCH_AGREEMENT[method]
    base = BASE.replace("dt = 1.0e-3", integration)
    (tmp_path / "camp.nml").write_text(base.format(t_end=1.0) + SPIN_RADIUS)
    assert run(ellroll, "run", "camp.nml", "-q", "-o", "campaign.h5", cwd=tmp_path).returncode == 0
    for index in (6, 19):
        with h5py.File(tmp_path / "campaign.h5", "r") as c:
            spin, radius = float(c["case/omega"][index][2]), float(c["case/radius"][index])
        alone = (base.format(t_end=1.0).replace("omega = -2.0, 2.0, 20.0", f"omega = -2.0, 2.0, {spin!r}")
                 .replace("radius = 0.2", f"radius = {radius!r}"))
        (tmp_path / "alone.nml").write_text(alone)
        assert run(ellroll, "run", "alone.nml", "-q", "--overwrite", "-o", "alone.h5", cwd=tmp_path).returncode == 0
        with h5py.File(tmp_path / "campaign.h5", "r") as c, h5py.File(tmp_path / "alone.h5", "r") as a:
            for field in ("contact", "omega", "reaction", "energy"):
                np.testing.assert_allclose(c[f"trajectory/{field}"][index], a[f"trajectory/{field}"][0],
                                           rtol=rtol, atol=rtol * np.max(np.abs(a[f"trajectory/{field}"][0])))
            for figure in ("theta_max", "nutation_period"):
                np.testing.assert_allclose(c[f"summary/{figure}"][index], a[f"summary/{figure}"][0], rtol=rtol)
            for figure in ("reaction_normal_max", "friction_needed_max", "displacement_max", "horizontal_force_max"):
                np.testing.assert_allclose(c[f"summary/{figure}"][index], a[f"summary/{figure}"][0],
                                           rtol=rtol_step_ends)
            assert c["summary/n_rhs"][index] == a["summary/n_rhs"][0]


def test_shards_merge_to_the_single_run(ellroll, tmp_path):
    name = write(tmp_path, SPIN_RADIUS)
    assert run(ellroll, "run", name, "-q", "-o", "single.h5", cwd=tmp_path).returncode == 0
    for i in range(3):
        result = run(ellroll, "run", name, "-q", "--shard", f"{i}/3", "-o", f"shard_{i}.h5", cwd=tmp_path)
        assert result.returncode == 0, result.stderr
    with h5py.File(tmp_path / "shard_1.h5", "r") as f:
        assert list(f["case/index"][:]) == [1, 4, 7, 10, 13, 16, 19]
        assert list(f["summary/case"][:]) == [1, 4, 7, 10, 13, 16, 19]
    result = run(ellroll, "merge", "merged.h5", "shard_2.h5", "shard_0.h5", "shard_1.h5", cwd=tmp_path)
    assert result.returncode == 0, result.stderr
    assert_same_datasets(tmp_path / "single.h5", tmp_path / "merged.h5")

    # refusals: a missing shard, a shard twice, a shard of another campaign
    result = run(ellroll, "merge", "m2.h5", "shard_0.h5", "shard_2.h5", cwd=tmp_path)
    assert result.returncode == 2 and "missing shard 1/3 (given: 0/3, 2/3): run it with --shard 1/3 -o FILE (a file of its own) and merge again" in result.stderr
    result = run(ellroll, "merge", "m3.h5", "shard_0.h5", "shard_1.h5", "shard_1.h5", "shard_2.h5", cwd=tmp_path)
    assert result.returncode == 2 and "given twice" in result.stderr
    other = write(tmp_path, SPIN_RADIUS.replace("80", "90"), name="other.nml")
    assert run(ellroll, "run", other, "-q", "--shard", "1/3", "-o", "other_1.h5", cwd=tmp_path).returncode == 0
    result = run(ellroll, "merge", "m4.h5", "shard_0.h5", "other_1.h5", "shard_2.h5", cwd=tmp_path)
    assert result.returncode == 2 and "another campaign" in result.stderr
    assert not any((tmp_path / n).exists() for n in ("m2.h5", "m3.h5", "m4.h5"))


# a journal record (src/run/journal.f90): marker, slot, status, the summary
# as (value, kind, spare) words per entry in summary_record's order
# (src/cases/results.f90: wall_time is the 5th), the checksum of the
# trajectories written in place, the trajectories written through HDF5
# (compressed), the count of the case's switches of regime (their times and
# kinds after it: none for a case that did not slide), the record's checksum
SUMMARY_ENTRIES, WALL_TIME_ENTRY = 34, 4
# magic; id, writer (16 words), slots, samples, shard, two flags per field, the note's words;
# checksum; then the note of the input's files (empty without records) and its checksum
JOURNAL_HEADER = 8 + 8 * (8 + 16 + 4 + 2 * 10 + 1) + 8 + 8
RECORD_MARKER = 7310312871522813004


def record_bytes(samples_in_record=0):
    """The size of a journal record holding `samples_in_record` trajectory
    values (samples x components of the compressed fields)."""
    return 8 * (3 + 3 * SUMMARY_ENTRIES + 1 + samples_in_record + 1 + 1)


def test_the_journal_record_layout_here_is_the_programs(ellroll, tmp_path):
    """The summary entries a journal record holds are the /summary figures
    (the datasets on the case coordinate, status and checksum aside): the
    record sizes the tests below compute follow the figure table."""
    name = write(tmp_path, "&sweep name = 'omega_z', values = 5, 10 /\n")
    assert run(ellroll, "run", name, "-q", cwd=tmp_path).returncode == 0
    with h5py.File(tmp_path / "out.h5", "r") as f:
        figures = [k for k, v in f["summary"].items() if "coordinates" in v.attrs and k not in ("status", "checksum")]
        assert len(figures) == SUMMARY_ENTRIES, figures
        assert figures[WALL_TIME_ENTRY] == "wall_time"


def test_a_shard_past_the_last_case_is_empty_and_merges(ellroll, tmp_path):
    name = write(tmp_path, "&sweep name = 'omega_z', values = 5, 10 /\n")
    assert run(ellroll, "run", name, "-q", "-o", "whole.h5", cwd=tmp_path).returncode == 0
    for index in range(3):
        assert run(ellroll, "run", name, "-q", "--shard", f"{index}/3", "-o", f"s{index}.h5", cwd=tmp_path).returncode == 0
    with h5py.File(tmp_path / "s2.h5", "r") as f:
        assert f["summary/status"].shape == (0,) and f["trajectory/contact"].shape[0] == 0
    assert run(ellroll, "merge", "merged.h5", "s0.h5", "s1.h5", "s2.h5", cwd=tmp_path).returncode == 0
    assert_same_datasets(tmp_path / "whole.h5", tmp_path / "merged.h5")


def merge_under_limit(ellroll, folder, soft, hard, shards):
    def limit():
        resource.setrlimit(resource.RLIMIT_NOFILE, (soft, hard))
    return subprocess.run([str(ellroll), "merge", "merged.h5", *shards], cwd=folder, capture_output=True,
                          text=True, timeout=120, preexec_fn=limit)


def test_a_merge_of_more_shards_than_the_soft_open_file_limit(ellroll, tmp_path):
    """A merge holds every shard open: 120 shards under a soft limit of 64
    open files (as a job array's thousand shards under the usual 1024) merge
    to the single run; under a hard limit of 64 the merge is refused before
    it opens a shard, naming the count and the limit, and leaves nothing."""
    count = 120
    name = write(tmp_path, f"&sweep name = 'omega_z', start = 5, stop = 40, count = {count} /\n", t_end=0.01)
    assert run(ellroll, "run", name, "-q", "-o", "whole.h5", cwd=tmp_path).returncode == 0
    shards = [f"s{index}.h5" for index in range(count)]
    for index, shard in enumerate(shards):
        assert run(ellroll, "run", name, "-q", "--shard", f"{index}/{count}", "-o", shard,
                   cwd=tmp_path).returncode == 0
    before = sorted(p.name for p in tmp_path.iterdir())
    refused = merge_under_limit(ellroll, tmp_path, 64, 64, shards)
    assert refused.returncode == 3 and refused.stderr == (
        f"ellroll: error: {count} shards: a merge holds every shard open and needs about {count + 64} open files, "
        "where this process may open 64 (the hard limit, ulimit -Hn): raise it\n"), refused.stderr
    assert sorted(p.name for p in tmp_path.iterdir()) == before
    hard = resource.getrlimit(resource.RLIMIT_NOFILE)[1]
    if hard != resource.RLIM_INFINITY and hard < count + 64:
        pytest.skip(f"this machine's hard limit on open files is {hard}")
    merged = merge_under_limit(ellroll, tmp_path, 64, hard, shards)
    assert merged.returncode == 0, merged.stderr
    assert_same_datasets(tmp_path / "whole.h5", tmp_path / "merged.h5")


@pytest.mark.parametrize("shard", ["0/2", "1/2", "2/3", "0/1"])
def test_a_shard_without_its_own_file_is_refused(ellroll, tmp_path, shard):
    """--shard I/N with N > 1 and no -o: every shard would write the one
    &output file (the second refused, or replacing the first with
    --overwrite); refused before anything is written, naming the option and
    a file of its own. One shard of one (the whole campaign) needs none."""
    name = write(tmp_path, "&sweep name = 'omega_z', values = 5, 10, 15 /\n")
    for options in ([], ["--overwrite"]):
        result = run(ellroll, "run", name, "-q", "--shard", shard, *options, cwd=tmp_path)
        if shard == "0/1":
            assert result.returncode == 0 and (tmp_path / "out.h5").exists(), result.stderr
            continue
        index = shard.split("/")[0]
        assert result.returncode == 2 and result.stderr.strip() == (
            f"ellroll: error: --shard {shard} needs -o naming this shard's own file (e.g. -o "
            f"out.shard_{index}.h5): every shard of the campaign would write out.h5"), result.stderr
        assert sorted(p.name for p in tmp_path.iterdir()) == ["camp.nml"]


def journal_wall_times(path, samples_in_record=0):
    """(slot -> wall_time) of the records of a journal (places never
    written, as a kill leaves them, are skipped)."""
    data = path.read_bytes()
    size = record_bytes(samples_in_record)
    out = {}
    for start in range(JOURNAL_HEADER, len(data) - size + 1, size):
        record = struct.unpack(f"<{size // 8}q", data[start:start + size])
        if record[0] != RECORD_MARKER:
            continue
        slot, wall = record[1], struct.unpack("<d", struct.pack("<q", record[3 + 3 * WALL_TIME_ENTRY]))[0]
        out[slot] = wall
    return out


def kill_after_records(args, cwd, journal, records, size_of_record, delay=0.0):
    """Start a run, kill it -9 once its journal has grown by `records` cases
    (plus `delay` seconds); False if it finished first."""
    size_at_start = journal.stat().st_size if journal.exists() else 0
    proc = subprocess.Popen(args, cwd=cwd, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    deadline = time.monotonic() + 60
    while proc.poll() is None and time.monotonic() < deadline:
        if journal.exists() and journal.stat().st_size >= size_at_start + records * size_of_record:
            break
        time.sleep(0.002)
    time.sleep(delay)
    if proc.poll() is not None:
        return False
    proc.send_signal(signal.SIGKILL)
    proc.wait()
    return True


@pytest.mark.parametrize("compression", [0, 4])
def test_kill_and_resume_equals_an_uninterrupted_run(ellroll, tmp_path, compression):
    # 240 cases: long enough (about 0.1 s) for several kills to land mid-run.
    # Uncompressed, a resume takes the journaled cases' trajectories from the
    # killed run's file; compressed, from their journal records.
    name = write(tmp_path, SPIN_RADIUS.replace("values = 5, 10, 20, 40, 80", "values = 5, 10, 20, 40, 80, 100")
                 .replace("count = 4", "count = 40"), t_end=5.0)
    text = (tmp_path / name).read_text()
    (tmp_path / name).write_text(text.replace("interval = 0.01 /", f"interval = 0.01, compression = {compression} /"))
    assert run(ellroll, "run", name, "-q", "-o", "whole.h5", cwd=tmp_path).returncode == 0
    in_record = 501 * 17 if compression else 0
    journal = tmp_path / "out.h5.journal"
    rng = random.Random(4)
    kept_before = {}
    kills = 0
    for attempt in range(5):
        args = [str(ellroll), "run", name, "-q", "--threads", "2"] + (["--resume"] if attempt else [])
        # kill at a random moment after this attempt has finished at least one case
        if not kill_after_records(args, tmp_path, journal, 2, record_bytes(in_record), rng.uniform(0.0, 0.03)):
            break
        if not journal.exists():     # the kill came after the run had completed its file (while it
            assert (tmp_path / "out.h5").exists()        # printed the summary): nothing to resume
            break
        kills += 1
        kept_before.update(journal_wall_times(journal, in_record))
        assert not (tmp_path / "out.h5").exists()
    if not (tmp_path / "out.h5").exists():
        result = run(ellroll, "run", name, "-q", "--resume", cwd=tmp_path)
        assert result.returncode == 0, result.stderr
        assert "run again" not in result.stderr
    assert kills >= 2 and kept_before
    assert not journal.exists() and not (tmp_path / "out.h5.partial").exists()
    assert_same_datasets(tmp_path / "whole.h5", tmp_path / "out.h5")
    with h5py.File(tmp_path / "out.h5", "r") as f:
        assert (f["trajectory/nutation"].compression is not None) == bool(compression)
        wall = f["summary/wall_time"][:]
        for slot, seconds in kept_before.items():
            assert wall[slot] == seconds, "a case finished before the kill was computed again"


@pytest.mark.parametrize("stop", [signal.SIGTERM, signal.SIGINT, signal.SIGHUP])
def test_a_stop_signal_keeps_the_finished_cases_and_says_how_to_resume(ellroll, tmp_path, stop):
    """SIGTERM (Slurm's time limit), SIGINT or SIGHUP (the terminal or ssh
    connection closed) half way: the run drops the
    cases under way, keeps the journaled ones, exits within seconds with
    128 + the signal's number, and prints the command that finishes it; that
    command gives the uninterrupted run's file."""
    name = write(tmp_path, SPIN_RADIUS.replace("count = 4", "count = 40"), t_end=40.0)
    assert run(ellroll, "run", name, "-q", "-o", "whole.h5", cwd=tmp_path).returncode == 0
    journal = tmp_path / "out.h5.journal"
    args = [str(ellroll), "run", name, "-q", "--threads", "2"]
    proc = subprocess.Popen(args, cwd=tmp_path, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True)
    while proc.poll() is None and not (journal.exists() and journal.stat().st_size >= 3 * record_bytes()):
        time.sleep(0.002)
    assert proc.poll() is None, "the run finished before the signal"
    proc.send_signal(stop)
    sent = time.monotonic()
    _, stderr = proc.communicate(timeout=30)
    assert time.monotonic() - sent < 5
    assert proc.returncode == 128 + stop, stderr
    kept = journal_wall_times(journal)
    name_of = {signal.SIGTERM: "SIGTERM", signal.SIGINT: "SIGINT", signal.SIGHUP: "SIGHUP"}[stop]
    command = f"ellroll run {name} -q --threads 2 --resume"
    assert f"ellroll: interrupted by {name_of} after {len(kept)} of 200 cases; '{command}' finishes the rest" \
        in stderr, stderr
    assert 0 < len(kept) < 200 and (tmp_path / "out.h5.partial").exists() and not (tmp_path / "out.h5").exists()
    result = run(ellroll, *command.split()[1:], cwd=tmp_path)
    assert result.returncode == 0, result.stderr
    assert_same_datasets(tmp_path / "whole.h5", tmp_path / "out.h5")
    with h5py.File(tmp_path / "out.h5", "r") as f:
        wall = f["summary/wall_time"][:]
        assert all(wall[slot] == seconds for slot, seconds in kept.items())


def test_a_run_under_nohup_goes_on_through_a_hangup(ellroll, tmp_path):
    """SIGHUP ignored by the run's parent (nohup): the run stays deaf to it
    and finishes the uninterrupted run's file."""
    name = write(tmp_path, SPIN_RADIUS.replace("count = 4", "count = 40"), t_end=10.0)
    assert run(ellroll, "run", name, "-q", "-o", "whole.h5", cwd=tmp_path).returncode == 0
    proc = subprocess.Popen([str(ellroll), "run", name, "-q", "--threads", "2"], cwd=tmp_path,
                            stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True,
                            preexec_fn=lambda: signal.signal(signal.SIGHUP, signal.SIG_IGN))
    while proc.poll() is None and not (tmp_path / "out.h5.journal").exists():
        time.sleep(0.002)
    assert proc.poll() is None, "the run finished before the signal"
    proc.send_signal(signal.SIGHUP)
    _, stderr = proc.communicate(timeout=120)
    assert proc.returncode == 0, stderr
    assert_same_datasets(tmp_path / "whole.h5", tmp_path / "out.h5")


def test_a_stop_signal_ends_a_long_case_within_milliseconds(ellroll, tmp_path):
    """One case of 2e7 RK4 steps (several seconds): the integration looks for
    the request every 4096 steps, so the run stops at once."""
    (tmp_path / "long.nml").write_text(BASE.format(t_end=20000.0).replace("interval = 0.01", "interval = 1.0"))
    proc = subprocess.Popen([str(ellroll), "run", "long.nml", "-q"], cwd=tmp_path, stdout=subprocess.DEVNULL,
                            stderr=subprocess.PIPE, text=True)
    time.sleep(0.5)
    assert proc.poll() is None
    proc.send_signal(signal.SIGTERM)
    sent = time.monotonic()
    _, stderr = proc.communicate(timeout=30)
    assert time.monotonic() - sent < 1.0
    assert proc.returncode == 143
    assert "interrupted by SIGTERM after 0 of 1 cases; 'ellroll run long.nml -q --resume'" in stderr


@pytest.mark.skipif(not FULL, reason="a record of 3e6 samples: set ELLROLL_TEST_FULL=1")
def test_a_stop_signal_does_not_wait_for_a_batchs_spectra_over_a_long_record(ellroll, tmp_path):
    """Eight cases in one batch on a record of 3e6 samples: after the steps,
    each case's Sa at its linear periods runs over the whole record (about
    0.2 s a case here). SIGTERM as the loop starts ends the run within a
    third of the uninterrupted loop's time (one case's Sa, not the batch's),
    and the resume gives the uninterrupted run's bits."""
    values = np.random.default_rng(3).standard_normal(3_000_000) * 0.01
    with open(tmp_path / "long.AT2", "w") as f:
        f.write(f"PEER\nX\nACCELERATION TIME SERIES IN UNITS OF G\nNPTS= {values.size}, DT= 0.0010 SEC\n")
        f.write(" ".join(f"{v:.7E}" for v in values) + "\n")
    (tmp_path / "long.nml").write_text("""&geometry a = 1.0, b = 0.4, c = 0.2 /
&ball radius = 0.2, weight = 2620.0 /
&initial omega = 0.0, 0.0, 0.0 /
&integration method = 'rk4', dt = 5e-4, t_end = 1.0 /
&excitation kind = 'record', record_file = 'long.AT2', 'long.AT2' /
&output file = 'out.h5', interval = 0.1 /
&sweep name = 'scale', start = 1, stop = 8, count = 8 /
""")
    whole = run(ellroll, "run", "long.nml", "-q", "--threads", "1", "--timings", "-o", "whole.h5", cwd=tmp_path)
    assert whole.returncode == 0, whole.stderr
    loop = float(re.search(r"([0-9.]+) s in the loop", whole.stdout + whole.stderr).group(1))
    proc = subprocess.Popen([str(ellroll), "run", "long.nml", "-q", "--threads", "1"], cwd=tmp_path,
                            stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True)
    journal = tmp_path / "out.h5.journal"
    while proc.poll() is None and not journal.exists():
        time.sleep(0.002)
    assert proc.poll() is None, "the run finished before the signal"
    proc.send_signal(signal.SIGTERM)
    sent = time.monotonic()
    _, stderr = proc.communicate(timeout=120)
    assert proc.returncode == 143, stderr
    assert time.monotonic() - sent < loop / 3, (time.monotonic() - sent, loop)
    assert "interrupted by SIGTERM after 0 of 8 cases" in stderr
    result = run(ellroll, "run", "long.nml", "-q", "--resume", cwd=tmp_path)
    assert result.returncode == 0, result.stderr
    assert_same_datasets(tmp_path / "whole.h5", tmp_path / "out.h5")


def killed_run(ellroll, tmp_path, records=2):
    """A run of 20 cases killed -9 after `records` journal records (one
    thread); its journaled (slot -> wall_time), and the uninterrupted
    run's file whole.h5 beside it."""
    name = write(tmp_path, SPIN_RADIUS, t_end=3.0)
    assert run(ellroll, "run", name, "-q", "-o", "whole.h5", cwd=tmp_path).returncode == 0
    journal = tmp_path / "out.h5.journal"
    assert kill_after_records([str(ellroll), "run", name, "-q", "--threads", "1"], tmp_path, journal, records,
                              record_bytes())
    journaled = journal_wall_times(journal)
    assert len(journaled) >= records
    return name, journaled


def resume_equals_the_whole_run(ellroll, tmp_path, name):
    """Resume; the file must equal the uninterrupted run's. Its wall times
    and the resume's standard error."""
    result = run(ellroll, "run", name, "-q", "--resume", cwd=tmp_path)
    assert result.returncode == 0, result.stderr
    assert_same_datasets(tmp_path / "whole.h5", tmp_path / "out.h5")
    assert not any((tmp_path / f"out.h5.{end}").exists() for end in ("journal", "partial", "partial.new"))
    with h5py.File(tmp_path / "out.h5", "r") as f:
        return f["summary/wall_time"][:], result.stderr


def test_resume_skips_a_journal_place_never_written(ellroll, tmp_path):
    # threads reserve journal places in turn and fill them at once: a kill can
    # leave an early place empty behind later records; resume must skip it,
    # keep the later records and run the empty place's case again
    name, before = killed_run(ellroll, tmp_path)
    journal = tmp_path / "out.h5.journal"
    with open(journal, "r+b") as f:
        f.seek(JOURNAL_HEADER)
        emptied = struct.unpack("<3q", f.read(24))[1]
        f.seek(JOURNAL_HEADER)
        f.write(bytes(record_bytes()))
    kept = journal_wall_times(journal)
    assert emptied not in kept and len(kept) == len(before) - 1
    wall, _ = resume_equals_the_whole_run(ellroll, tmp_path, name)
    assert all(wall[slot] == seconds for slot, seconds in kept.items()), "a journaled case was run again"


def flip_bits(path, offset, bits):
    """Flip the given bits (numbered from the byte at offset, lowest first)."""
    with open(path, "r+b") as f:
        for bit in bits:
            f.seek(offset + bit // 8)
            byte = f.read(1)[0]
            f.seek(offset + bit // 8)
            f.write(bytes([byte ^ (1 << bit % 8)]))


@pytest.mark.parametrize("bits", [[3], [200, 271], [64 * 9 + 5, 64 * 10 + 12], [70, 1000, 2000]],
                         ids=["1 bit", "2 bits", "bit i and i + 7 of the next word", "3 bits"])
def test_resume_runs_again_the_case_of_a_damaged_record(ellroll, tmp_path, bits):
    """Bits flipped in the summary of the journal's first record (its status
    and figures, behind the marker): the CRC-32C catches it, the resume warns
    and runs that case again, and the file equals the uninterrupted run's."""
    name, before = killed_run(ellroll, tmp_path)
    journal = tmp_path / "out.h5.journal"
    first = struct.unpack("<3q", journal.read_bytes()[JOURNAL_HEADER:JOURNAL_HEADER + 24])[1]
    flip_bits(journal, JOURNAL_HEADER + 16, bits)
    wall, stderr = resume_equals_the_whole_run(ellroll, tmp_path, name)
    rerun = sum(1 for slot in range(len(wall)) if slot not in before or wall[slot] != before[slot])
    assert (f"out.h5.journal: 1 damaged records skipped (their checksum does not match); {rerun} of {len(wall)} "
            "cases have no valid record and run") in stderr, stderr
    assert wall[first] != before[first], "the case of a damaged record was kept"
    assert all(wall[slot] == seconds for slot, seconds in before.items() if slot != first)


@pytest.mark.parametrize("offset, bits", [(8, [3, 10]), (8 + 8 * 9, [0, 7 + 64])], ids=["campaign id", "case count"])
def test_a_damaged_journal_header_refuses_the_resume(ellroll, tmp_path, offset, bits):
    name, _ = killed_run(ellroll, tmp_path)
    journal = tmp_path / "out.h5.journal"
    flip_bits(journal, offset, bits)
    result = run(ellroll, "run", name, "-q", "--resume", cwd=tmp_path)
    assert result.returncode == 3
    assert "out.h5.journal: the journal's header is damaged (its checksum does not match)" in result.stderr
    assert journal.exists() and (tmp_path / "out.h5.partial").exists() and not (tmp_path / "out.h5").exists()


def trajectory_label(path):
    """The label near an output file's start (/trajectory_label, found by its
    marker as a resume finds it, src/output/trajectory_store.f90): version,
    cases, samples, the address of each field (-1: not in place), checksum."""
    head = path.read_bytes()[:65536]
    at = head.index(b"ellroll trajectories: ")
    words = [int(w) for w in head[at:at + 512].split(b"\0")[0].split()[2:]]
    assert words[0] == 3 and len(words) == 14
    return words[1], words[2], words[3:13]


def test_resume_runs_again_a_case_whose_trajectories_are_damaged(ellroll, tmp_path):
    # a journal record vouches for its case's trajectories in the file by
    # their checksum: if the system lost them (a power cut), the case runs again
    name, before = killed_run(ellroll, tmp_path)
    partial = tmp_path / "out.h5.partial"
    n_cases, n_samples, addresses = trajectory_label(partial)
    assert n_cases == 20 and n_samples == 301 and all(a > 0 for a in addresses[:7]) and addresses[7] == -1
    damaged = min(before)
    nutation = addresses[4] + damaged * n_samples * 8    # one component per sample
    with open(partial, "r+b") as f:
        f.seek(nutation + 8 * 100)
        f.write(struct.pack("<d", 0.125))
    wall, stderr = resume_equals_the_whole_run(ellroll, tmp_path, name)
    assert "warning: 1 finished cases run again" in stderr and "damaged" in stderr
    assert wall[damaged] != before[damaged], "a case with damaged trajectories was kept"
    assert all(wall[slot] == seconds for slot, seconds in before.items() if slot != damaged)


def test_resume_without_the_killed_runs_file_runs_its_cases_again(ellroll, tmp_path):
    name, before = killed_run(ellroll, tmp_path)
    (tmp_path / "out.h5.partial").unlink()
    wall, stderr = resume_equals_the_whole_run(ellroll, tmp_path, name)
    assert f"warning: {len(before)} finished cases run again" in stderr and "out.h5.partial: cannot open" in stderr
    assert not any(wall[slot] == seconds for slot, seconds in before.items())


def test_a_resume_killed_while_copying_leaves_the_killed_runs_file_whole(ellroll, tmp_path):
    # a resume builds out.h5.partial.new and moves it over out.h5.partial
    # only once every journaled case is in it: killed before, it leaves
    # out.h5.partial as it was, and a half-built .new that the next resume replaces
    name, before = killed_run(ellroll, tmp_path)
    (tmp_path / "out.h5.partial.new").write_bytes(bytes(4096))
    wall, stderr = resume_equals_the_whole_run(ellroll, tmp_path, name)
    assert "warning" not in stderr
    assert all(wall[slot] == seconds for slot, seconds in before.items()), "a journaled case was run again"


def test_resume_refusals(ellroll, tmp_path):
    name = write(tmp_path, SPIN_RADIUS, t_end=3.0)
    journal = tmp_path / "out.h5.journal"
    assert kill_after_records([str(ellroll), "run", name, "-q", "--threads", "1"], tmp_path, journal, 1,
                              record_bytes())
    result = run(ellroll, "run", name, cwd=tmp_path)
    assert result.returncode == 3 and "--resume" in result.stderr
    write(tmp_path, SPIN_RADIUS.replace("80", "90"), t_end=3.0)
    result = run(ellroll, "run", name, "--resume", cwd=tmp_path)
    assert result.returncode == 2 and "input differs" in result.stderr
    write(tmp_path, SPIN_RADIUS, t_end=3.0)
    result = run(ellroll, "run", name, "--resume", "--shard", "0/2", "-o", "out.h5", cwd=tmp_path)
    assert result.returncode == 2 and "other options" in result.stderr, result.stderr
    assert run(ellroll, "run", name, "--resume", "-q", cwd=tmp_path).returncode == 0


def test_invalid_cases_stop_or_skip(ellroll, tmp_path):
    sweep = "&sweep name = 'radius', values = 0.2, 0.9, 0.5, 1.5 /\n"
    name = write(tmp_path, sweep)
    for command in ("check", "run"):
        result = run(ellroll, command, name, cwd=tmp_path)
        assert result.returncode == 2
        assert "2 of 4 cases are invalid" in result.stderr
        assert "case 1 (radius = 0.9): radius = 0.9: the ball does not fit" in result.stderr
        assert "case 3 (radius = 1.5)" in result.stderr
    assert not (tmp_path / "out.h5").exists()
    name = write(tmp_path, "&campaign invalid = 'skip' /\n" + sweep)
    assert "2 invalid cases will be skipped" in run(ellroll, "check", name, cwd=tmp_path).stdout
    result = run(ellroll, "run", name, cwd=tmp_path)
    assert result.returncode == 0, result.stderr
    with h5py.File(tmp_path / "out.h5", "r") as f:
        status = f["summary/status"]
        names = status.attrs["flag_meanings"].split()
        # R = 0.5 fits at the start (radii 0.8, 5 m) but meets no_fit as the ball climbs
        assert [names[s] for s in status[:]] == ["completed", "invalid", "no_fit", "invalid"]
        assert np.all(np.isnan(f["trajectory/nutation"][1])) and np.all(np.isfinite(f["trajectory/nutation"][0]))
        # a case never run holds no number that could pass for data: every real
        # figure is NaN, every count -1, the _FillValue (of its type) that
        # marks it missing to netCDF readers
        # (the checksum of an invalid case is that of what the file holds of it)
        assert np.all(f["summary/checksum"][:] >= 0)
        for name, dataset in f["summary"].items():
            if name in ("status", "checksum", "case") or name in f["summary/status"].attrs["coordinates"].split():
                continue
            values = dataset[:]
            if values.dtype.kind == "f":
                assert np.all(np.isnan(values[[1, 3]])), name
                # the completed case's figures are numbers but for those its inputs leave
                # undefined (no reference run, no excitation, no capacity set)
                assert np.all(np.isfinite(values[0])) or name in (
                    "nutation_period", "transmissibility", "error_contact", "error_theta", "error_energy",
                    "time_beyond_capacity", "residual_displacement", "rest_time", "sa_linear_periods"), name
            else:
                # (no reference run: n_rhs_reference is undefined for every case)
                assert np.all(values[[1, 3]] == -1), name
                assert np.all(values[[0, 2]] >= 0) != (name == "n_rhs_reference"), name
                fill = dataset.attrs["_FillValue"]
                assert fill.dtype == dataset.dtype and list(fill) == [-1], name
    table = run(ellroll, "summary", "out.h5", "--format", "csv", cwd=tmp_path).stdout.splitlines()
    header = [name.split(" [")[0] for name in table[0].split(",")]
    invalid_row = dict(zip(header, table[2].split(",")))
    assert invalid_row["status"] == "invalid" and invalid_row["theta_max"] == "NaN", invalid_row
    assert invalid_row["n_steps"] == invalid_row["slip_episodes"] == "NaN", invalid_row
    steps = dict(zip(header, table[1].split(",")))["n_steps"]
    assert int(steps) > 0
    # the steps of all cases: the cases run (not the invalid ones' -1)
    text = run(ellroll, "summary", "out.h5", cwd=tmp_path).stdout
    with h5py.File(tmp_path / "out.h5", "r") as f:
        assert f"steps, all cases: {f['summary/n_steps'][0] + f['summary/n_steps'][2]};" in text, text


def test_invalid_cases_keep_their_undefined_counts_through_shards_merge_and_resume(ellroll, tmp_path):
    """The counts of invalid cases (-1) are the same bits in a run, in its
    shards merged and in a killed run resumed."""
    name = write(tmp_path, "&campaign invalid = 'skip' /\n&sweep name = 'x', values = 0.0, 1.5, 0.1 /\n"
                 "&sweep name = 'omega_z', start = 5, stop = 80, count = 40, spacing = 'linear' /\n", t_end=5.0)
    assert run(ellroll, "run", name, "-q", "-o", "whole.h5", cwd=tmp_path).returncode == 0
    with h5py.File(tmp_path / "whole.h5", "r") as f:
        invalid = f["summary/status"][()] == f["summary/status"].attrs["flag_meanings"].split().index("invalid")
        assert invalid.sum() == 40
        assert np.all(f["summary/n_steps"][()][invalid] == -1) and np.all(f["summary/n_steps"][()][~invalid] > 0)
    run_shards_and_merge(ellroll, name, tmp_path, (2, 0, 1))
    assert_same_datasets(tmp_path / "whole.h5", tmp_path / "merged.h5")
    with h5py.File(tmp_path / "merged.h5", "r") as f:
        assert list(f["summary/slip_episodes"].attrs["_FillValue"]) == [-1]
    journal = tmp_path / "out.h5.journal"
    assert kill_after_records([str(ellroll), "run", name, "-q", "--threads", "1"], tmp_path, journal, 2,
                              record_bytes())
    assert journal.exists() and not (tmp_path / "out.h5").exists()
    result = run(ellroll, "run", name, "-q", "--resume", cwd=tmp_path)
    assert result.returncode == 0, result.stderr
    assert_same_datasets(tmp_path / "whole.h5", tmp_path / "out.h5")


def test_the_step_advice_leaves_out_invalid_cases(ellroll, tmp_path):
    """A case outside the cup is never run: it gets no advice about its step."""
    name = write(tmp_path, "&campaign invalid = 'skip' /\n"
                 "&sweep name = 'x', values = 0.0, 1.5 /\n&sweep name = 'omega_z', values = 20, 1e6 /\n")
    result = run(ellroll, "check", name, cwd=tmp_path)
    assert result.returncode == 0, result.stderr
    assert "2 of 4 cases: dt is beyond rk4's stability" not in result.stderr
    assert "1 of 4 cases: dt is beyond rk4's stability" in result.stderr and "case 1:" in result.stderr, result.stderr


def test_a_sweep_with_an_invalid_step_is_advised_and_skipped_under_fp_traps(ellroll_debug, tmp_path):
    """The step advice runs before invalid cases are set aside: a case with
    dt = 0 must not be divided by (the Debug build traps floating-point errors)."""
    name = write(tmp_path, "&campaign invalid = 'skip' /\n&sweep name = 'dt', values = 0, 0.001 /\n", t_end=0.5)
    result = run(ellroll_debug, "run", name, cwd=tmp_path)
    assert result.returncode == 0, result.stderr
    with h5py.File(tmp_path / "out.h5", "r") as f:
        names = f["summary/status"].attrs["flag_meanings"].split()
        assert [names[s] for s in f["summary/status"][:]] == ["invalid", "completed"]


@pytest.mark.parametrize("extra,words", [
    ("&sweep name = 'speed', values = 1, 2 /\n", "not an input that can vary"),
    ("&sweep name = 'radius' /\n", "give either values"),
    ("&sweep name = 'radius', values = 0.1, start = 0.1, stop = 0.2, count = 2 /\n", "give either values"),
    ("&sweep name = 'omega_z', values = 1, 2 /\n&sweep name = 'omega_z', values = 3 /\n", "already varied"),
    ("&sweep name = 'radius', start = 0, stop = 1, count = 3, spacing = 'log' /\n", "needs start > 0"),
    ("&sweep name = 'radius', start = 0.1, stop = 0.2, count = 1 /\n", "count = 1: one value cannot run from start"),
    ("&sample name = 'radius', low = 0.1, high = 0.2 /\n", "needs &campaign samples"),
    ("&campaign samples = 3 /\n", "no &sample group"),
    ("&campaign samples = 3 /\n&sample name = 'radius', low = 0.2, high = 0.1 /\n", "must be greater than low"),
    ("&campaign combine = 'zip' /\n&sweep name = 'x', values = 0, 0.1 /\n&sweep name = 'y', values = 0 /\n",
     "equal length"),
    ("&campaign combine = 'cross' /\n", "must be 'grid' or 'zip'"),
    ("&sweep name = 'mass', values = 1, 2 /\n", "vary weight instead"),
])
def test_bad_campaign_input(ellroll, tmp_path, extra, words):
    name = write(tmp_path, extra)
    result = run(ellroll, "check", name, cwd=tmp_path)
    assert result.returncode == 2 and words in result.stderr, result.stderr
    assert re.match(r"ellroll: error: camp\.nml(:\d+)?: ", result.stderr)


def test_progress_lines_in_a_log_and_quiet(ellroll, tmp_path):
    name = write(tmp_path, SPIN_RADIUS)
    result = run(ellroll, "run", name, cwd=tmp_path)
    assert result.returncode == 0
    lines = result.stderr.strip().splitlines()
    progress = [line for line in lines if line.startswith("ellroll: ") and " cases (" in line]
    assert progress[-1].startswith("ellroll: 20/20 cases (100%)") and "cases/s" in progress[-1]
    assert "ETA" not in progress[-1] and "done in" in progress[-1]
    assert lines[-1].startswith("ellroll: done in ") and "20 cases run" in lines[-1]
    assert "\r" not in result.stderr
    assert re.search(r"^  completed +20$", result.stdout, re.M)
    result = run(ellroll, "run", name, "-q", "--overwrite", cwd=tmp_path)
    assert result.returncode == 0 and result.stderr == ""
    assert run(ellroll, "summary", "out.h5", cwd=tmp_path).stdout == result.stdout


def test_error_figures_are_the_distance_to_a_vern9_run(ellroll, tmp_path):
    """error_estimate = 'reference' runs the case again with vern9 at rtol
    1e-12, atol 1e-14 (dt: the whole run): its figures are the largest
    distances to that run over the output times, and n_rhs_reference is that
    run's count."""
    fields = "fields = 'contact', 'nutation', 'energy'"
    estimated = (BASE.format(t_end=2.0).replace("dt = 1.0e-3", "dt = 1.0e-3, error_estimate = 'reference'")
                 .replace("interval = 0.01", f"interval = 0.01, {fields}"))
    reference = (BASE.format(t_end=2.0).replace("dt = 1.0e-3", "method = 'vern9', rtol = 1e-12, atol = 1e-14")
                 .replace("interval = 0.01", f"interval = 0.01, {fields}"))
    for name, text in [("estimated.nml", estimated), ("reference.nml", reference)]:
        (tmp_path / name).write_text(text)
        assert run(ellroll, "run", name, "-q", "-o", name.replace(".nml", ".h5"), cwd=tmp_path).returncode == 0
    with h5py.File(tmp_path / "estimated.h5", "r") as e, h5py.File(tmp_path / "reference.h5", "r") as r:
        assert e["summary/n_rhs_reference"][0] == r["summary/n_rhs"][0] > 0
        # a run without a reference run (the vern9 one, batched or not) has none: -1, not 0
        assert r["summary/n_rhs_reference"][0] == -1 and np.isnan(r["summary/error_contact"][0])
        distance = np.linalg.norm(e["trajectory/contact"][0] - r["trajectory/contact"][0], axis=1).max()
        assert e["summary/error_contact"][0] == pytest.approx(distance, rel=1e-12, abs=1e-17)
        theta = np.abs(e["trajectory/nutation"][0] - r["trajectory/nutation"][0]).max()
        assert e["summary/error_theta"][0] == pytest.approx(theta, rel=1e-12, abs=1e-17)
        assert 1e-13 < distance < 1e-10         # RK4 at dt = 1e-3 over 2 s: 1.6e-12 m


# Moving cups run in SIMD lanes too: a harmonic sweep and a suite of records
# (each lane its own record and scale), 12 cases, on 1, 2 and 3 threads and
# in 3 shards, bitwise the same; and a case of each from the batch against
# the same case alone (the one-case path) to round-off (rk4).
def moving_campaign(kind):
    if kind == "harmonic":
        return ("&excitation kind = 'harmonic', amplitude = 0.3, 0.2, 0.1, frequency = 0.6, phase = 0.4 /\n"
                "&sweep name = 'excitation_frequency', start = 0.2, stop = 2.0, count = 4, spacing = 'log' /\n"
                "&sweep name = 'omega_z', values = 5, 20, 40 /\n")
    records = ROOT / "input" / "records"
    return ("&excitation kind = 'record' /\n"
            + "".join(f"&record name = '{n}', record_file = '{records / (n + '.AT2')}' /\n"
                      for n in ("SYN1_H1", "SYN2_H1", "SYN3_H2"))
            + "&sweep name = 'scale', values = 0.5, 1.0, 2.0, 3.0 /\n")


@pytest.mark.parametrize("kind", ["harmonic", "record"])
def test_moving_cups_in_lanes_are_the_same_on_any_threads_and_shards(ellroll, tmp_path, kind):
    name = write(tmp_path, moving_campaign(kind), t_end=2.0)
    for threads, out in [("1", "t1.h5"), ("2", "t2.h5"), ("3", "t3.h5")]:
        assert run(ellroll, "run", name, "-q", "--threads", threads, "-o", out, cwd=tmp_path).returncode == 0
    with h5py.File(tmp_path / "t1.h5", "r") as f:
        assert f["summary/status"].shape == (12,) and np.all(f["summary/n_steps"][:] == 2000)
    assert_same_datasets(tmp_path / "t1.h5", tmp_path / "t2.h5")
    assert_same_datasets(tmp_path / "t1.h5", tmp_path / "t3.h5")
    run_shards_and_merge(ellroll, name, tmp_path, (0, 1, 2))
    assert_same_datasets(tmp_path / "t1.h5", tmp_path / "merged.h5")


@pytest.mark.parametrize("kind", ["harmonic", "record"])
def test_batched_moving_cups_equal_the_same_cases_run_alone(ellroll, tmp_path, kind):
    """rk4 takes the same steps in a batch and alone: samples (the cup's
    acceleration among them) and summary figures to 1e-12 relative."""
    extra = moving_campaign(kind)
    (tmp_path / "camp.nml").write_text(BASE.format(t_end=2.0).replace("interval = 0.01 /", "interval = 0.01, "
                                       "fields = 'contact', 'omega', 'reaction', 'base_acceleration' /") + extra)
    assert run(ellroll, "run", "camp.nml", "-q", "-o", "campaign.h5", cwd=tmp_path).returncode == 0
    index = 9
    with h5py.File(tmp_path / "campaign.h5", "r") as c:
        if kind == "harmonic":
            frequency, spin = float(c["case/excitation_frequency"][index]), float(c["case/omega"][index][2])
            alone = (extra.split("&sweep")[0].replace("frequency = 0.6", f"frequency = {frequency!r}"),
                     f"omega = -2.0, 2.0, {spin!r}")
        else:
            record = c["case/record"][index].decode().strip()
            scale = float(c["case/scale"][index])
    if kind == "harmonic":
        text = BASE.format(t_end=2.0).replace("omega = -2.0, 2.0, 20.0", alone[1]) + alone[0]
    else:
        assert record == "SYN3_H2"
        text = (BASE.format(t_end=2.0) + "&excitation kind = 'record', record_file = '"
                + str(ROOT / "input" / "records" / (record + ".AT2")) + f"' /\n&sweep name = 'scale', values = {scale!r} /\n")
    text = text.replace("interval = 0.01 /", "interval = 0.01, fields = 'contact', 'omega', 'reaction', "
                        "'base_acceleration' /")
    (tmp_path / "alone.nml").write_text(text)
    assert run(ellroll, "run", "alone.nml", "-q", "-o", "alone.h5", cwd=tmp_path).returncode == 0
    with h5py.File(tmp_path / "campaign.h5", "r") as c, h5py.File(tmp_path / "alone.h5", "r") as a:
        assert c["summary/n_steps"][index] == a["summary/n_steps"][0] == 2000
        for field in ("contact", "omega", "reaction", "base_acceleration"):
            expected = a[f"trajectory/{field}"][0]
            np.testing.assert_allclose(c[f"trajectory/{field}"][index], expected, rtol=1e-12,
                                       atol=1e-12 * np.max(np.abs(expected)))
        assert np.max(np.abs(c["trajectory/base_acceleration"][index])) > 0
        for figure in ("theta_max", "reaction_normal_max", "horizontal_force_max", "displacement_max",
                       "energy_drift", "transmissibility"):
            np.testing.assert_allclose(c[f"summary/{figure}"][index], a[f"summary/{figure}"][0], rtol=1e-10)


ROLLING_RESISTANCE = """&sweep name = 'rolling_resistance', values = 1.0e-3, 2.0e-3, 4.0e-3, 8.0e-3 /
&sweep name = 'omega_z', values = 0.0, 3.0 /
"""


def test_batched_rolling_resistance_equals_the_same_cases_run_alone(ellroll, tmp_path):
    """A sweep of rolling resistance (rk4, 8 cases) runs in SIMD lanes (one
    batch: its cases share its wall time), each lane its own mode per step
    and its own rest events; each case equals the one-case path (the case
    alone in its own input) to round-off: the same steps and status, samples
    and figures to 1e-12, the time and place it comes to rest. The event
    search's trials (its RHS calls) follow the round-off of the two paths."""
    base = (BASE.format(t_end=3.0).replace("x = 0.0, y = 0.0, omega = -2.0, 2.0, 20.0",
                                           "x = 0.1, y = 0.0, omega = 0.0, 0.0, 0.0")
            .replace("t_end = 3.0", "t_end = 3.0, settle = 3.0"))
    (tmp_path / "camp.nml").write_text(base + ROLLING_RESISTANCE)
    assert run(ellroll, "run", "camp.nml", "-q", "--threads", "1", "-o", "campaign.h5", cwd=tmp_path).returncode == 0
    assert run(ellroll, "run", "camp.nml", "-q", "--threads", "2", "-o", "threads.h5", cwd=tmp_path).returncode == 0
    assert_same_datasets(tmp_path / "campaign.h5", tmp_path / "threads.h5")
    with h5py.File(tmp_path / "campaign.h5", "r") as c:
        assert len(set(c["summary/wall_time"][:])) == 1, "the sweep runs as one batch"
        assert np.sum(c["summary/at_rest"][:]) >= 6 and np.max(c["summary/t_final"][:]) > 3.0
    for index in (1, 4, 7):
        with h5py.File(tmp_path / "campaign.h5", "r") as c:
            resistance, spin = float(c["case/rolling_resistance"][index]), float(c["case/omega"][index][2])
        alone = (base.replace("omega = 0.0, 0.0, 0.0", f"omega = 0.0, 0.0, {spin!r}")
                 + f"&sweep name = 'rolling_resistance', values = {resistance!r} /\n")
        (tmp_path / "alone.nml").write_text(alone)
        assert run(ellroll, "run", "alone.nml", "-q", "--overwrite", "-o", "alone.h5", cwd=tmp_path).returncode == 0
        with h5py.File(tmp_path / "campaign.h5", "r") as c, h5py.File(tmp_path / "alone.h5", "r") as a:
            for name in ("status", "n_steps", "at_rest", "t_final"):
                assert c[f"summary/{name}"][index] == a[f"summary/{name}"][0], name
            assert abs(int(c["summary/n_rhs"][index]) - int(a["summary/n_rhs"][0])) <= 4 * 60
            for field in ("contact", "omega", "reaction", "energy"):
                expected = a[f"trajectory/{field}"][0]
                np.testing.assert_allclose(c[f"trajectory/{field}"][index], expected, rtol=1e-12,
                                           atol=1e-12 * np.max(np.abs(expected)))
            for figure in ("rest_time", "residual_displacement", "rolling_resistance_energy", "theta_max",
                           "reaction_normal_max", "energy_drift"):
                np.testing.assert_allclose(c[f"summary/{figure}"][index], a[f"summary/{figure}"][0], rtol=1e-12,
                                           atol=1e-15)


def writer(exe):
    """'ellroll VERSION (BUILD build)' as the executable says it."""
    return run(exe, "--version").stdout.strip()


def test_merge_refuses_shards_of_another_version_or_build(ellroll, ellroll_debug, tmp_path):
    """Two programs' results differ in their last bits: a shard written by
    the Debug build, or one whose file says another version, is refused
    (exit 2, both programs named); the Release build's own shards merge."""
    name = write(tmp_path, "&sweep name = 'omega_z', values = 5, 10, 20 /\n")
    release, debug = writer(ellroll), writer(ellroll_debug)
    assert release.endswith(" build)") and "Debug" in debug and release != debug
    for index, exe in ((0, ellroll), (1, ellroll), (1, ellroll_debug)):
        out = f"s{index}{'d' if exe == ellroll_debug else ''}.h5"
        assert run(exe, "run", name, "-q", "--shard", f"{index}/2", "-o", out, cwd=tmp_path).returncode == 0
    with h5py.File(tmp_path / "s1d.h5", "r") as f:
        assert f"ellroll {f.attrs['version']} ({f.attrs['build']} build)" == debug
    result = run(ellroll, "merge", "m.h5", "s0.h5", "s1d.h5", cwd=tmp_path)
    assert result.returncode == 2
    assert f"s1d.h5: written by {debug}; this is {release}, and a merge would mix" in result.stderr, result.stderr
    assert not (tmp_path / "m.h5").exists()
    other = tmp_path / "s1v.h5"
    other.write_bytes((tmp_path / "s1.h5").read_bytes())
    with h5py.File(other, "r+") as f:
        f.attrs["version"] = "0.0.9+git.0000000"
        build = f.attrs["build"]
    result = run(ellroll, "merge", "m.h5", "s1v.h5", "s0.h5", cwd=tmp_path)
    assert result.returncode == 2
    assert f"s1v.h5: written by ellroll 0.0.9+git.0000000 ({build} build); this is {release}" in result.stderr
    assert run(ellroll, "merge", "m.h5", "s0.h5", "s1.h5", cwd=tmp_path).returncode == 0


def test_resume_refuses_a_run_started_by_another_build(ellroll, ellroll_debug, tmp_path):
    """A run the Debug build started and a kill cut short: the Release build
    refuses to resume it (exit 2, both named) and leaves it whole, so that
    the Debug build resumes it; a journal of an earlier format is refused
    the same way."""
    name, _ = killed_run(ellroll_debug, tmp_path)
    release, debug = writer(ellroll), writer(ellroll_debug)
    journal = tmp_path / "out.h5.journal"
    kept = journal.read_bytes()
    result = run(ellroll, "run", name, "-q", "--resume", cwd=tmp_path)
    assert result.returncode == 2
    assert (f"out.h5.journal: this run was started by {debug}; this is {release}, and a resume would mix the "
            "results of two programs") in result.stderr, result.stderr
    assert journal.read_bytes() == kept and (tmp_path / "out.h5.partial").exists()
    older = tmp_path / "older"
    older.mkdir()
    for path in tmp_path.glob("out.h5.*"):
        (older / path.name).write_bytes(path.read_bytes())
    (older / name).write_text((tmp_path / name).read_text())
    with open(older / "out.h5.journal", "r+b") as f:
        f.write(b"ELLROLL7")
    result = run(ellroll, "run", name, "-q", "--resume", cwd=older)
    assert result.returncode == 2
    assert ("out.h5.journal: this run was started by another version of ellroll (journal format 7, not 8); "
            f"this is {release}") in result.stderr, result.stderr
    result = run(ellroll_debug, "run", name, "-q", "--resume", cwd=tmp_path)
    assert result.returncode == 0, result.stderr
    assert_same_datasets(tmp_path / "whole.h5", tmp_path / "out.h5")
    with h5py.File(tmp_path / "out.h5", "r") as f:
        assert f.attrs["build"] in debug
