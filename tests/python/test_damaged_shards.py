"""Each case's checksum (/summary/checksum, docs/output.md): the CRC-32C of
what the file holds of the case, laid out as docs/output.md says, the same
for a case run alone, in a shard or on any thread count. `ellroll merge`
checks every case of every shard against it: a shard with bytes damaged in
a case's trajectories, figures, checksum or switches (seeded random places,
found through h5py's file offsets) is refused with exit 2, naming the shard
and the case, and no output is left (docs/campaigns.md)."""
import random
import shutil
import sys

import h5py
import numpy as np
import pytest

from conftest import ROOT, run

sys.path.insert(0, str(ROOT / "post"))       # this tree's Python package, as test_python_api takes it
import ellroll_post  # noqa: E402

# a cup shaken hard enough that the low mu slide (switches of regime), with
# every field stored
CAMPAIGN = """&geometry a = 1.0, b = 0.4, c = 0.2 /
&ball radius = 0.2, mass = 1.0, mu = 0.1, slip = 'slide' /
&initial x = 0.0, y = 0.0, omega = 0.0, 0.0, 0.0 /
&integration method = 'rk4', dt = 1e-3, t_end = 2.0 /
&excitation kind = 'harmonic', amplitude = 1.5, 0.5, 0.0, frequency = 0.8 /
&sweep name = 'mu', start = 0.02, stop = 0.2, count = 6, spacing = 'log' /
&output file = 'out.h5', interval = 0.01, fields = 'all', compression = {compression} /
"""
WORK_NAMES = ["m.h5", "m.h5.partial", "m.h5.lock"]


def _crc_table():
    table = []
    for byte in range(256):
        crc = byte
        for _ in range(8):
            crc = (crc >> 1) ^ (0x82F63B78 if crc & 1 else 0)
        table.append(crc)
    return table


CRC_TABLE = _crc_table()


def crc32c(data, crc=0):
    """CRC-32C (Castagnoli), continued from crc as zlib's crc32 is."""
    crc ^= 0xFFFFFFFF
    for byte in data:
        crc = (crc >> 8) ^ CRC_TABLE[(crc ^ byte) & 0xFF]
    return crc ^ 0xFFFFFFFF


def documented_checksum(f, slot):
    """The checksum of the case in `slot` as docs/output.md lays it out."""
    crc = 0
    for name in ("contact", "center", "omega", "normal", "nutation", "reaction", "energy",
                 "base_acceleration", "regime", "slip_speed"):
        if f"trajectory/{name}" in f:
            crc = crc32c(np.ascontiguousarray(f[f"trajectory/{name}"][slot], "<f8").tobytes(), crc)
    words = [np.int64(f["summary/status"][slot]).tobytes()]
    coordinates = f["summary/status"].attrs["coordinates"].split()
    for name in f["summary"]:
        if name in {"case", "status", "checksum", "wall_time", *coordinates}:
            continue
        dataset = f[f"summary/{name}"]
        words.append(np.ascontiguousarray(dataset[slot], "<i8" if dataset.dtype.kind == "i" else "<f8").tobytes())
    first, count = (int(f["switches/first"][slot]), int(f["switches/count"][slot])) if "switches" in f else (0, 0)
    words.append(np.int64(max(count, 0)).tobytes())
    if count > 0:
        words.append(f["switches/switch_time"][first:first + count].astype("<f8").tobytes())
        words.append(f["switches/switch_kind"][first:first + count].astype("<i8").tobytes())
    return crc32c(b"".join(words), crc)


@pytest.fixture(scope="module", params=[0, 1], ids=["in_place", "compressed"])
def shards(ellroll, tmp_path_factory, request):
    """The campaign run whole and in 2 shards (uncompressed, compressed)."""
    folder = tmp_path_factory.mktemp(f"damaged{request.param}")
    (folder / "c.nml").write_text(CAMPAIGN.format(compression=request.param))
    result = run(ellroll, "run", "c.nml", "-q", "-o", "whole.h5", cwd=folder)
    assert result.returncode == 0, result.stderr
    for i in range(2):
        result = run(ellroll, "run", "c.nml", "-q", "--shard", f"{i}/2", "-o", f"s{i}.h5", "--threads", 2 - i,
                     cwd=folder)
        assert result.returncode == 0, result.stderr
    return folder, request.param


