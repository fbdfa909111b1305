"""The emcee runner: seeded, resumable, diagnosed (on an analytic posterior)."""

from __future__ import annotations

from collections.abc import Callable
from pathlib import Path

import numpy as np
import pytest
from scipy import stats

from pneumafit.identification import Parameter, ParameterSet, run_mcmc
from pneumafit.identification.sampling import MCMCResult

MEAN = np.array([1.0, -2.0])
COV = np.array([[1.0, 0.9], [0.9, 4.0]])
PREC = np.linalg.inv(COV)


def gaussian(z: np.ndarray) -> np.ndarray:
    """Vectorised log density of N(MEAN, COV), (n, 2) -> (n,)."""
    d = np.atleast_2d(z) - MEAN
    return -0.5 * np.einsum("ij,jk,ik->i", d, PREC, d)


def params() -> ParameterSet:
    return ParameterSet(
        [Parameter("a", 1.0, "", -50.0, 50.0), Parameter("b", -2.0, "", -50.0, 50.0)]
    )


class Interrupt(Exception):
    """Stands for Ctrl-C in the middle of a run."""


def _resumed_after_interrupt(
    path: Path,
    cut: int,
    start: np.ndarray,
    cov: np.ndarray | None,
    log_prob: Callable[[np.ndarray], np.ndarray] = gaussian,
    ps: ParameterSet | None = None,
    **kw: object,
) -> MCMCResult:
    """A run of ``log_prob`` (default :func:`gaussian` on :func:`params`)
    stopped at its ``cut``-th log-posterior call (one call per step once the
    walkers are placed), then the same run resumed from its backend ``path``:
    what a user gets after Ctrl-C."""
    calls = 0
    ps = params() if ps is None else ps

    def flaky(z: np.ndarray) -> np.ndarray:
        nonlocal calls
        calls += 1
        if calls == cut:
            raise Interrupt
        return log_prob(z)

    with pytest.raises(Interrupt):
        run_mcmc(flaky, ps, start, cov, backend=path, **kw)  # type: ignore[arg-type]
    return run_mcmc(log_prob, ps, start, cov, backend=path, **kw)  # type: ignore[arg-type]


def test_same_seed_same_chain_and_seed_matters() -> None:
    a = run_mcmc(gaussian, params(), MEAN, COV, n_walkers=8, n_steps=50, seed=4)
    b = run_mcmc(gaussian, params(), MEAN, COV, n_walkers=8, n_steps=50, seed=4)
    c = run_mcmc(gaussian, params(), MEAN, COV, n_walkers=8, n_steps=50, seed=5)
    assert np.array_equal(a.chain, b.chain)
    assert not np.array_equal(a.chain, c.chain)


def test_interrupted_run_resumes_to_the_uninterrupted_chain(tmp_path: Path) -> None:
    full = run_mcmc(
        gaussian, params(), MEAN, COV, n_walkers=8, n_steps=120, seed=11,
        backend=tmp_path / "full.h5", name="stage",
    )  # fmt: skip
    path = tmp_path / "cut.h5"
    # cut at call 70: well inside the run
    resumed = _resumed_after_interrupt(path, 70, MEAN, COV, n_walkers=8, n_steps=120, seed=11,
                                       name="stage")  # fmt: skip
    assert 0 < resumed.resumed_from < 120
    assert np.array_equal(resumed.chain, full.chain)
    assert np.array_equal(resumed.log_prob, full.log_prob)
    # a finished chain is read back, not extended
    again = run_mcmc(gaussian, params(), MEAN, COV, n_walkers=8, n_steps=120, seed=11,
                     backend=path, name="stage")  # fmt: skip
    assert again.evaluations == 0 and np.array_equal(again.chain, full.chain)


def test_posterior_summaries_match_the_target() -> None:
    # seeded statistical check: 16 walkers x 3000 steps of a 2-D Gaussian;
    # tolerances are ~4 Monte Carlo standard errors (ESS > 2000)
    res = run_mcmc(gaussian, params(), MEAN, COV, n_walkers=16, n_steps=3000, seed=2)
    ps = res.parameters
    sd = np.sqrt(np.diag(COV))
    assert ps["a"].median == pytest.approx(MEAN[0], abs=0.1 * sd[0])
    assert ps["b"].std == pytest.approx(sd[1], rel=0.1)
    lo, hi = ps["a"].interval_90
    assert lo == pytest.approx(MEAN[0] - 1.645 * sd[0], abs=0.15)
    assert hi == pytest.approx(MEAN[0] + 1.645 * sd[0], abs=0.15)
    assert res.correlation[0, 1] == pytest.approx(COV[0, 1] / sd[0] / sd[1], abs=0.05)
    assert 0.2 < res.acceptance < 0.8
    assert res.tau_multiple > 50 and not res.warnings
    assert all(abs(r - 1.0) < 0.02 for r in res.rhat.values())
    assert all(e > 1000 for e in res.ess.values())
    # the draws are distributed as the target (KS test on thinned draws)
    tau = max(res.tau.values())
    draws = res.chain[res.discard :: int(np.ceil(tau)), :, 0].ravel()
    assert stats.kstest(draws, stats.norm(MEAN[0], sd[0]).cdf).pvalue > 0.01


