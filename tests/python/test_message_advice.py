"""Messages that name the real fault and give one way forward: a &sweep
with both forms or without count, a resume refused for a damaged journal."""
import pytest

from conftest import run
from test_campaign import flip_bits, killed_run, write


@pytest.mark.parametrize("sweep, words", [
    ("values = 1, 2, count = 3", "count = 3: values is given too: give either values = v1, v2, ... or start, "
                                 "stop and count, not both"),
    ("values = 1, 2, start = 1", "start = 1: values is given too"),
    ("start = 1, stop = 2", "count is required but not given: give count = N, how many values from start to stop"),
    ("name = 'omega_z'", "values is required but not given: give either values = v1, v2, ... or start, stop "
                         "and count"),
])
def test_sweep_forms(ellroll, tmp_path, sweep, words):
    text = f"&sweep name = 'omega_z', {sweep} /\n".replace("name = 'omega_z', name = 'omega_z'", "name = 'omega_z'")
    name = write(tmp_path, text)
    result = run(ellroll, "check", name, cwd=tmp_path)
    assert result.returncode == 2
    assert f"camp.nml:6: &sweep: {words}" in result.stderr, result.stderr
    assert len(result.stderr.splitlines()) == 1


def test_a_damaged_journal_header_gives_one_way_forward(ellroll, tmp_path):
    name, _ = killed_run(ellroll, tmp_path)
    journal = tmp_path / "out.h5.journal"
    flip_bits(journal, 8, [3, 10])
    before = journal.read_bytes()
    result = run(ellroll, "run", name, "-q", "--resume", cwd=tmp_path)
    assert result.returncode == 3
    assert result.stderr.strip().endswith("so none of its cases can be trusted; start over with --overwrite"), \
        result.stderr
    assert "--resume" not in result.stderr and len(result.stderr.splitlines()) == 1
    assert journal.read_bytes() == before and (tmp_path / "out.h5.partial").exists()
