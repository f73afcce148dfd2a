"""The switches of regime in the file (/switches) and its readers: the
times located inside the steps (rk4 at dt 1e-4 against vern9 at rtol
1e-12), the same bits through a resume after kill -9, shards and merge and
any thread count, nothing stored for a campaign that cannot slide."""
import os
import struct
import subprocess

import h5py
import numpy as np
import pytest

from conftest import FULL, PAPER_INPUT, run, run_shards_and_merge
from test_campaign import JOURNAL_HEADER, RECORD_MARKER, WALL_TIME_ENTRY, assert_same_datasets, kill_after_records, record_bytes
from test_sliding_truth import run_case

import ellroll_post


def switches(path, case=0):
    """(times, kinds) of a case, read with h5py alone."""
    with h5py.File(path, "r") as f:
        group = f["switches"]
        first, count = group["first"][case], group["count"][case]
        assert group["switch_time"].attrs["units"] == "s"
        assert group["switch_kind"].attrs["flag_meanings"] == "to_sliding to_rolling"
        assert list(group["switch_kind"].attrs["flag_values"]) == [1, 2]
        return group["switch_time"][first:first + count], group["switch_kind"][first:first + count]


def shaken_as_the_unit_test(ellroll, folder, name, integration, factor=1.3):
    """tests/unit/test_slide_switches.f90's case, its inputs computed as
    there, to the last bit (factor: the amplitude over the slip threshold)."""
    mu, frequency, k, g, r = 0.05, 1.25, 0.4, 9.81, 0.2
    w = 2 * np.pi * frequency
    direction = np.array([2.0, 1.0]) / np.sqrt(5.0)
    factors = direction / ((1 + k) * w**2 - g / np.array([1.0 / 0.2 - r, 0.16 / 0.2 - r]))
    threshold = mu * g / (k * w**2 * np.linalg.norm(factors))
    amplitude = factor * threshold
    velocity = [float(v) for v in amplitude * factors * w]
    ax, ay = (float(v) for v in amplitude * direction)
    excitation = (f"&excitation kind = 'harmonic', amplitude = {ax!r}, {ay!r}, 0.0, "
                  f"frequency = {frequency}, phase = 0.0 /")
    run_case(ellroll, folder, name, mu=mu, omega=f"{-velocity[1] / r!r}, {velocity[0] / r!r}, 0.0",
             integration=integration, t_end=3.0, excitation=excitation, fields="'none'")


def test_rk4_switch_times_agree_with_vern9_in_the_file(ellroll, tmp_path):
    """The paper cup shaken at 1.3 A* (mu 0.05) for 3 s slides twice a cycle:
    15 switches, sliding first. rk4 at dt 1e-4 s puts every one within 5e-9 s
    of vern9 at rtol 1e-12 (3.0e-9 s at most: the slip's error from the
    substeps near a slow stop, over its approach rate)."""
    shaken_as_the_unit_test(ellroll, tmp_path, "vern9", "method = 'vern9', rtol = 1e-12")
    shaken_as_the_unit_test(ellroll, tmp_path, "rk4", "method = 'rk4', dt = 1e-4")
    reference, reference_kinds = switches(tmp_path / "vern9.h5")
    times, kinds = switches(tmp_path / "rk4.h5")
    assert len(reference) == 15 and list(reference_kinds) == [1, 2] * 7 + [1]
    assert list(kinds) == list(reference_kinds)
    errors = np.abs(times - reference)
    assert errors.max() < 5e-9, errors
    with h5py.File(tmp_path / "rk4.h5", "r") as f:
        assert f["summary/slip_episodes"][0] == 8                    # every switch into sliding
        assert list(f["switches/case"][:]) == [0] and list(f["switches/switch"][:]) == list(range(15))
    with ellroll_post.open(tmp_path / "rk4.h5") as out:
        read_times, names = out.switches(0)
    assert read_times.tobytes() == times.tobytes()
    assert list(names) == ["to_sliding", "to_rolling"] * 7 + ["to_sliding"]