def test_short_chains_are_flagged() -> None:
    res = run_mcmc(gaussian, params(), MEAN, COV, n_walkers=8, n_steps=60, seed=3)
    assert res.tau_multiple < 50
    assert any("shorter than 50 tau" in w for w in res.warnings)


def test_bad_settings_are_refused() -> None:
    with pytest.raises(ValueError, match="at least 4 walkers"):
        run_mcmc(gaussian, params(), MEAN, COV, n_walkers=3, n_steps=10)
    with pytest.raises(ValueError, match="steps"):
        run_mcmc(gaussian, params(), MEAN, COV, n_walkers=8, n_steps=0)


def test_laplace_covariance_survives_mixed_units() -> None:
    """The internal coordinates mix pascals and logarithms: J^T J's diagonal
    spans many decades. The covariance is the equilibrated pseudo-inverse,
    equal to the exact inverse; a plain pinv with a relative cut-off drops the
    small-diagonal direction as if it were known (too narrow intervals)."""
    from pneumafit.identification.optimise import _laplace

    rng = np.random.default_rng(0)
    base = rng.standard_normal((400, 3))
    base[:, 2] = base[:, 0] + 0.05 * base[:, 2]  # correlated, well-posed once scaled
    scale = np.array([1.0e4, 1.0, 2.0e-3])  # e.g. a log friction, a K, a Pa coordinate
    jac = base * scale
    exact = np.linalg.inv(jac.T @ jac)
    cov = _laplace(jac)
    assert cov is not None
    # measured 7e-13; rtol leaves room for other BLAS, far below any dropped direction
    np.testing.assert_allclose(cov, exact, rtol=1e-6)
    naive = np.linalg.pinv(jac.T @ jac, rcond=1e-12, hermitian=True)
    # what the old code reported: sd 0.05 of the true one here
    assert np.sqrt(naive[0, 0] / exact[0, 0]) < 0.2


def test_short_chain_is_extended_until_50_tau_and_resumes(tmp_path: Path) -> None:
    """A 30-step chain (far below 50 tau) is extended in rounds up to its
    limit; interrupted during the extension, it resumes to the same chain."""
    full = run_mcmc(
        gaussian, params(), MEAN, COV, n_walkers=8, n_steps=30, seed=3, max_steps=600,
        backend=tmp_path / "full.h5", name="stage",
    )  # fmt: skip
    assert full.n_steps > 30  # extended
    assert full.n_steps <= 600
    # it stops at the first round that reaches 50 tau and R-hat <= 1.01, or at the limit
    converged = full.tau_multiple >= 50 and max(full.rhat.values()) <= 1.01
    assert converged or full.n_steps == 600
    # cut at call 100: inside the extension rounds
    resumed = _resumed_after_interrupt(tmp_path / "cut.h5", 100, MEAN, COV, n_walkers=8,
                                       n_steps=30, seed=3, max_steps=600, name="stage")  # fmt: skip
    assert resumed.n_steps == full.n_steps
    assert np.array_equal(resumed.chain, full.chain)


def test_without_a_limit_the_chain_has_exactly_its_steps() -> None:
    run = run_mcmc(gaussian, params(), MEAN, COV, n_walkers=8, n_steps=30, seed=3)
    assert run.n_steps == 30


def test_early_stop_at_the_first_converged_check_and_resumes(tmp_path: Path) -> None:
    """With ``min_steps`` the chain is checked every 200 steps and stops at the
    first check where it is >= 50 tau long with R-hat <= 1.01, well before its
    3000 steps (the analytic Gaussian needs a few hundred); the checks see
    only the stored chain, so an interrupted run resumes to the same stop."""
    full = run_mcmc(
        gaussian, params(), MEAN, COV, n_walkers=8, n_steps=3000, seed=6, min_steps=200,
        backend=tmp_path / "full.h5", name="stage",
    )  # fmt: skip
    assert full.n_steps % 200 == 0 and full.n_steps < 3000
    assert full.tau_multiple >= 50 and max(full.rhat.values()) <= 1.01
    # one check earlier it was not converged (or it would have stopped there)
    if full.n_steps > 200:
        shorter = run_mcmc(gaussian, params(), MEAN, COV, n_walkers=8,
                           n_steps=full.n_steps - 200, seed=6)  # fmt: skip
        assert shorter.tau_multiple < 50 or max(shorter.rhat.values()) > 1.01
    # cut inside the last check's stretch
    resumed = _resumed_after_interrupt(tmp_path / "cut.h5", full.n_steps - 50, MEAN, COV,
                                       n_walkers=8, n_steps=3000, seed=6, min_steps=200,
                                       name="stage")  # fmt: skip
    assert resumed.n_steps == full.n_steps
    assert np.array_equal(resumed.chain, full.chain)


def test_checks_continue_while_the_chain_is_extended() -> None:
    """Past its default length an extended chain is still checked every
    ``min_steps`` steps (not in rounds of half the default length), so it
    stops at the first converged multiple of ``min_steps``. The default
    length here (100 steps) is far too short for 50 tau of the analytic
    Gaussian, so the stop lies in the extension."""
    run = run_mcmc(
        gaussian, params(), MEAN, COV, n_walkers=8, n_steps=100, seed=6, min_steps=50,
        max_steps=3000,
    )  # fmt: skip
    assert 100 < run.n_steps < 3000 and run.n_steps % 50 == 0
    assert run.tau_multiple >= 50 and max(run.rhat.values()) <= 1.01
    shorter = run_mcmc(gaussian, params(), MEAN, COV, n_walkers=8, n_steps=run.n_steps - 50,
                       seed=6)  # fmt: skip
    assert shorter.tau_multiple < 50 or max(shorter.rhat.values()) > 1.01


