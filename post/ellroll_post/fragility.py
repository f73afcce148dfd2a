"""Lognormal fragility functions from a suite's exceedances.

A fragility P(exceed | IM = x) = Phi(ln(x / theta) / beta): median theta,
dispersion beta. Two ways to fit it (Baker, Earthquake Spectra 31(1), 2015):

- stripes (multiple-stripe analysis): at each intensity level x_j, z_j of
  n_j records exceed; theta and beta maximise the binomial likelihood
  sum_j ln C(n_j, z_j) + z_j ln p_j + (n_j - z_j) ln(1 - p_j), p_j the
  fragility at x_j;
- capacities (incremental analysis): each record's intensity at its first
  exceedance; theta is their geometric mean, beta the standard deviation of
  their logarithms.

An interval on theta and beta comes from a parametric bootstrap: the counts
drawn again from the fitted curve (stripes) or the capacities resampled
(incremental), the fit repeated. A resample whose counts separate in the
intensity (none exceeds below some level, all above, at most one level
between) has no finite maximum: it counts as a step, beta = 0
(separating_step). Observed counts that separate have no interval (NaN):
the fit is then the optimiser's last point, not an estimate a resample's
step repeats."""
import math

import numpy as np
from scipy import optimize, special, stats


class FragilityFit:
    """A fitted lognormal fragility: median theta (the IM's unit), dispersion
    beta, and their 5-95 % intervals from the bootstrap (NaN where none)."""

    def __init__(self, theta, beta, theta_interval=(math.nan, math.nan), beta_interval=(math.nan, math.nan),
                 samples=None):
        self.theta, self.beta = float(theta), float(beta)
        self.theta_interval, self.beta_interval = tuple(theta_interval), tuple(beta_interval)
        # the bootstrap's (theta, beta) pairs, for a band about the curve
        self.samples = np.empty((0, 2)) if samples is None else np.asarray(samples, dtype=float)

    def band(self, x, low=5, high=95):
        """The low-high percentile band of P(exceed | IM = x) over the
        bootstrap's fits (NaN without a bootstrap)."""
        x = np.asarray(x, dtype=float)
        if not len(self.samples):
            return np.full(x.shape, np.nan), np.full(x.shape, np.nan)
        theta, beta = self.samples[:, :1], self.samples[:, 1:]
        with np.errstate(divide="ignore", invalid="ignore"):
            p = stats.norm.cdf(np.log(x[None, :] / theta) / beta)
        p = np.where(beta > 0, p, (x[None, :] > theta) + 0.5 * (x[None, :] == theta))   # a step: beta = 0
        return np.percentile(p, low, axis=0), np.percentile(p, high, axis=0)

    def probability(self, x):
        """P(exceed | IM = x)."""
        x = np.asarray(x, dtype=float)
        with np.errstate(divide="ignore"):
            return stats.norm.cdf(np.log(x / self.theta) / self.beta)

    def as_dict(self):
        return {"theta": self.theta, "beta": self.beta, "theta_interval": list(self.theta_interval),
                "beta_interval": list(self.beta_interval)}

    def __repr__(self):
        return f"FragilityFit(theta={self.theta:.6g}, beta={self.beta:.6g})"


def _negative_log_likelihood(params, log_x, n, z):
    """-ln L and its gradient in (ln theta, ln beta)."""
    log_theta, log_beta = params
    beta = math.exp(log_beta)
    u = (log_x - log_theta) / beta
    # ln Phi(u) and ln(1 - Phi(u)) = ln Phi(-u), each without cancellation
    up, down = special.log_ndtr(u), special.log_ndtr(-u)
    log_density = -0.5 * u**2 - 0.5 * math.log(2 * math.pi)
    slope = z * np.exp(log_density - up) - (n - z) * np.exp(log_density - down)     # d ln L / du
    value = -np.sum(z * up + (n - z) * down)
    return value, np.array([np.sum(slope) / beta, np.sum(slope * u)])