@pytest.mark.parametrize("factor", [1.3, 1.5])
def test_rk4_at_a_coarse_step_puts_every_switch_near_vern9s(ellroll, tmp_path, factor):
    """The shaken cup at 1.3 and 1.5 A*, rk4 at dt 1e-3 against vern9 at rtol
    1e-12: the switches into sliding within 1e-10 s (the state's error there
    is rk4's, 1.4e-11 s), the stops within 2e-7 s (9.1e-8 s at 1.5 A*, where
    the slip turns by a right angle as it falls to 1e-8 m/s, and the stop is
    taken there). A stop that substeps find inside a partial step is where
    they find it, not at the partial step's end."""
    shaken_as_the_unit_test(ellroll, tmp_path, "vern9", "method = 'vern9', rtol = 1e-12", factor)
    shaken_as_the_unit_test(ellroll, tmp_path, "rk4", "method = 'rk4', dt = 1e-3", factor)
    reference, reference_kinds = switches(tmp_path / "vern9.h5")
    times, kinds = switches(tmp_path / "rk4.h5")
    assert len(reference) == 15 and list(kinds) == list(reference_kinds) == [1, 2] * 7 + [1]
    errors = np.abs(times - reference)
    assert errors[kinds == 1].max() < 1e-10 and errors[kinds == 2].max() < 2e-7, errors


def test_rk4_takes_a_turned_slip_to_its_zero(ellroll, tmp_path):
    """At 1.5 A* the slip turns by more than a right angle while it falls
    below 1e-7 m/s: the rest of it reaches zero with the friction against the
    slip itself, not against the piece's start, so rk4 at dt 1e-4 and 2.5e-5 s
    puts every stop within 1e-8 s of vern9 at rtol 1e-12 (5.8e-9 and 2.9e-9 s
    measured; the turn is stopped at once without it, 3.0e-8 and 5.2e-8 s
    early), the starts within 1e-10 s."""
    shaken_as_the_unit_test(ellroll, tmp_path, "vern9", "method = 'vern9', rtol = 1e-12", 1.5)
    reference, reference_kinds = switches(tmp_path / "vern9.h5")
    for dt in ("1e-4", "2.5e-5"):
        shaken_as_the_unit_test(ellroll, tmp_path, f"rk4_{dt}", f"method = 'rk4', dt = {dt}", 1.5)
        times, kinds = switches(tmp_path / f"rk4_{dt}.h5")
        assert list(kinds) == list(reference_kinds) == [1, 2] * 7 + [1], dt
        errors = np.abs(times - reference)
        assert errors[kinds == 1].max() < 1e-10 and errors[kinds == 2].max() < 1e-8, (dt, errors)


def test_a_campaign_that_cannot_slide_stores_no_switches(ellroll, tmp_path):
    result = run(ellroll, "run", PAPER_INPUT, "-q", "-o", "paper.h5", cwd=tmp_path)
    assert result.returncode == 0, result.stderr
    with h5py.File(tmp_path / "paper.h5", "r") as f:
        assert "switches" not in f and "regime" not in f["trajectory"]
    with ellroll_post.open(tmp_path / "paper.h5") as out, pytest.raises(ellroll_post.NotAnEllrollFile):
        out.switches(0)


# mu from 0.02 to 0.2 on the paper cup shaken at 1.5, 0.5 m/s^2: from many
# slip episodes to none (the larger mu roll throughout)
CAMPAIGN = """&geometry a = 1.0, b = 0.4, c = 0.2 /
&ball radius = 0.2, mass = 1.0, mu = 0.1, slip = 'slide' /
&initial x = 0.0, y = 0.0, omega = 0.0, 0.0, 0.0 /
&integration method = 'rk4', dt = 1e-3, t_end = {t_end} /
&excitation kind = 'harmonic', amplitude = 1.5, 0.5, 0.0, frequency = 0.8 /
&sweep name = 'mu', start = 0.02, stop = 0.2, count = {count}, spacing = 'log' /
&output file = 'out.h5', interval = 0.01, fields = 'center', compression = {compression} /
"""


def campaign(folder, count=24, t_end=2.0, compression=0):
    (folder / "camp.nml").write_text(CAMPAIGN.format(count=count, t_end=t_end, compression=compression))
    return "camp.nml"


