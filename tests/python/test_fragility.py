"""Lognormal fragility fits against independent truth: counts drawn from a
known lognormal fragility are fitted back within their sampling error (the
bootstrap interval covers the truth about as often as it claims); the
maximum-likelihood fit equals a probit regression fitted by iteratively
reweighted least squares (an independent algorithm for the same
likelihood); capacities of an incremental analysis give the sample's
geometric mean and log standard deviation."""
import math

import numpy as np
import pytest
from scipy import stats

from ellroll_post.fragility import fit_capacities, fit_stripes

THETA, BETA = 0.8, 0.4            # the true median (say, g of Sa) and dispersion
LEVELS = np.array([0.2, 0.35, 0.5, 0.65, 0.8, 1.0, 1.25, 1.6, 2.0, 2.5])
RECORDS = 40


def draw(seed):
    rng = np.random.default_rng(seed)
    p = stats.norm.cdf(np.log(LEVELS / THETA) / BETA)
    return rng.binomial(RECORDS, p)


def probit_irls(x, n, z, iterations=100):
    """Binomial GLM with the probit link on ln x, by Fisher scoring: returns
    theta, beta from the intercept and slope."""
    X = np.column_stack([np.ones_like(x), np.log(x)])
    coef = np.array([0.0, 1.0])
    for _ in range(iterations):
        eta = X @ coef
        mu = np.clip(stats.norm.cdf(eta), 1e-12, 1 - 1e-12)
        density = stats.norm.pdf(eta)
        weight = n * density**2 / (mu * (1 - mu))
        working = eta + (z / n - mu) / density
        new = np.linalg.solve(X.T @ (weight[:, None] * X), X.T @ (weight * working))
        if np.max(np.abs(new - coef)) < 1e-13:
            coef = new
            break
        coef = new
    intercept, slope = coef
    return math.exp(-intercept / slope), 1 / slope


def test_the_fit_is_the_probit_maximum_likelihood():
    for seed in range(5):
        z = draw(seed)
        fit = fit_stripes(LEVELS, np.full(LEVELS.size, RECORDS), z)
        theta, beta = probit_irls(LEVELS, np.full(LEVELS.size, RECORDS), z)
        assert fit.theta == pytest.approx(theta, rel=1e-6) and fit.beta == pytest.approx(beta, rel=1e-6), seed


def test_counts_from_a_known_fragility_are_fitted_back_within_their_sampling_error():
    errors, covered = [], 0
    trials = 20
    for seed in range(trials):
        fit = fit_stripes(LEVELS, np.full(LEVELS.size, RECORDS), draw(seed), bootstrap=100, seed=seed)
        errors.append((math.log(fit.theta / THETA), fit.beta / BETA - 1))
        covered += fit.theta_interval[0] <= THETA <= fit.theta_interval[1]
    errors = np.array(errors)
    print(f"ln(theta) error: mean {errors[:, 0].mean():.4f}, sd {errors[:, 0].std():.4f}; "
          f"beta relative error: mean {errors[:, 1].mean():.4f}, sd {errors[:, 1].std():.4f}; "
          f"90 % interval covers theta in {covered} of {trials}")
    # the sampling error of ln(theta): about beta / sqrt(records near the median), ~0.03
    assert abs(errors[:, 0].mean()) < 0.02 and errors[:, 0].std() < 0.06
    assert abs(errors[:, 1].mean()) < 0.1 and errors[:, 1].std() < 0.2
    assert 0.75 * trials <= covered <= trials


def test_capacities_give_their_geometric_mean_and_log_spread():
    rng = np.random.default_rng(3)
    capacities = np.exp(rng.normal(math.log(THETA), BETA, size=30))
    fit = fit_capacities(capacities, bootstrap=500, seed=1)
    assert fit.theta == pytest.approx(math.exp(np.log(capacities).mean()), rel=1e-14)
    assert fit.beta == pytest.approx(np.log(capacities).std(ddof=1), rel=1e-14)
    assert fit.theta_interval[0] < fit.theta < fit.theta_interval[1]
    assert fit.probability(fit.theta) == pytest.approx(0.5)


@pytest.mark.parametrize("z", [np.zeros(LEVELS.size), np.full(LEVELS.size, RECORDS)], ids=["none", "all"])
def test_no_fit_where_every_record_or_none_exceeds(z):
    with pytest.raises(ValueError, match="every record exceeds, or none does"):
        fit_stripes(LEVELS, np.full(LEVELS.size, RECORDS), z)


@pytest.mark.parametrize("z", [[0, 0, 0, 1], [0, 0, 1, 3], [0, 0, 3, 3], [0, 2, 3, 3]])
def test_counts_that_separate_have_no_interval(z):
    """Observed counts that separate in the intensity have no finite
    maximum: theta and beta are the optimiser's last point, which the
    bootstrap's steps do not estimate (on the first counts, an outside
    probe's suite, theta 4.17 got the interval [2.83, 4.0] and beta 0.098
    the interval [0, 0]). The intervals are NaN and there is no band; counts
    with a maximum keep intervals that hold their estimate."""
    x, n = [0.5, 1.0, 2.0, 4.0], [3, 3, 3, 3]
    fit = fit_stripes(x, n, z, bootstrap=200)
    assert np.isfinite(fit.theta) and np.isfinite(fit.beta)
    assert all(math.isnan(v) for v in fit.theta_interval + fit.beta_interval), fit.as_dict()
    assert len(fit.samples) == 0 and np.all(np.isnan(fit.band(np.array(x))))
    fit = fit_stripes(x, n, [0, 1, 2, 3], bootstrap=200)
    assert fit.theta_interval[0] <= fit.theta <= fit.theta_interval[1]
    assert fit.beta_interval[0] <= fit.beta <= fit.beta_interval[1]
