"""The cup's geometry and the energy integral in NumPy, for the figures."""
import numpy as np


def normal_at(a, b, c, x, y):
    """Inward unit normal at the contact points (x, y) of the lower half."""
    x, y = np.asarray(x, float), np.asarray(y, float)
    q = np.stack([x / a**2, y / b**2, -np.sqrt(np.maximum(0.0, 1 - (x / a)**2 - (y / b)**2)) / c])
    return -q / np.linalg.norm(q, axis=0)


def center_height(a, b, c, radius, x, y):
    """Height of the ball's centre for contact points (x, y): z_A + R n_z."""
    x, y = np.asarray(x, float), np.asarray(y, float)
    z = c - c * np.sqrt(np.maximum(0.0, 1 - (x / a)**2 - (y / b)**2))
    return z + radius * normal_at(a, b, c, x, y)[2]


def energy_bound(a, b, c, radius, level, n_angles=721, n_radial=4000):
    """Points (x, y) where the centre height first reaches `level` going out
    from the bottom along rays (z_C rises, then falls towards the rim where
    n_z = 0): bracketed on a fine grid, then refined by bisection; NaN on a
    ray that never reaches the level."""
    phi = np.linspace(0, 2 * np.pi, n_angles)
    cos, sin = np.cos(phi), np.sin(phi)
    t = np.linspace(0, 1 - 1e-9, n_radial)
    heights = center_height(a, b, c, radius, np.outer(t, a * cos), np.outer(t, b * sin))
    above = heights >= level
    reached = above.any(axis=0)
    first = np.argmax(above, axis=0)
    high = t[first]
    low = t[np.maximum(first - 1, 0)]
    for _ in range(60):
        mid = (low + high) / 2
        is_above = center_height(a, b, c, radius, mid * a * cos, mid * b * sin) >= level
        high = np.where(is_above, mid, high)
        low = np.where(is_above, low, mid)
    scale = np.where(reached, (low + high) / 2, np.nan)
    return scale * a * cos, scale * b * sin


def surface_residual(a, b, c, contact):
    x, y, z = contact[..., 0], contact[..., 1], contact[..., 2]
    return np.abs((x / a)**2 + (y / b)**2 + ((z - c) / c)**2 - 1)