def test_the_checksum_is_the_crc_of_what_the_file_holds_of_the_case(shards):
    folder, _ = shards
    with h5py.File(folder / "whole.h5", "r") as whole:
        stored = whole["summary/checksum"]
        assert stored.dtype == np.int64 and stored.attrs["units"] == "1"
        assert "CRC-32C" in stored.attrs["long_name"] and stored.attrs["_FillValue"] == -1
        assert (whole["switches/count"][:] > 0).any(), "some case slides"
        expected = [documented_checksum(whole, slot) for slot in range(whole["summary/case"].shape[0])]
        assert list(stored[:]) == expected
        by_case = dict(zip(whole["summary/case"][:], stored[:]))
    for i in range(2):
        with h5py.File(folder / f"s{i}.h5", "r") as shard:
            # the same case, the same checksum, on another thread count and shard split
            assert [by_case[c] for c in shard["summary/case"][:]] == list(shard["summary/checksum"][:])
        with ellroll_post.open(folder / f"s{i}.h5") as opened:
            assert "checksum" not in opened.summary_figures      # not a figure of the case


def damage_places(path, seed, n):
    """n places (file offset, length, what, slot) inside the raw data of
    one case of the shard: its trajectories, figures, checksum or switches."""
    rng = random.Random(seed)
    places = []
    with h5py.File(path, "r") as f:
        n_cases = f["summary/case"].shape[0]
        coordinates = f["summary/status"].attrs["coordinates"].split()
        targets = [f"trajectory/{name}" for name in f["trajectory"]
                   if name not in {"case", "time", *coordinates}]
        targets += [f"summary/{name}" for name in f["summary"]
                    if name not in {"case", "wall_time", *coordinates}]
        sliding = [slot for slot in range(n_cases) if f["switches/count"][slot] > 0]
        for k in range(n):
            if k % 5 == 4 and sliding:      # a switch time of a case that slides
                slot = rng.choice(sliding)
                what = "switches/switch_time"
                first, count = int(f["switches/first"][slot]), int(f["switches/count"][slot])
                index = first + rng.randrange(count)
                start, length = f[what].id.get_offset() + 8 * index, 8
            else:
                what = targets[k % len(targets)] if k < len(targets) else rng.choice(targets)
                slot = rng.randrange(n_cases)
                start, length = case_bytes(f[what], slot)
            at = start + rng.randrange(length)
            places.append((at, rng.randint(1, min(8, start + length - at)), what, slot))
    return places


def case_bytes(dataset, slot):
    """Where the case in `slot` lies in the file: (offset, length)."""
    row = int(np.prod(dataset.shape[1:], dtype=np.int64)) * dataset.dtype.itemsize
    if dataset.id.get_offset() is not None:               # contiguous
        return dataset.id.get_offset() + slot * row, row
    info = dataset.id.get_chunk_info_by_coord((slot,) + (0,) * (dataset.ndim - 1))
    if dataset.compression:                               # the whole compressed chunk
        return info.byte_offset, info.size
    return info.byte_offset + (slot - info.chunk_offset[0]) * row, row


def test_merge_refuses_a_shard_damaged_in_any_case(ellroll, shards):
    folder, compression = shards
    places = damage_places(folder / "s1.h5", 20260511 + compression, 24)
    with h5py.File(folder / "s1.h5", "r") as f:
        case_of = list(f["summary/case"][:])
    rng = random.Random(7)
    for at, length, what, slot in places:
        shutil.copy(folder / "s1.h5", folder / "d1.h5")
        with open(folder / "d1.h5", "r+b") as f:
            f.seek(at)
            old = f.read(length)
            f.seek(at)
            f.write(bytes(b ^ rng.randint(1, 255) for b in old))
        result = run(ellroll, "merge", "m.h5", "s0.h5", "d1.h5", cwd=folder)
        where = f"{what} of case {case_of[slot]}"
        assert result.returncode == 2, (where, result.stderr)
        assert "d1.h5: " in result.stderr, (where, result.stderr)
        if not (compression and what.startswith("trajectory/")):       # (deflate may fail first)
            assert f"d1.h5: case {case_of[slot]} is damaged" in result.stderr, (where, result.stderr)
        assert not any((folder / name).exists() for name in WORK_NAMES), where
    # the shards undamaged merge into the single run's file
    assert run(ellroll, "merge", "m.h5", "s1.h5", "s0.h5", cwd=folder).returncode == 0
    with h5py.File(folder / "m.h5", "r") as merged, h5py.File(folder / "whole.h5", "r") as whole:
        for name in ("summary/checksum", "trajectory/contact", "trajectory/regime", "switches/switch_time", "time"):
            assert merged[name][()].tobytes() == whole[name][()].tobytes(), name