def test_walkers_at_a_bound_start_spread_inside_it() -> None:
    """An estimate on its lower bound (a half-normal posterior against 0): the walkers
    start inside the interval with distinct coordinates, none on the bound itself.

    Clipping put every draw below the bound onto it (about half the walkers at
    exactly 0), a degenerate ensemble that moves along walker differences leave
    slowly. The reflected draws are |N(0, 1)|: their spread must be that of the
    Laplace width (0.3-2 of it for 64 walkers, a loose bound on a sample std).
    """
    from pneumafit.identification.sampling import _initial_walkers

    rng = np.random.default_rng(3)
    lower, upper = np.array([0.0, -50.0]), np.array([50.0, 50.0])
    walkers = _initial_walkers(
        lambda z: np.zeros(np.atleast_2d(z).shape[0]), np.array([0.0, 1.0]), np.eye(2), 64, rng,
        lower, upper,
    )  # fmt: skip
    assert np.all(walkers[:, 0] > 0.0) and np.all(walkers[:, 0] <= 50.0)
    assert np.unique(walkers[:, 0]).size == 64
    spread = np.sqrt(np.mean(walkers[:, 0] ** 2))  # |N(0, 1)| has RMS 1
    assert 0.3 < spread < 2.0


# ----------------------------------------------------------- adaptation phase
# ``adapt``: DE steps, then a Student-t independence proposal fitted to the
# walkers and frozen (sampling module doc). These tests are analytic targets,
# so the truth is exact; their tolerances are Monte-Carlo errors from the
# chain's own effective sample size.


def banana(z: np.ndarray) -> np.ndarray:
    """x ~ N(0, 1), y | x ~ N(0.5 (x^2 - 1), 0.5^2): curved, not Gaussian.

    Exact: x's quantiles are the normal ones; E y = 0 and
    Var y = 0.25 Var(x^2) + 0.25 = 0.75.
    """
    z = np.atleast_2d(z)
    x, y = z[:, 0], z[:, 1]
    return -0.5 * x**2 - 0.5 * ((y - 0.5 * (x**2 - 1.0)) / 0.5) ** 2


def _assert_exact_90(run: MCMCResult) -> None:
    """The 90 % interval ends of a chain on N(MEAN, COV) are the exact ones
    (mean +- 1.645 sd) to 4 standard errors of a 5 % / 95 % quantile at the
    chain's effective sample size."""
    sd = np.sqrt(np.diag(COV))
    kept = run.n_steps - run.discard
    for j, p in enumerate(run.parameters.free):
        ess = kept * run.n_walkers / run.tau[p.name]
        se = sd[j] * np.sqrt(0.05 * 0.95 / ess) / stats.norm.pdf(1.645)
        lo, hi = p.interval_90
        assert abs(lo - (MEAN[j] - 1.645 * sd[j])) < 4 * se
        assert abs(hi - (MEAN[j] + 1.645 * sd[j])) < 4 * se


def test_adapted_proposal_shortens_tau_and_keeps_the_posterior() -> None:
    """On the correlated Gaussian the fitted t is nearly the posterior: tau
    falls from 7.5-8.3 steps (DE alone, measured at seed 1) to ~1.5, and the
    90 % intervals stay the exact ones (mean +- 1.645 sd) to Monte-Carlo error
    (4 standard errors of a 5 % / 95 % quantile at the chain's ESS)."""
    plain = run_mcmc(gaussian, params(), MEAN, None, n_walkers=8, n_steps=2000, seed=1)
    adapted = run_mcmc(gaussian, params(), MEAN, None, n_walkers=8, n_steps=2000, seed=1,
                       adapt=300)  # fmt: skip
    assert max(adapted.tau.values()) < max(plain.tau.values()) / 3
    assert adapted.discard >= 300  # the adaptation is never summarised
    _assert_exact_90(adapted)


def test_adapted_chain_samples_a_curved_posterior() -> None:
    """A fixed proposal leaves any posterior invariant, also one that no t
    fits (a banana): the marginal quantiles of x and the mean and variance of
    y are the exact ones to 4 Monte-Carlo standard errors."""
    ps = ParameterSet([Parameter("x", 0.0, "", -50.0, 50.0), Parameter("y", 0.0, "", -50.0, 50.0)])
    run = run_mcmc(banana, ps, np.zeros(2), None, n_walkers=16, n_steps=4000, seed=2, adapt=300)
    kept = run.chain[run.discard :].reshape(-1, 2)
    ess_x = kept.shape[0] / run.tau["x"]
    ess_y = kept.shape[0] / run.tau["y"]
    for q in (0.05, 0.5, 0.95):
        z = stats.norm.ppf(q)
        se = np.sqrt(q * (1 - q) / ess_x) / stats.norm.pdf(z)
        assert abs(np.quantile(kept[:, 0], q) - z) < 4 * se
    var_y = 0.75
    assert abs(kept[:, 1].mean()) < 4 * np.sqrt(var_y / ess_y)
    # the variance of y's sample variance: (m4 - var^2) / n, m4 from the chain
    m4 = np.mean((kept[:, 1] - kept[:, 1].mean()) ** 4)
    assert abs(kept[:, 1].var() - var_y) < 4 * np.sqrt((m4 - var_y**2) / ess_y)


