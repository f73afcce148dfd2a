"""Messages that name the real fault: a &sweep with both forms or without
count."""
import pytest

from conftest import run
from test_campaign import write


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

