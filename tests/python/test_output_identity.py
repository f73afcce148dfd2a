"""A run, resume or merge moves into place only the file it wrote, replaces
only the output it checked when it began (none: only where nothing is),
and removes only its own journal: a file moved to one of the output's names
while it runs stays as it is (docs/campaigns.md). Each case moves another
file to a name while a run of about a second writes (the journal there
shows it has begun), then checks what the run did with it and that a
resume finishes the run to the uninterrupted run's bits."""
import os
import time

import pytest

from conftest import run
from test_campaign import assert_same_datasets
from test_output_safety import LONG, folder_with, start


def other_output(ellroll, folder):
    """Another campaign's finished output beside the run, and its bytes."""
    (folder / "other.nml").write_text((folder / "camp.nml").read_text().replace(f"t_end = {LONG}", "t_end = 0.2"))
    assert run(ellroll, "run", "other.nml", "-q", "-o", "other.h5", cwd=folder).returncode == 0
    return (folder / "other.h5").read_bytes()


def run_with_a_move(ellroll, folder, source, name, *options):
    """Start the run, move source to name once it writes, wait for it."""
    writer = start(ellroll, folder, *options)
    while not (folder / "out.h5.journal").exists() and writer.poll() is None:
        time.sleep(0.002)
    assert writer.poll() is None, "the run ended before the move"
    os.rename(folder / source, folder / name)
    _, stderr = writer.communicate(timeout=120)
    return writer.returncode, stderr


@pytest.mark.parametrize("name, options", [("out.h5", ()), ("out.h5", ("--overwrite",)), ("out.h5.partial", ())],
                         ids=["output-appears", "output-replaced", "partial-replaced"])
def test_a_file_moved_to_the_outputs_names_while_it_runs_stays(ellroll, tmp_path, name, options):
    folder = folder_with(tmp_path, t_end=LONG)
    assert run(ellroll, "run", "camp.nml", "-q", "-o", "whole.h5", cwd=folder).returncode == 0
    theirs = other_output(ellroll, folder)
    if options:                            # --overwrite checks an output of this campaign at the start
        (folder / "out.h5").write_bytes((folder / "whole.h5").read_bytes())
    code, stderr = run_with_a_move(ellroll, folder, "other.h5", name, *options)
    assert code == 3, stderr
    words = {"out.h5": "a file was made at its name while this run wrote it" if not options else
             "not the output this run was to replace (another file was moved to its name while it ran)",
             "out.h5.partial": "not the file this run wrote (another file was moved to its name while it ran)"}
    assert f"ellroll: error: {name}: {words[name]}" in stderr, stderr
    assert (folder / name).read_bytes() == theirs
    assert "out.h5.journal keeps the cases finished so far" in stderr
    if name == "out.h5":
        os.rename(folder / "out.h5", folder / "theirs.h5")
        result = run(ellroll, "run", "camp.nml", "-q", "--resume", cwd=folder)
        assert result.returncode == 0, result.stderr
        assert_same_datasets(folder / "whole.h5", folder / "out.h5")
    assert (folder / ("theirs.h5" if name == "out.h5" else name)).read_bytes() == theirs


def test_a_file_moved_to_the_journals_name_while_it_runs_is_left_alone(ellroll, tmp_path):
    folder = folder_with(tmp_path, t_end=LONG)
    (folder / "notes.txt").write_text("my notes\n")
    code, stderr = run_with_a_move(ellroll, folder, "notes.txt", "out.h5.journal")
    assert code == 0, stderr
    assert "out.h5.journal: not the journal this run wrote (another file was moved to its name while it ran); " \
           "left as it is" in stderr
    assert (folder / "out.h5.journal").read_text() == "my notes\n" and (folder / "out.h5").exists()


def test_a_resume_never_replaces_another_campaigns_output(ellroll, tmp_path):
    """A run killed, another campaign's output put at its name: --resume
    refuses it (exit 3), leaving both; moved away, the resume finishes."""
    folder = folder_with(tmp_path, t_end=LONG)
    assert run(ellroll, "run", "camp.nml", "-q", "-o", "whole.h5", cwd=folder).returncode == 0
    theirs = other_output(ellroll, folder)
    writer = start(ellroll, folder)
    while not (folder / "out.h5.journal").exists() and writer.poll() is None:
        time.sleep(0.002)
    writer.kill()
    writer.wait()
    os.rename(folder / "other.h5", folder / "out.h5")
    result = run(ellroll, "run", "camp.nml", "-q", "--resume", cwd=folder)
    assert result.returncode == 3
    assert "out.h5: holds the output of another input, which a resume never replaces; move it away, " \
           "then resume" in result.stderr, result.stderr
    assert (folder / "out.h5").read_bytes() == theirs and (folder / "out.h5.journal").exists()
    os.rename(folder / "out.h5", folder / "theirs.h5")
    result = run(ellroll, "run", "camp.nml", "-q", "--resume", cwd=folder)
    assert result.returncode == 0, result.stderr
    assert_same_datasets(folder / "whole.h5", folder / "out.h5")


def test_a_refused_command_leaves_a_killed_runs_lock_as_it_found_it(ellroll, tmp_path):
    """A run killed: its lock names its command line. A plain run again
    (exit 3, an interrupted run exists) and a resume of another input
    (exit 2) are refused and leave that note in place, so that every reader
    still names the command that finishes the run; that resume does."""
    folder = folder_with(tmp_path, t_end=LONG)
    writer = start(ellroll, folder)
    while not (folder / "out.h5.journal").exists() and writer.poll() is None:
        time.sleep(0.002)
    writer.kill()
    writer.wait()
    note = (folder / "out.h5.lock").read_bytes()
    assert b"ellroll run camp.nml -q --threads 1" in note
    (folder / "other.nml").write_text((folder / "camp.nml").read_text().replace(f"t_end = {LONG}", "t_end = 0.2"))
    for command, code in ((["camp.nml", "-q"], 3), (["other.nml", "-q", "-o", "out.h5", "--resume"], 2)):
        result = run(ellroll, "run", *command, cwd=folder)
        assert result.returncode == code, result.stderr
        assert (folder / "out.h5.lock").read_bytes() == note, command
    result = run(ellroll, "summary", "out.h5.partial", cwd=folder)
    assert "finish it with 'ellroll run camp.nml -q --threads 1 --resume'" in result.stderr, result.stderr
    assert run(ellroll, "run", "camp.nml", "-q", "--threads", "1", "--resume", cwd=folder).returncode == 0
    assert not (folder / "out.h5.lock").exists()