@pytest.mark.parametrize("cut", [40, 140])  # before and after the switch at step 60
def test_adapted_run_is_seeded_and_resumes_to_the_same_chain(tmp_path: Path, cut: int) -> None:
    """The proposal is rebuilt from the stored chain: a run interrupted
    during the adaptation or after the switch ends with the uninterrupted
    chain, and the same seed gives the same chain."""
    kw = {"n_walkers": 8, "n_steps": 200, "seed": 9, "adapt": 60, "name": "stage"}
    full = run_mcmc(gaussian, params(), MEAN, COV, backend=tmp_path / "full.h5", **kw)
    again = run_mcmc(gaussian, params(), MEAN, COV, **kw)
    assert np.array_equal(full.chain, again.chain)
    resumed = _resumed_after_interrupt(tmp_path / "cut.h5", cut, MEAN, COV, **kw)
    assert np.array_equal(resumed.chain, full.chain)


def test_a_vector_of_medians_off_the_posterior_is_not_reported() -> None:
    """On a curved ridge (y = x^2 + noise) each median lies inside its 90 %
    interval, but the point (median x, median y) is far off the ridge: the
    reported point is then the most probable draw inside every interval
    (staged._reported_point), and it is typical of the draws. On a Gaussian
    the medians are kept. Kind: the rule on exact draws of known densities."""
    from types import SimpleNamespace

    from pneumafit.identification.sampling import summarize_samples
    from pneumafit.identification.staged import TYPICAL_QUANTILE, _reported_point

    ps = ParameterSet([Parameter("x", 0.0, "", -10.0, 10.0), Parameter("y", 0.0, "", -10.0, 10.0)])
    rng = np.random.default_rng(4)
    for curved in (True, False):

        def post(z: np.ndarray, curved: bool = curved) -> np.ndarray:
            x, y = z[:, 0], z[:, 1]
            return -0.5 * x**2 - 0.5 * ((y - (x**2 if curved else 0.0)) / 0.1) ** 2

        x = rng.normal(size=(500, 8))
        y = (x**2 if curved else 0.0) + 0.1 * rng.normal(size=(500, 8))
        chain = np.stack([x, y], axis=-1)
        lp = post(chain.reshape(-1, 2)).reshape(500, 8)
        summary = summarize_samples(chain.reshape(-1, 2), ps)
        res = SimpleNamespace(chain=chain, log_prob=lp, discard=0, names=("x", "y"),
                              parameters=ps)  # fmt: skip
        point, line = _reported_point(post, ps, res, summary)
        if not curved:
            assert point == {} and line == ""
            continue
        assert "not a typical point" in line
        lp_point = post(np.array([[point["x"], point["y"]]]))[0]
        assert lp_point >= np.quantile(lp, TYPICAL_QUANTILE)
        for p in summary.free:
            lo, hi = p.interval_90
            assert lo <= point[p.name] <= hi


def test_propagated_draws_stay_inside_the_bounds() -> None:
    """A held parameter with a huge Laplace variance strongly correlated with
    the sampled one shifts the draws far outside the sampled parameter's
    bounds; they are drawn again, then put on the bound: every propagated
    value finite and inside (before: exp(800) and a NaN interval). Draws
    that a small covariance keeps inside are those of the plain shift.
    Kind: control flow of sampling.propagate on a constructed covariance."""
    from types import SimpleNamespace

    from pneumafit.identification.sampling import propagate

    h = Parameter("v_s", 0.02, "m/s", 1e-4, 10.0, scale="log")
    joint = ParameterSet([h, Parameter("other", 0.0, "", -1e9, 1e9)])
    sampled = ParameterSet([h])
    rng = np.random.default_rng(2)
    chain = np.log(0.02) + 0.1 * rng.normal(size=(200, 4, 1))
    res = SimpleNamespace(chain=chain, discard=0, names=("v_s",), parameters=sampled)
    for scale, inside_before in ((1e6, False), (1e-6, True)):
        cov = np.array([[scale, 0.999 * scale], [0.999 * scale, scale]])
        summary, z = propagate(res, joint, cov, seed=3)
        lo, hi = sampled.internal_bounds()
        assert np.all(np.isfinite(z)) and np.all((z >= lo) & (z <= hi))
        p = summary["v_s"]
        eps = 1e-12  # exp(log(10)) = 10.000000000000002: the round trip, not a bound crossed
        assert 1e-4 * (1 - eps) <= p.interval_90[0] <= p.median <= p.interval_90[1]
        assert p.interval_90[1] <= 10.0 * (1 + eps)
        if inside_before:  # nothing to redraw: the plain shift, same seed
            root = np.sqrt(cov[0, 1] ** 2 / cov[1, 1])
            plain = chain.reshape(-1, 1) + np.random.default_rng(3).standard_normal((800, 1)) * root
            np.testing.assert_allclose(z, plain, rtol=1e-9)


