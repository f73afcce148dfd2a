"""The equations of docs/model.md in NumPy, written independently of the
Fortran code: the peer that SciPy integrates in bench/workprecision.py."""
import numpy as np


class RollingBall:
    def __init__(self, a, b, c, radius, g=9.81, inertia_factor=0.4):
        self.axes2 = np.array([a * a, b * b, c * c])
        self.c = c
        self.radius = radius
        self.g = g
        self.jstar = 1.0 / (1.0 + inertia_factor)

    def initial_state(self, x, y, omega):
        q = np.array([x / self.axes2[0], y / self.axes2[1], -np.sqrt(1 - x * x / self.axes2[0] - y * y / self.axes2[1]) / self.c])
        return np.concatenate([-q / np.linalg.norm(q), omega])

    def rhs(self, t, state):
        length = np.linalg.norm(state[:3])
        n = state[:3] / length
        omega = state[3:]
        an = self.axes2 * n
        s2 = n @ an
        s = np.sqrt(s2)
        trace_k = (self.axes2.sum() - an @ an / s2) / s
        det_k = self.axes2.prod() / (s2 * s2)
        r = self.radius
        v = r * np.cross(omega, n)
        kv = (self.axes2 * v - an * (an @ v) / s2) / s
        n_dot = ((r - trace_k) * v + kv) / (r * (r - trace_k) + det_k)
        omega_dot = self.jstar * ((omega @ n) * n_dot + (self.g / r) * np.array([-n[1], n[0], 0.0]))
        return np.concatenate([length * n_dot, omega_dot])

    def contact(self, states):
        n = states[:3] / np.linalg.norm(states[:3], axis=0)
        s = np.sqrt((self.axes2[:, None] * n * n).sum(axis=0))
        p = -self.axes2[:, None] * n / s
        p[2] += self.c
        return p
