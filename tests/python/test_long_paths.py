"""Paths as long as the system allows: an input deep in folders (its path
past 1024 characters, each name within 255) is read whole, with a record
file beside it; a path past the system's 4095 is refused in one line; an
output name of 4083 characters (its work file OUT.partial.new is 4095) runs,
one character more is refused before any work, from -o and merge (&output's
file takes 1024 characters);
an output name whose work files of other runs could not be named (240
characters: OUT.h5.rank1.h5.partial passes 255) runs as any other."""
import os

import h5py
import pytest

from conftest import ROOT, run
from test_campaign import write

RECORD = ROOT / "input" / "records" / "SYN1_H1.AT2"


def deep_folder(base, length):
    folder = base
    while len(str(folder)) < length:
        folder = folder / ("d" * 200)
    folder.mkdir(parents=True)
    return folder


def test_an_input_past_1024_characters_is_read_whole(ellroll, tmp_path):
    folder = deep_folder(tmp_path, 1500)
    (folder / "SYN1_H1.AT2").write_bytes(RECORD.read_bytes())
    name = write(folder, "&excitation kind = 'record', record_file = 'SYN1_H1.AT2', 'SYN1_H1.AT2' /\n", t_end=0.1)
    path = folder / name
    assert len(str(path)) > 1500
    for command in (["check"], ["run", "-q"]):
        result = run(ellroll, *command, str(path), "-o", str(tmp_path / "out.h5"), cwd=tmp_path)
        assert result.returncode == 0, (command, result.stderr[-300:])
    with h5py.File(tmp_path / "out.h5", "r") as f:
        assert f["summary/status"][0] == 1


def test_a_path_past_the_system_s_limit_is_refused(ellroll, tmp_path):
    path = "/".join(["x" * 200] * 25)               # 5024 characters
    result = run(ellroll, "check", path, cwd=tmp_path)
    lines = result.stderr.strip().splitlines()
    assert result.returncode == 2 and len(lines) == 1, result.stderr[-300:]
    assert "a path of 5024 characters" in lines[0] and "at most 4095" in lines[0]


def test_an_output_name_runs_up_to_the_limit_its_work_files_leave(ellroll, tmp_path):
    name = write(tmp_path, "", t_end=0.1)
    folder = deep_folder(tmp_path, 3850)        # each name within 255
    base = str(folder) + "/"
    for length in (4083, 4084, 4095):
        output = base + "o" * (length - len(base) - 3) + ".h5"
        assert len(output) == length
        result = run(ellroll, "run", name, "-q", "-o", output, cwd=tmp_path)
        if length == 4083:
            assert result.returncode == 0, result.stderr[-300:]
            assert os.listdir(folder) == [os.path.basename(output)]
            continue
        lines = result.stderr.strip().splitlines()
        assert result.returncode == 2 and len(lines) == 1, result.stderr[-300:]
        assert f"{length} characters; an output's name has at most 4083" in lines[0], lines[0]
        result = run(ellroll, "merge", output, str(folder / os.listdir(folder)[0]), cwd=tmp_path)
        assert result.returncode == 2 and "at most 4083" in result.stderr, result.stderr[-300:]
        assert len(os.listdir(folder)) == 1


@pytest.mark.parametrize("length", [243, 244, 255])
def test_an_output_file_s_own_name_is_at_most_243_characters(ellroll, tmp_path, length):
    """A file name of 244 to 255 characters is a name, but its work file's
    (with .partial.new) is not: refused before any work, saying so."""
    name = write(tmp_path, "", t_end=0.1)
    output = "n" * (length - 3) + ".h5"
    result = run(ellroll, "run", name, "-q", "-o", output, cwd=tmp_path)
    if length == 243:
        assert result.returncode == 0, result.stderr
        return
    assert result.returncode == 2 and len(result.stderr.strip().splitlines()) == 1, result.stderr
    assert f"its file's own name has {length} characters; at most 243" in result.stderr, result.stderr
    assert sorted(os.listdir(tmp_path)) == [name]


def test_an_output_name_too_long_for_other_runs_work_files_runs(ellroll, tmp_path):
    name = write(tmp_path, "", t_end=0.1)
    output = "n" * 237 + ".h5"
    result = run(ellroll, "run", name, "-q", "-o", output, cwd=tmp_path)
    assert result.returncode == 0, result.stderr
    assert sorted(os.listdir(tmp_path)) == sorted([name, output])