def test_propagation_widens_by_the_inflation_to_the_widened_marginal() -> None:
    """A Gaussian joint posterior of Laplace covariance L, widened to C = D L D
    (recording_robust_covariance): the chain samples the conditional of h
    given v, N(0, L_cond); propagate with inflation D_h and covariance C
    must give draws of variance C_hh = d_h^2 L_hh (the widened marginal),
    their median where the chain's was. Kind: the propagation's algebra on
    exact Gaussian draws; the tolerance is the sampling error of a variance
    from 40 000 draws (~0.7 %), taken at 5 %."""
    from types import SimpleNamespace

    from pneumafit.identification.sampling import propagate

    h = Parameter("h", 0.0, "", -1e3, 1e3)
    joint = ParameterSet([h, Parameter("v", 0.0, "", -1e3, 1e3)])
    sampled = ParameterSet([h])
    lap = np.array([[1.0, 0.6], [0.6, 1.0]])
    d = np.array([2.5, 1.5])
    widened = d[:, None] * lap * d[None, :]
    l_cond = lap[0, 0] - lap[0, 1] ** 2 / lap[1, 1]
    rng = np.random.default_rng(8)
    chain = np.sqrt(l_cond) * rng.normal(size=(5000, 8, 1))
    res = SimpleNamespace(chain=chain, discard=0, names=("h",), parameters=sampled)
    summary, z = propagate(res, joint, widened, seed=1, inflation={"h": d[0], "v": d[1]})
    assert np.var(z) == pytest.approx(widened[0, 0], rel=0.05)
    assert summary["h"].median == pytest.approx(float(np.median(chain)), abs=0.05)
    # no inflation, no widening: the plain propagation of the Laplace covariance
    _, z0 = propagate(res, joint, lap, seed=1)
    assert np.var(z0) == pytest.approx(lap[0, 0], rel=0.05)
    # inflation without a covariance (nothing held): the chain itself, widened
    summary_only, z1 = propagate(res, joint, None, seed=1, inflation={"h": 2.0})
    assert np.var(z1) == pytest.approx(4.0 * l_cond, rel=0.05)
    lo, hi = summary_only["h"].interval_90
    assert hi - lo == pytest.approx(2.0 * 2 * 1.6449 * np.sqrt(l_cond), rel=0.05)


# ------------------------------------------- the adaptation phase ends early
# ``adapt_check``: the phase is checked every adapt_check steps and ends when
# the walkers have settled (sampling._phase_settled), at ``adapt`` at the latest.


def test_a_settled_phase_ends_at_its_first_check_and_a_climbing_one_does_not() -> None:
    """The rule on log posteriors made to order: walkers at equilibrium (mean
    log posterior flat, the spread of a 2-d Gaussian's) end the phase at the
    first check, with no fit within it; walkers still climbing (by 0.05 per
    step, above the 0.25 sqrt(d/2) allowed per quarter) do not, so the phase
    runs its full length with the t fitted at every check; a climb that
    levels off at step 120 ends at the first check whose steps since the
    last fit (100-125 still climb, 125-150 do not) have settled: 150, where
    judged from step 0 it would have run to 250; but not where the walkers
    barely moved since that fit."""
    from pneumafit.identification.sampling import PHASE_MIXED, _phase_plan, _phase_settled

    rng = np.random.default_rng(0)
    flat = -rng.chisquare(2, size=(300, 8)) / 2
    moving = rng.normal(size=(300, 8, 2))  # every walker moves at every step
    assert _phase_settled(flat[:50], 2) and _phase_plan(flat, moving, 300, 25, 2) == (50, [])
    climbing = flat - 0.05 * np.arange(300)[::-1, None]
    assert not any(_phase_settled(climbing[n - 25 : n], 2) for n in range(75, 300, 25))
    assert _phase_plan(climbing, moving, 300, 25, 2) == (300, list(range(50, 300, 25)))
    assert _phase_plan(climbing[:200], moving[:200], 300, 25, 2) == (
        None, [50, 75, 100, 125, 150, 175, 200]
    )  # fmt: skip
    levels = flat - 0.2 * np.clip(120 - np.arange(300), 0, None)[:, None]  # flat from 120
    assert _phase_plan(levels, moving, 300, 25, 2) == (150, [50, 75, 100, 125])
    assert _phase_settled(levels[125:150], 2) and not _phase_settled(levels[:150], 2)
    # walkers that moved in a fifth of the steps since the fit at 125: their
    # t is the one they were drawn with, so the phase goes on to 175
    stuck = moving.copy()
    for step in range(126, 150):  # no move at steps 126-149 but every fifth
        stuck[step] = stuck[step - 1] + (step % 5 == 0)
    assert 0.15 < np.mean(np.any(np.diff(stuck[124:150], axis=0) != 0, axis=2)) < PHASE_MIXED
    assert _phase_plan(levels, stuck, 300, 25, 2) == (175, [50, 75, 100, 125, 150])