def test_switches_are_the_same_bits_for_any_thread_count_and_through_shards_and_merge(ellroll, tmp_path):
    name = campaign(tmp_path)
    assert run(ellroll, "run", name, "-q", "--threads", "1", "-o", "one.h5", cwd=tmp_path).returncode == 0
    assert run(ellroll, "run", name, "-q", "--threads", "2", "-o", "two.h5", cwd=tmp_path).returncode == 0
    assert_same_datasets(tmp_path / "one.h5", tmp_path / "two.h5")
    with h5py.File(tmp_path / "one.h5", "r") as f:
        count, first = f["switches/count"][:], f["switches/first"][:]
        assert count.max() >= 4 and count[-1] == 0 and np.all(count >= 0)
        assert list(first) == list(np.concatenate([[0], np.cumsum(count)[:-1]]))
        assert len(f["switches/switch_time"]) == count.sum()
        assert list(count[count > 0] // 2 + count[count > 0] % 2) == \
            list(f["summary/slip_episodes"][:][count > 0])
    run_shards_and_merge(ellroll, name, tmp_path, (1, 2, 0))
    assert_same_datasets(tmp_path / "one.h5", tmp_path / "merged.h5")


@pytest.mark.parametrize("compression", [0, 4])
def test_switches_survive_kill_and_resume(ellroll, tmp_path, compression):
    """kill -9 at random moments, then --resume: the journal's records carry
    each case's switches (records of several sizes), the file holds the
    uninterrupted run's bits. (48 cases with ELLROLL_TEST_FULL.)"""
    import random
    name = campaign(tmp_path, count=48 if FULL else 24, compression=compression)
    assert run(ellroll, "run", name, "-q", "-o", "whole.h5", cwd=tmp_path).returncode == 0
    journal = tmp_path / "out.h5.journal"
    rng = random.Random(5)
    kills = 0
    for attempt in range(6):
        args = [str(ellroll), "run", name, "-q", "--threads", "2"] + (["--resume"] if kills else [])
        # the journal grows by a batch of cases at a time: on a loaded machine the
        # run may end before the kill lands, and then the first try starts again
        if not kill_after_records(args, tmp_path, journal, 3, record_bytes(), rng.uniform(0.0, 0.02)) \
                or not journal.exists():
            if kills or attempt == 5:
                break
            (tmp_path / "out.h5").unlink(missing_ok=True)
            continue
        kills += 1
        if kills == 3:
            break
    if not (tmp_path / "out.h5").exists():
        result = run(ellroll, "run", name, "-q", "--resume", cwd=tmp_path)
        assert result.returncode == 0, result.stderr
        assert "run again" not in result.stderr
    assert kills >= 1
    assert_same_datasets(tmp_path / "whole.h5", tmp_path / "out.h5")
    with h5py.File(tmp_path / "out.h5", "r") as f:
        assert f["switches/count"][:].max() >= 4


def test_the_python_api_gives_the_files_switches(ellroll, tmp_path):
    ellroll_api = pytest.importorskip("ellroll")
    name = campaign(tmp_path, count=8)
    assert run(ellroll, "run", name, "-q", "-o", "file.h5", cwd=tmp_path).returncode == 0
    text = (tmp_path / name).read_text()
    arrays, attributes = ellroll_api.run_arrays(text, threads=2)
    tree = ellroll_api.run(text, threads=1)
    with h5py.File(tmp_path / "file.h5", "r") as f:
        assert sorted(arrays["switches"]) == sorted(f["switches"])
        for key in f["switches"]:
            assert np.array_equal(arrays["switches"][key], f["switches"][key][:]), key
            assert np.array_equal(tree["switches"][key].values, f["switches"][key][:]), key
            assert attributes["switches"][key]["units"] == f["switches"][key].attrs["units"]
        assert f["switches/count"][:].max() >= 4
    assert attributes["switches"]["switch_kind"]["flag_meanings"] == "to_sliding to_rolling"
    assert "switches" not in ellroll_api.run(PAPER_INPUT.read_text().replace("t_end = 30.0", "t_end = 1.0")).children


def journal_records(path):
    """[(offset, slot, number of switches)] of a journal's records in
    order, each found where the one before it ends (their sizes differ)."""
    data = path.read_bytes()
    fixed = record_bytes() // 8 - 2                  # the part of one size (no trajectories in the record)
    at, out = JOURNAL_HEADER, []
    while at + 8 * (fixed + 2) <= len(data):
        words = struct.unpack(f"<{fixed + 1}q", data[at:at + 8 * (fixed + 1)])
        assert words[0] == RECORD_MARKER
        out.append((at, words[1], words[fixed]))
        at += 8 * (fixed + 2 + 2 * words[fixed])
    return out


@pytest.mark.parametrize("damage", ["zeroed", "bits"])
def test_a_damaged_record_with_switches_runs_its_case_again_and_keeps_the_rest(ellroll, tmp_path, damage):
    """A kill after every case was journaled (strace kills at the unlink
    that follows), then the first record that holds switches is zeroed (a
    place never written) or has a bit of its switches flipped: the resume
    finds the records after it by their marker, keeps them, runs that case
    again, and the file is the uninterrupted run's."""
    name = campaign(tmp_path, count=6)
    assert run(ellroll, "run", name, "-q", "-o", "whole.h5", cwd=tmp_path).returncode == 0
    killed = subprocess.run(["strace", "-f", "-o", os.devnull, "-e", "inject=unlink:signal=SIGKILL:when=1",
                             str(ellroll), "run", name, "-q", "--threads", "1"], cwd=tmp_path)
    assert killed.returncode != 0
    (tmp_path / "out.h5").rename(tmp_path / "out.h5.partial")
    journal = tmp_path / "out.h5.journal"
    records = journal_records(journal)
    assert sorted(slot for _, slot, _ in records) == list(range(6))
    offset, slot, n = next(r for r in records if r[2] > 0)
    size = record_bytes() + 16 * n
    with open(journal, "r+b") as f:
        if damage == "zeroed":
            f.seek(offset)
            f.write(bytes(size))
        else:
            f.seek(offset + size - 8 * n - 16)       # a switch's time
            byte = f.read(1)[0]
            f.seek(offset + size - 8 * n - 16)
            f.write(bytes([byte ^ 4]))
    data = journal.read_bytes()
    result = run(ellroll, "run", name, "-q", "--resume", cwd=tmp_path)
    assert result.returncode == 0, result.stderr
    if damage == "bits":
        assert "1 damaged records skipped" in result.stderr and "1 of 6 cases have no valid record" in result.stderr, \
            result.stderr
    assert_same_datasets(tmp_path / "whole.h5", tmp_path / "out.h5")
    # the records after the damaged one were kept: their cases' wall times are the journal's
    with h5py.File(tmp_path / "out.h5", "r") as f:
        wall = f["summary/wall_time"][:]
    later = [(at, kept) for at, kept, _ in records if at > offset]
    assert later
    for at, kept in later:
        assert struct.unpack("<d", data[at + 8 * (3 + 3 * WALL_TIME_ENTRY):][:8])[0] == wall[kept]


GRAZE = """&geometry a = 1.0, b = 0.4, c = 0.2 /
&ball radius = 0.2, weight = 2620.0{mu} /
&initial x = 0.1, y = 0.05, omega = 1, -2, 30 /
&integration method = '{method}', rtol = {rtol}, t_end = 3.0 /
&output file = 'g.h5', interval = 0.5, fields = 'none' /
"""


@pytest.mark.parametrize("method", ["dop853", "vern9"])
@pytest.mark.parametrize("margin", [1e-3, 1e-5])
def test_a_slip_that_grazes_mu_inside_a_long_step_is_met(ellroll, tmp_path, method, margin):
    """mu just below the largest friction the rolling ball needs (its
    maximum over the step ends at rtol 1e-12, less a margin): the friction
    needed passes mu N for a moment. At rtol 1e-6 the steps are long, and
    both ends of the step can lie below: the slide starts where slip =
    'end' ends (its search on the dense output), within the method's
    accuracy there."""
    def summary(mu, rtol, name):
        (tmp_path / f"{name}.nml").write_text(GRAZE.format(mu=mu, method=method, rtol=rtol))
        result = run(ellroll, "run", f"{name}.nml", "-q", "-o", f"{name}.h5", cwd=tmp_path)
        assert result.returncode == 0, result.stderr
        return tmp_path / f"{name}.h5"
    with h5py.File(summary("", 1e-12, "rolling"), "r") as f:
        mu = float(f["summary/friction_needed_max"][0] * (1 - margin))
    with h5py.File(summary(f", mu = {mu!r}, slip = 'end'", 1e-6, "end"), "r") as f:
        assert f["summary/status"][0] == 4                   # slip
        t_slip = f["summary/t_final"][0]
    times, kinds = switches(summary(f", mu = {mu!r}, slip = 'slide'", 1e-6, "slide"))
    assert len(times) >= 2 and kinds[0] == 1                # slides, and rolls again
    assert abs(times[0] - t_slip) < 1e-5                    # 1.3e-6 s measured


@pytest.mark.parametrize("dt", [2e-2, 1e-2])
def test_a_slip_that_grazes_mu_between_fixed_step_ends_is_met(ellroll, tmp_path, dt):
    """rk4 with mu halfway between the largest friction needed at its own
    step ends and the largest at vern9's (rtol 1e-12, steps of 1e-4 s at
    most): the friction needed passes mu N only between two step ends.
    slip = 'end' finds it (the limit at the stages); the slide starts
    there too (the parabola through three step ends)."""
    def output(mu, integration, name):
        text = GRAZE.replace("method = '{method}', rtol = {rtol}", "{integration}")
        (tmp_path / f"{name}.nml").write_text(text.format(mu=mu, integration=integration))
        result = run(ellroll, "run", f"{name}.nml", "-q", "-o", f"{name}.h5", cwd=tmp_path)
        assert result.returncode == 0, result.stderr
        return tmp_path / f"{name}.h5"
    rk4 = f"method = 'rk4', dt = {dt}"
    with h5py.File(output("", "method = 'vern9', rtol = 1e-12, dt = 1e-4", "fine"), "r") as f:
        peak = f["summary/friction_needed_max"][0]
    with h5py.File(output("", rk4, "coarse"), "r") as f:
        at_step_ends = f["summary/friction_needed_max"][0]
    assert at_step_ends < peak
    mu = float((peak + at_step_ends) / 2)
    with h5py.File(output(f", mu = {mu!r}, slip = 'end'", rk4, "end"), "r") as f:
        assert f["summary/status"][0] == 4
        t_slip = f["summary/t_final"][0]
    times, kinds = switches(output(f", mu = {mu!r}, slip = 'slide'", rk4, "slide"))
    assert len(times) >= 2 and kinds[0] == 1
    assert abs(times[0] - t_slip) < 1e-5                    # 2.9e-6 s (dt 2e-2), 1.1e-7 s (1e-2) measured


SLIP_BEFORE_NO_FIT = """&geometry a = 1.0, b = 0.4, c = 0.2 /
&ball radius = 0.2, weight = 2620.0, mu = 0.20411491139823162, slip = '{slip}' /
&initial x = -0.051375778168383734, y = 0.0593546051480669, omega = -2.6238600990030667, -4.891228461708808, -3.282479430530529 /
&integration method = 'rk4', dt = 1e-3, t_end = 5.0 /
&excitation kind = 'harmonic', amplitude = 1.0, 0.5, 0.0, frequency = 0.7 /
&output file = 'o.h5', interval = 0.01, fields = 'none' /
"""


def test_a_slip_inside_the_step_that_meets_a_limit_comes_first(ellroll, tmp_path):
    """A shaken ball whose friction needed passes mu N 0.5 ms before it
    meets no_fit, both inside one rk4 step: slip = 'end' ends at the slip;
    slip = 'slide' slides from there (not ending at no_fit without sliding),
    then meets no_fit later."""
    out = {}
    for slip in ("end", "slide"):
        (tmp_path / f"{slip}.nml").write_text(SLIP_BEFORE_NO_FIT.format(slip=slip))
        result = run(ellroll, "run", f"{slip}.nml", "-q", "-o", f"{slip}.h5", cwd=tmp_path)
        assert result.returncode == 0, result.stderr
        with h5py.File(tmp_path / f"{slip}.h5", "r") as f:
            out[slip] = (f["summary/status"][0], f["summary/t_final"][0])
    assert out["end"][0] == 4                                # slip, at 0.748036 s
    times, kinds = switches(tmp_path / "slide.h5")
    assert len(times) >= 1 and kinds[0] == 1
    assert abs(times[0] - out["end"][1]) < 1e-5              # 6.8e-7 s measured
    assert out["slide"][0] == 3 and out["slide"][1] > times[0]   # no_fit, after the slide began


# Starts whose rolling friction at t = 0 is above mu, no velocity given (seeded
# fuzz cases): a fixed cup, vern9 and rk4
MUST_SLIDE_AT_ONCE = {
    "vern9": """&geometry a=0.5, b=0.162272204724216, c=0.7931880244875041 /
&ball radius=0.009481447951150569, mass=100.0, mu=0.016467004862557345, slip='slide', inertia_factor=0.4 /
&initial x=0.04491986272897186, y=-0.012798163508954003, omega=-4.273257349183711,3.5257076356101624,9.479883844789518 /
&integration method='vern9', rtol=1e-06, t_end=1.0 /
&output file='o.h5', interval=0.01 /
""",
    "rk4": """&geometry a=0.5, b=0.22360749859437612, c=0.33007612994043123 /
&ball radius=0.01908846954761211, mass=100.0, mu=0.09496275847030129, slip='slide', inertia_factor=0.6666666666666666 /
&initial x=-0.06186509510359414, y=-0.04045611463825726, omega=3.38115771499748,3.921610435820335,0.8645794892093353 /
&integration method='rk4', dt=1e-3, t_end=1.0 /
&output file='o.h5', interval=0.01 /
""",
}


def start_reaction(path):
    with h5py.File(path, "r") as f:
        force, normal = f["trajectory/reaction"][0, 0], f["trajectory/normal"][0, 0]
        regime = f["trajectory/regime"][0, 0] if "trajectory/regime" in f else None
        episodes = int(f["summary/slip_episodes"][0])
    normal_force = force @ normal
    return force, normal_force, force - normal_force * normal, regime, episodes


@pytest.mark.parametrize("method", sorted(MUST_SLIDE_AT_ONCE))
def test_a_start_that_must_slide_at_once_stores_mu_along_rollings_need_and_its_switch(ellroll, ellroll_debug,
                                                                                       tmp_path, method):
    """At t = 0 the slip is round-off: the sample there holds the sliding
    state's reaction with the friction mu N along the direction of the
    friction rolling needs (slip = 'end''s t = 0 sample), the same in the
    Release and Debug builds to round-off, and /switches holds the
    to_sliding switch at t = 0, so that slip_episodes counts the to_sliding
    switches."""
    text = MUST_SLIDE_AT_ONCE[method]
    mu = float(text.split("mu=")[1].split(",")[0])
    (tmp_path / "slide.nml").write_text(text)
    (tmp_path / "end.nml").write_text(text.replace("slip='slide', ", ""))
    outputs = {}
    for name, exe in (("release", ellroll), ("debug", ellroll_debug)):
        result = run(exe, "run", "slide.nml", "-q", "-o", f"{name}.h5", cwd=tmp_path, timeout=300)
        assert result.returncode == 0, result.stderr
        outputs[name] = start_reaction(tmp_path / f"{name}.h5")
    result = run(ellroll, "run", "end.nml", "-q", "-o", "end.h5", cwd=tmp_path)
    assert result.returncode == 0, result.stderr
    _, _, needed, _, _ = start_reaction(tmp_path / "end.h5")
    assert np.linalg.norm(needed) > 1.05 * mu * (outputs["release"][1])          # rolling's need is above mu
    for name, (force, normal_force, tangential, regime, episodes) in outputs.items():
        assert regime == 1, name
        assert abs(np.linalg.norm(tangential) / normal_force - mu) <= 1e-12 * mu, name
        assert tangential @ needed / np.linalg.norm(tangential) / np.linalg.norm(needed) > 1 - 1e-12, name
        times, kinds = ellroll_post.open(tmp_path / f"{name}.h5").switches(0)
        assert times[0] == 0.0 and kinds[0] == "to_sliding", (name, times, kinds)
        assert episodes == list(kinds).count("to_sliding") >= 1, (name, episodes, list(kinds))
    release, debug = outputs["release"][0], outputs["debug"][0]
    assert np.abs(release - debug).max() <= 1e-9 * np.abs(release).max(), (release, debug)