@pytest.mark.parametrize("keep", [0.1, 0.5, 0.9])
def test_merge_refuses_a_shard_cut_short_with_exit_2_naming_it(ellroll, shards, tmp_path, keep):
    """A shard cut short (a copy that stopped: HDF5's own tables end before
    the file says they do) ends the merge with exit 2 naming the shard, and
    leaves no output (docs/campaigns.md)."""
    folder, _ = shards
    for i in range(2):
        shutil.copy(folder / f"s{i}.h5", tmp_path / f"s{i}.h5")
    whole = (tmp_path / "s1.h5").read_bytes()
    (tmp_path / "s1.h5").write_bytes(whole[:int(len(whole) * keep)])
    result = run(ellroll, "merge", "m.h5", "s0.h5", "s1.h5", cwd=tmp_path)
    assert result.returncode == 2, result.stderr
    assert "ellroll: error: s1.h5: damaged" in result.stderr, result.stderr
    assert not any((tmp_path / name).exists() for name in WORK_NAMES)


def declared_rows(source, target, rows):
    """source's file rewritten by h5py (libver up to v110) with each numeric
    per-case table declared `rows` long, chunked, its rows past the file's
    own never written (so the file stays small)."""
    with h5py.File(source, "r") as f, h5py.File(target, "w", libver=("earliest", "v110")) as g:
        cases = f["summary/status"].shape[0]
        g.attrs.update(dict(f.attrs))

        def copy(name, item):
            if isinstance(item, h5py.Group):
                g.require_group(name).attrs.update(dict(item.attrs))
                return
            if item.shape and item.shape[0] == cases and item.dtype.kind in "fiu":
                made = g.create_dataset(name, shape=(rows, *item.shape[1:]), dtype=item.dtype,
                                        chunks=(1, *(min(s, 1024) for s in item.shape[1:])))
                made[:cases] = item[()]
            else:
                made = g.create_dataset(name, data=item[()])
            made.attrs.update({k: v for k, v in item.attrs.items()
                               if k not in ("DIMENSION_LIST", "REFERENCE_LIST", "CLASS", "NAME")})
        f.visititems(copy)


@pytest.mark.parametrize("rows", [10**8 + 1, 10**10, 2**40])
def test_tables_declared_longer_than_any_campaign_are_refused_in_one_line(ellroll, shards, tmp_path, rows):
    """A file whose tables say they hold more rows than the 1e8 cases of any
    campaign (another program's rewrite; a few MB on the disk): `ellroll
    summary` (every format) and `merge` refuse it in one line naming it,
    exit 2, before reading its tables whole (80 GB at 1e10 rows, more than
    the memory holds), and merge leaves nothing."""
    folder, _ = shards
    declared_rows(folder / "s1.h5", tmp_path / "big.h5", rows)
    shutil.copy(folder / "s0.h5", tmp_path / "s0.h5")
    for command in (["summary", "big.h5"], ["summary", "big.h5", "--format", "json"], ["summary", "big.h5", "--suite"],
                    ["merge", "m.h5", "s0.h5", "big.h5"]):
        result = run(ellroll, *command, cwd=tmp_path, timeout=60)
        lines = result.stderr.strip().splitlines()
        assert result.returncode == 2 and len(lines) == 1, (command, result.stderr[-2000:])
        assert lines[0].startswith("ellroll: error: big.h5: not laid out as ellroll writes its files") and \
            f"holds {rows} rows" in lines[0], (command, lines)
    assert not any((tmp_path / name).exists() for name in WORK_NAMES)