@pytest.mark.parametrize("cut", [30, 60])  # before and after the fit within the phase
def test_an_early_phase_end_is_seeded_resumable_and_keeps_the_posterior(
    tmp_path: Path, cut: int
) -> None:
    """From a wide start on the correlated Gaussian the walkers still climb
    at the first check (step 50), where the t is fitted to them; the phase
    ends at the next (75), before its 300 steps (recorded in
    ``adapted_after`` and ``phase_fits``, never summarised); a run
    interrupted in the phase, before or after that fit, resumes to the same
    chain and phase end; the 90 % intervals are the exact ones to 4
    Monte-Carlo standard errors."""
    kw = {"n_walkers": 8, "n_steps": 1500, "seed": 4, "adapt": 300, "adapt_check": 25,
          "name": "stage"}  # fmt: skip
    wide = np.diag([25.0, 25.0])
    full = run_mcmc(gaussian, params(), MEAN + 8.0, wide, backend=tmp_path / "full.h5", **kw)
    assert 50 <= full.adapted_after < 300 and full.discard >= full.adapted_after
    assert full.as_dict()["adapted_after"] == full.adapted_after
    assert full.phase_fits == [50] and full.as_dict()["phase_fits"] == [50]
    assert full.readapted_after == []  # a t fitted to settled walkers is kept
    # the cut inside the phase (every step is one call)
    resumed = _resumed_after_interrupt(tmp_path / "cut.h5", cut, MEAN + 8.0, wide, **kw)
    assert resumed.adapted_after == full.adapted_after
    assert resumed.phase_fits == full.phase_fits
    assert np.array_equal(resumed.chain, full.chain)
    _assert_exact_90(full)


# ------------------------------------------------ the proposal fitted again
# A phase that ends before the walkers settle fits a t that misses the
# posterior; a check window with acceptance below READAPT_ACCEPTANCE fits it
# again to the steps since (sampling.run_mcmc).


@pytest.mark.parametrize("cut", [60, 100])  # before and after the new fit at step 70
def test_a_proposal_fitted_to_unsettled_walkers_is_fitted_again(
    tmp_path: Path, cut: int, monkeypatch: pytest.MonkeyPatch
) -> None:
    """From 30 sd away with a 20-step phase, the t is fitted to climbing
    walkers: 7 % of the steps 20-70 are accepted, the t is fitted again at
    step 70, and the chain converges (>= 50 tau, R-hat <= 1.01) by step 320
    with acceptance 0.57 and the exact 90 % intervals (4 Monte-Carlo
    standard errors). Without the new fit (MAX_READAPT = 0, measured the same
    way) the acceptance stays at 0.04 and the chain is still unconverged at
    its 2000-step limit (36 tau, R-hat 1.03). A run interrupted before or
    after the new fit resumes to the same chain and the same decision."""
    kw = {"n_walkers": 8, "n_steps": 1000, "seed": 1, "adapt": 20, "min_steps": 50,
          "max_steps": 2000, "name": "stage"}  # fmt: skip
    start, wide = MEAN + 30.0, np.diag([400.0, 400.0])
    full = run_mcmc(gaussian, params(), start, wide, backend=tmp_path / "full.h5", **kw)
    assert full.readapted_after == [70] and full.as_dict()["readapted_after"] == [70]
    assert full.discard >= 70
    assert full.n_steps < 1000 and full.acceptance > 0.4
    assert full.tau_multiple >= 50 and max(full.rhat.values()) <= 1.01
    _assert_exact_90(full)
    resumed = _resumed_after_interrupt(tmp_path / "cut.h5", cut, start, wide, **kw)
    assert resumed.readapted_after == full.readapted_after
    assert np.array_equal(resumed.chain, full.chain)

    import pneumafit.identification.sampling as sampling

    monkeypatch.setattr(sampling, "MAX_READAPT", 0)
    # extended to the limit whatever the projection (EXTEND_REACH), as when
    # this was measured: the projection stops this chain at 1020 steps
    monkeypatch.setattr(sampling, "EXTEND_REACH", float("inf"))
    kept = run_mcmc(gaussian, params(), start, wide, **kw)
    assert kept.readapted_after == [] and kept.acceptance < 0.1 and kept.n_steps == 2000


def skewed(z: np.ndarray) -> np.ndarray:
    """a ~ Gamma(1.5, 1), b ~ N(0, 1), independent: a long right tail, which
    a t fitted to walkers near the mode under-covers."""
    z = np.atleast_2d(z)
    a, b = z[:, 0], z[:, 1]
    with np.errstate(divide="ignore", invalid="ignore"):
        lp = 0.5 * np.log(a) - a - 0.5 * b**2
    return np.where(a > 0.0, lp, -np.inf)


