"""A FIFO, a folder or a device given to `summary` or `merge` as a file to
read: refused at once (one line, exit 2), never opened (a FIFO would wait
for a writer), nothing written."""
import os

import pytest

from conftest import run
from test_campaign import write


@pytest.fixture(scope="module")
def folder(ellroll, tmp_path_factory):
    folder = tmp_path_factory.mktemp("nonregular")
    write(folder, "&sweep name = 'omega_z', values = 10, 20 /\n", t_end=0.2)
    for i in range(2):
        assert run(ellroll, "run", "camp.nml", "-q", "--shard", f"{i}/2", "-o", f"s{i}.h5", cwd=folder).returncode == 0
    os.mkfifo(folder / "ff.h5")
    (folder / "dir.h5").mkdir()
    return folder


WHAT = {"ff.h5": "a FIFO (named pipe), not a regular file", "dir.h5": "a folder, not",
        "/dev/null": "a character device, not a regular file"}


@pytest.mark.parametrize("name", ["ff.h5", "dir.h5", "/dev/null"])
@pytest.mark.parametrize("command", [["summary"], ["summary", "--format", "csv"], ["merge", "m.h5", "s0.h5"],
                                     ["merge", "m.h5"]])
def test_a_file_that_is_not_regular_is_refused_at_once(ellroll, folder, command, name):
    before = sorted(os.listdir(folder))
    argv = command + [name] + (["s1.h5"] if command == ["merge", "m.h5"] else [])
    result = run(ellroll, *argv, cwd=folder, timeout=20)
    assert result.returncode == 2, result.stderr
    lines = result.stderr.splitlines()
    assert len(lines) == 1 and lines[0].startswith(f"ellroll: error: {name}: {WHAT[name]}"), result.stderr
    if name != "dir.h5" or command[0] == "merge":
        assert "not a regular file" in lines[0]
    assert result.stdout == "" and sorted(os.listdir(folder)) == before