def fit_stripes(x, n, z, bootstrap=0, seed=0):
    """theta, beta maximising the binomial likelihood of z[j] exceedances in
    n[j] records at intensity x[j] (> 0); with bootstrap > 0, that many
    parametric resamples give 5-95 % intervals. Stripes where every record
    exceeds or none does count (they bound the curve); at least one stripe
    with exceedances and one with survivors are needed. Where the counts
    separate (separating_step) the likelihood has no maximum: theta and beta
    are the optimiser's last point, which no resample's fit estimates, so
    there is no interval (NaN) and no bootstrap. Where the exceedances do
    not grow with the intensity (without_trend) the likelihood's supremum
    lies at beta -> infinity: theta and beta are NaN (a resample without
    a trend has no fit either and is left out of the intervals)."""
    x, n, z = (np.asarray(a, dtype=float) for a in (x, n, z))
    if x.shape != n.shape or x.shape != z.shape or x.size == 0:
        raise ValueError("x, n and z must be of one length, at least one stripe")
    if np.any(x <= 0) or np.any(n < 1) or np.any(z < 0) or np.any(z > n):
        raise ValueError("each stripe needs x > 0, n >= 1 and 0 <= z <= n")
    if z.sum() == 0 or (n - z).sum() == 0:
        raise ValueError("no fragility can be fitted: every record exceeds, or none does")
    if without_trend(x, n, z):
        return FragilityFit(math.nan, math.nan)
    theta, beta = _fit_once(np.log(x), n, z)
    fit = FragilityFit(theta, beta)
    if bootstrap > 0 and separating_step(x, n, z) is None:
        rng = np.random.default_rng(seed)
        samples = []
        p = fit.probability(x)
        for _ in range(bootstrap):
            zb = rng.binomial(n.astype(int), p)
            if zb.sum() == 0 or (n - zb).sum() == 0 or without_trend(x, n, zb):
                continue
            samples.append(separating_step(x, n, zb) or _fit_once(np.log(x), n, zb))
        fit = _with_intervals(fit, samples)
    return fit


def without_trend(x, n, z):
    """Whether the exceedances do not grow with the intensity: the
    likelihood, concave in (a, b) = (-ln theta / beta, 1 / beta), has its
    maximum over b >= 0 at b = 0 exactly where its slope in b there,
    sum_j ln x_j (z_j - n_j p) times a positive factor (p the overall
    fraction), is not positive (beta -> infinity: no fragility a number
    holds)."""
    x, n, z = (np.asarray(a, dtype=float) for a in (x, n, z))
    log_x = np.log(x)
    p = z.sum() / n.sum()
    trend = np.sum(log_x * (z - n * p))
    return bool(trend <= 1e-12 * np.sum(n * np.abs(log_x - np.average(log_x, weights=n))))


def separating_step(x, n, z):
    """(theta, 0) where the counts separate in the intensity (none exceeds
    below some level, all above it, at most one level between with some
    of each): the likelihood then grows without bound as beta -> 0, its
    supremum a step at that one level, or anywhere between the last level
    without exceedance and the first with only exceedances (taken at their
    geometric mean). None where a finite maximum exists."""
    x, n, z = (np.asarray(a, dtype=float) for a in (x, n, z))
    order = np.argsort(x)
    x, n, z = x[order], n[order], z[order]
    mixed = (z > 0) & (z < n)
    if mixed.sum() > 1 or np.any(np.diff(z / n) < 0) or z.sum() == 0 or z.sum() == n.sum():
        return None
    if mixed.any():
        return float(x[mixed][0]), 0.0
    return math.sqrt(x[z == 0].max() * x[z == n].min()), 0.0


def _fit_once(log_x, n, z):
    """The likelihood's maximum, from a start by the weighted least squares
    of the probit of the observed fractions."""
    fraction = np.clip(z / n, 0.5 / n, 1 - 0.5 / n)
    probit = stats.norm.ppf(fraction)
    if np.ptp(log_x) > 0:
        slope, intercept = np.polyfit(log_x, probit, 1, w=np.sqrt(n))
    else:
        slope, intercept = 1.0, -log_x[0]
    slope = slope if slope > 0 else 1.0
    start = [-intercept / slope, math.log(1 / slope)]
    result = optimize.minimize(_negative_log_likelihood, start, args=(log_x, n, z), jac=True, method="BFGS",
                               options={"gtol": 1e-10, "maxiter": 1000})
    log_theta, log_beta = result.x
    return math.exp(log_theta), math.exp(log_beta)


def fit_capacities(capacities, bootstrap=0, seed=0):
    """theta = geometric mean, beta = standard deviation of ln(capacity)
    (n - 1 in the denominator), of each record's intensity at its first
    exceedance (an incremental analysis); with bootstrap > 0, resampled
    capacities give 5-95 % intervals."""
    c = np.asarray(capacities, dtype=float)
    c = c[np.isfinite(c)]
    if c.size < 2 or np.any(c <= 0):
        raise ValueError("at least two positive capacities are needed")
    logs = np.log(c)
    fit = FragilityFit(math.exp(logs.mean()), logs.std(ddof=1))
    if bootstrap > 0:
        rng = np.random.default_rng(seed)
        samples = []
        for _ in range(bootstrap):
            pick = rng.choice(logs, size=logs.size, replace=True)
            if np.ptp(pick) > 0:
                samples.append((math.exp(pick.mean()), pick.std(ddof=1)))
        fit = _with_intervals(fit, samples)
    return fit


def _with_intervals(fit, samples):
    if not samples:
        return fit
    samples = np.array(samples)
    return FragilityFit(fit.theta, fit.beta, tuple(np.percentile(samples[:, 0], [5, 95])),
                        tuple(np.percentile(samples[:, 1], [5, 95])), samples)