@pytest.mark.parametrize("cut", [100, 250])  # before and after the new fit at step 170
def test_a_walker_held_in_the_tail_fits_the_proposal_again(
    tmp_path: Path, cut: int, monkeypatch: pytest.MonkeyPatch
) -> None:
    """From a tiny ball at the mode with a 20-step phase, the t misses the
    right tail of a Gamma(1.5): the walkers that reach it are held there
    (nearly every draw of the t is refused) while the others move, so the
    acceptance stays far above READAPT_ACCEPTANCE. A walker held for half a
    check window fits the t again (at steps 170 and 370, seed 3), and the
    chain converges (>= 50 tau, R-hat <= 1.01) by step 800 with the exact
    5 % and 95 % quantiles of a to 4 Monte-Carlo standard errors at its
    ESS. Without that rule (HELD_SHARE infinite; measured the same way) the
    chain runs to its 3000-step limit unconverged (tau of a 60 steps, R-hat
    1.017), and at seeds 1-6 it needs 420-3000 steps against 320-770 with
    it. A run interrupted before or after the new fit resumes to the same
    chain and the same decisions."""
    kw = {"n_walkers": 8, "n_steps": 1000, "seed": 3, "adapt": 20, "min_steps": 50,
          "max_steps": 3000, "name": "stage"}  # fmt: skip
    start, tiny = np.array([0.5, 0.0]), np.diag([1e-4, 1e-4])
    ps = ParameterSet([Parameter("a", 0.5, "", -50.0, 50.0), Parameter("b", 0.0, "", -50.0, 50.0)])
    full = run_mcmc(skewed, ps, start, tiny, backend=tmp_path / "full.h5", **kw)
    assert full.readapted_after == [170, 370]
    assert full.acceptance > 0.4 and full.n_steps <= 800
    assert full.tau_multiple >= 50 and max(full.rhat.values()) <= 1.01
    kept = full.chain[full.discard :, :, 0].ravel()
    ess = kept.size / full.tau["a"]
    exact = stats.gamma(1.5)
    for q in (0.05, 0.95):
        se = np.sqrt(q * (1 - q) / ess) / exact.pdf(exact.ppf(q))
        assert abs(np.quantile(kept, q) - exact.ppf(q)) < 4 * se

    resumed = _resumed_after_interrupt(
        tmp_path / "cut.h5", cut, start, tiny, log_prob=skewed, ps=ps, **kw
    )
    assert resumed.readapted_after == full.readapted_after
    assert np.array_equal(resumed.chain, full.chain)

    import pneumafit.identification.sampling as sampling

    monkeypatch.setattr(sampling, "HELD_SHARE", float("inf"))
    # extended to the limit whatever the projection, as when this was
    # measured: the projection (EXTEND_REACH) stops this chain at 2170 steps
    monkeypatch.setattr(sampling, "EXTEND_REACH", float("inf"))
    kept_t = run_mcmc(skewed, ps, start, tiny, **kw)
    assert kept_t.readapted_after == [] and kept_t.n_steps == 3000
    assert max(kept_t.rhat.values()) > 1.01


def thin_banana(z: np.ndarray) -> np.ndarray:
    """x ~ N(0, 1), y | x ~ N(1.5 x^2, 0.1^2): a thin curved ridge, which no
    t fits (a t over the ridge's envelope proposes off it nearly always)."""
    d = np.atleast_2d(z)
    x, y = d[:, 0], d[:, 1]
    return -0.5 * x**2 - 0.5 * ((y - 1.5 * x**2) / 0.1) ** 2


@pytest.mark.parametrize("cut", [300, 500])  # before and after the fallback at step 370
def test_a_posterior_that_no_t_fits_is_sampled_by_de_alone(
    tmp_path: Path, cut: int, monkeypatch: pytest.MonkeyPatch
) -> None:
    """On the thin banana the t, fitted at the phase's end and twice again
    (steps 70 and 270, seed 2), still accepts under READAPT_ACCEPTANCE: the
    chain drops it at step 370 and goes on with the DE moves alone, its
    steps kept (each kernel leaves the posterior invariant). At 1220 steps
    R-hat is 1.08 against 1.52 with the last t kept (FALLBACK off, as before
    2026-12-05; seeds 1-4: 1.18 / 1.08 / 1.22 / 1.20 against 1.36 / 1.52 /
    1.23 / 1.24), neither converged, both flagged: the banana is what the
    demo's stages are not, a test of the rule, not of the sampler's reach.
    A run interrupted before or after the fallback resumes to the same
    chain and the same decision."""
    kw = {"n_walkers": 8, "n_steps": 1000, "seed": 2, "adapt": 20, "min_steps": 50,
          "max_steps": 3000, "name": "stage"}  # fmt: skip
    ps = ParameterSet([Parameter("x", 0.0, "", -50.0, 50.0), Parameter("y", 0.0, "", -50.0, 50.0)])
    start, small = np.zeros(2), np.diag([1e-2, 1e-2])
    full = run_mcmc(thin_banana, ps, start, small, backend=tmp_path / "full.h5", **kw)
    assert full.readapted_after == [70, 270] and full.fallback_after == 370
    assert full.as_dict()["fallback_after"] == 370
    resumed = _resumed_after_interrupt(
        tmp_path / "cut.h5", cut, start, small, log_prob=thin_banana, ps=ps, **kw
    )
    assert resumed.fallback_after == full.fallback_after
    assert np.array_equal(resumed.chain, full.chain)

    import pneumafit.identification.sampling as sampling

    monkeypatch.setattr(sampling, "FALLBACK", False)
    kept_t = run_mcmc(thin_banana, ps, start, small, **kw)
    assert kept_t.fallback_after is None and kept_t.readapted_after == [70, 270]
    assert max(full.rhat.values()) < max(kept_t.rhat.values())


def rugged(z: np.ndarray) -> np.ndarray:
    """The Gaussian plus a deterministic field of pits 40 log units deep on a
    0.01 grid: from a pit bottom nearly every proposal is refused, so the
    walkers hold still where they stand (what a stick-slip likelihood whose
    events move with the parameters does to a sampler)."""
    d = np.atleast_2d(z)
    cell = np.floor(d / 0.01)
    h = np.sin(cell[:, 0] * 12.9898 + cell[:, 1] * 78.233) * 43758.5453
    return gaussian(d) + 40.0 * (h - np.floor(h))


