"""Rolling resistance with the embedded pairs: where the rolling part of
omega turns by a right angle inside a long step without stopping (it turns
in 3D at a rate the couple takes much longer than the step to stop), the
step is cut there and the ball rolls on (docs/model.md, "The stop is an
event"); only a turn the step cannot resolve is a stop. Truth: vern9 at
rtol 1e-13, whose steps resolve every turn; each pair's contact point stays
within 100 rtol metres of it (a stop taken at such a turn drops the rolling
of 0.2-1.6 rad/s and puts the ball centimetres off)."""
import random

import h5py
import numpy as np
import pytest

from conftest import run


def _case(seed, method):
    rng = random.Random(seed)
    omega = [rng.uniform(-3, 3), rng.uniform(-3, 3), rng.uniform(-25, 25)]
    x, y = rng.uniform(-0.15, 0.15), rng.uniform(-0.06, 0.06)
    delta = rng.choice([2e-4, 5e-4, 1e-3])
    shaking = ""
    if seed % 2 == 0:
        shaking = (f"&excitation kind = 'harmonic', amplitude = {rng.uniform(0.2, 1.0)!r}, {rng.uniform(0.0, 0.5)!r}, "
                   f"0.0, frequency = {rng.uniform(0.2, 0.6)!r} /\n")
    return ("&geometry a = 1.0, b = 0.4, c = 0.2 /\n"
            f"&ball radius = 0.2, weight = 2620.0, rolling_resistance = {delta!r} /\n"
            f"&initial x = {x!r}, y = {y!r}, omega = {omega[0]!r}, {omega[1]!r}, {omega[2]!r} /\n"
            f"&integration {method}, t_end = 10.0 /\n" + shaking
            + "&output file = 'o.h5', interval = 0.01, fields = 'contact' /\n")


def _contact(exe, folder, name, text):
    (folder / f"{name}.nml").write_text(text)
    done = run(exe, "run", f"{name}.nml", "-q", "-o", f"{name}.h5", cwd=folder)
    assert done.returncode == 0, done.stderr
    with h5py.File(folder / f"{name}.h5") as f:
        return f["trajectory/contact"][0], f["summary/status"][0]


@pytest.mark.parametrize("seed", [1, 2, 3, 4, 5, 6, 7, 8])
def test_pairs_roll_on_through_a_turn(ellroll, tmp_path, seed):
    truth, status = _contact(ellroll, tmp_path, "truth", _case(seed, "method = 'vern9', rtol = 1e-13"))
    assert status == 1
    for pair, rtol in (("dop853", 1e-4), ("dop853", 1e-5), ("dop853", 1e-6), ("vern9", 1e-4), ("vern9", 1e-6)):
        contact, status = _contact(ellroll, tmp_path, f"{pair}_{rtol}", _case(seed, f"method = '{pair}', rtol = {rtol}"))
        assert status == 1
        error = np.max(np.abs(contact - truth))
        assert error <= 100 * rtol, (pair, rtol, error)