def test_a_chain_that_cannot_converge_by_its_limit_is_not_extended(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """Past its default length (500 steps) a chain is extended only while it
    can converge by its limit (EXTEND_REACH). On the rugged posterior the
    walkers hold still (R-hat far above 1.01, tau not estimable): the chain
    stops at its default length with a warning naming why, where it ran to
    its 3000-step limit before (shown by disabling the rule). Not extending
    it changes nothing else: the same 500 steps, bit for bit. The analytic
    Gaussian with the same settings still converges: it is not converged at
    its default length either, so the rule is evaluated at every check of
    its extension (its projections, 804-1443 kept steps, overestimated the
    ~1080 it converged at by up to 1.4x, within the margin of 2) and does
    not stop a chain that mixes. An interrupted run resumes to the same
    stop."""
    import pneumafit.identification.sampling as sampling

    kw = {"n_walkers": 8, "n_steps": 500, "seed": 4, "min_steps": 100, "max_steps": 3000,
          "name": "stage"}  # fmt: skip
    lines: list[str] = []
    run = run_mcmc(
        rugged, params(), MEAN, COV, log=lines.append, backend=tmp_path / "full.h5", **kw
    )
    assert run.n_steps == 500
    assert max(run.rhat.values()) > 1.1
    assert any("not extended past 500 steps" in w for w in run.warnings)
    assert any("not extended past 500 steps" in line for line in lines)
    resumed = _resumed_after_interrupt(tmp_path / "cut.h5", 450, MEAN, COV, log_prob=rugged, **kw)
    assert resumed.n_steps == 500 and np.array_equal(resumed.chain, run.chain)

    smooth = run_mcmc(gaussian, params(), MEAN, COV, **kw)
    assert smooth.n_steps > 500  # extended: the rule was evaluated, and let it run
    assert smooth.tau_multiple >= 50 and max(smooth.rhat.values()) <= 1.01
    assert not any("not extended" in w for w in smooth.warnings)

    monkeypatch.setattr(sampling, "EXTEND_REACH", float("inf"))
    unruled = run_mcmc(rugged, params(), MEAN, COV, **kw)
    assert unruled.n_steps == 3000
    assert np.array_equal(unruled.chain[:500], run.chain)
    assert max(unruled.rhat.values()) > 1.01


def test_the_buffered_chain_file_is_emcee_s_own(tmp_path: Path) -> None:
    """Exact: the chain file written every FLUSH_STEPS steps holds what
    emcee's HDFBackend, which opens the file at every step, writes (chain,
    log-probabilities, acceptance counts, generator state), and a run
    stopped by an exception between two writes keeps every step it made."""
    import emcee

    from pneumafit.identification.sampling import FLUSH_STEPS, BufferedHDFBackend

    def run(backend: emcee.backends.Backend, steps: int, stop_at: int | None = None) -> None:
        calls = 0

        def lp(z: np.ndarray) -> np.ndarray:
            nonlocal calls
            calls += 1
            if stop_at is not None and calls > stop_at:
                raise KeyboardInterrupt
            return -0.5 * np.sum(z * z, axis=1)

        backend.reset(8, 3)
        sampler = emcee.EnsembleSampler(8, 3, lp, vectorize=True, backend=backend)
        sampler._random.seed(5)
        start = np.random.default_rng(0).normal(size=(8, 3))
        try:
            sampler.run_mcmc(start, steps)
        finally:
            if isinstance(backend, BufferedHDFBackend):
                backend.flush()

    plain = emcee.backends.HDFBackend(str(tmp_path / "plain.h5"), name="s")
    run(plain, 3 * FLUSH_STEPS + 7)
    buffered = BufferedHDFBackend(str(tmp_path / "buffered.h5"), name="s")
    run(buffered, 3 * FLUSH_STEPS + 7)
    a = emcee.backends.HDFBackend(str(tmp_path / "plain.h5"), name="s", read_only=True)
    b = emcee.backends.HDFBackend(str(tmp_path / "buffered.h5"), name="s", read_only=True)
    assert a.iteration == b.iteration == 3 * FLUSH_STEPS + 7
    assert np.array_equal(a.get_chain(), b.get_chain())
    assert np.array_equal(a.get_log_prob(), b.get_log_prob())
    assert np.array_equal(a.accepted, b.accepted)
    for x, y in zip(a.random_state, b.random_state, strict=True):
        assert np.array_equal(x, y)
    # stopped after 30 steps of the second write's 50: none lost
    cut = BufferedHDFBackend(str(tmp_path / "cut.h5"), name="s")
    with pytest.raises(KeyboardInterrupt):
        # call 1 is the start; the stretch move calls once per half-ensemble
        run(cut, 3 * FLUSH_STEPS, stop_at=1 + 2 * (FLUSH_STEPS + 30))
    c = emcee.backends.HDFBackend(str(tmp_path / "cut.h5"), name="s", read_only=True)
    assert c.iteration == FLUSH_STEPS + 30
    assert np.array_equal(c.get_chain(), a.get_chain()[: FLUSH_STEPS + 30])
