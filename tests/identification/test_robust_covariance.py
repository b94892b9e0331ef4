"""The robust fits' sandwich covariance against a dense computation from its definition.

``robust_covariance`` factors the weighted fit's estimating equation as
X^T U C^-1 U r and differentiates it analytically; here the same equation is written
the way the fit solves it, Psi(x) = sum_t A_t^T W_t(x) e_t(x) with W_t the inverse of
the noise covariance whose component i's variance is divided by its weight w(r_i)
(ols: W_t = diag(w)), on a small random linear problem, and differentiated by central
differences. The reweighting's convergence criterion is tested on a scripted sequence.
"""

from __future__ import annotations

import numpy as np
import pytest

from analysis.errors import InputError
from analysis.identification.estimators import irls as robust
from analysis.identification.estimators.irls import HUBER_C, TUKEY_C, huber_weight, tukey_weight
from analysis.identification.estimators.robust_covariance import robust_covariance, sqrt_weight

M, P = 12, 3  # tests, unknowns


def _problem(seed, robust_mode):
    """A (M, 6, P), SPD cov (M, 6, 6), residuals e (M, 6) with glitches, kept (M, 6)."""
    rng = np.random.default_rng(seed)
    A = rng.normal(size=(M, 6, P))
    L = rng.normal(size=(M, 6, 6)) * 0.3 + np.eye(6)
    cov = L @ np.swapaxes(L, -1, -2) * 1e-2
    kept = np.ones((M, 6), bool)
    kept[2, 4] = kept[7, 0] = False  # not measured
    A = A * kept[..., None]
    sig = np.sqrt(np.diagonal(cov, axis1=-2, axis2=-1))
    r = rng.normal(size=(M, 6))
    if robust_mode == "huber":
        r[1, 2], r[5, 5], r[9, 1] = 8.0, -3.0, 2.0  # glitches, down-weighted
    else:  # every |r| < c: the weights stay > 0 (the component stays in the fit)
        r = np.clip(r, -3.5, 3.5)
        r[1, 2], r[5, 5] = 4.2, -3.9
    return A, cov, r * sig, kept


def _weights(robust_mode, r):
    return huber_weight(r) if robust_mode == "huber" else tukey_weight(r)


def _score(A, cov, e, kept, robust_mode, weighted, t):
    """Test t's term of Psi, written as the fit's weighted normal equation (dense)."""
    k = kept[t]
    sig = np.sqrt(np.diag(cov[t])[k])
    w = _weights(robust_mode, e[t][k] / sig)
    if weighted:  # Sigma_w = D^-1/2 Sigma D^-1/2 on the kept components
        Sw = cov[t][np.ix_(k, k)] / np.sqrt(np.outer(w, w))
        return A[t][k].T @ np.linalg.solve(Sw, e[t][k])
    return A[t][k].T @ (w * e[t][k])


def _dense(A, cov, e, kept, robust_mode, weighted, skip=None):
    """(Psi at e, its Jacobian -dPsi/dx by central differences) over the tests but ``skip``."""
    tests = [t for t in range(M) if t != skip]

    def psi(dx):
        e_x = e - np.einsum("mip,p->mi", A, dx)
        return sum(_score(A, cov, e_x, kept, robust_mode, weighted, t) for t in tests)

    h = 1e-6
    J = np.column_stack([-(psi(h * np.eye(P)[j]) - psi(-h * np.eye(P)[j])) / (2 * h)
                         for j in range(P)])
    return psi(np.zeros(P)), J


def _dense_scaled(A, cov, e, kept, robust_mode, weighted, H):
    """The per-test-scale sandwich and its Satterthwaite dof written densely: the fixed
    weights' estimator as one (n, n) residual-maker L (r = L eps on the kept components,
    eps ~ N(0, R) the whitened noise), E[r_t^T N_t r_t] from L R L^T."""
    idx = [(t, i) for t in range(M) for i in range(6) if kept[t, i]]
    n = len(idx)
    sig = np.sqrt(np.array([cov[t, i, i] for t, i in idx]))
    r = np.array([e[t, i] for t, i in idx]) / sig
    w = _weights(robust_mode, r)
    Z = np.array([A[t, i] for t, i in idx]) / sig[:, None]
    X = Z if weighted else Z * sig[:, None] ** 2
    R = np.zeros((n, n))
    for a_, (t, i) in enumerate(idx):
        for b_, (s_, j) in enumerate(idx):
            if t == s_:
                R[a_, b_] = cov[t, i, j] / (sig[a_] * sig[b_])
    C = R if weighted else np.eye(n)
    Q = np.sqrt(w)[:, None] * np.linalg.inv(C) * np.sqrt(w)[None, :]  # block-diagonal
    Hf = X.T @ Q @ Z
    L = np.eye(n) - Z @ np.linalg.solve(Hf, X.T @ Q)
    E = L @ R @ L.T
    Hi = np.linalg.inv(H)
    meat, v = np.zeros((P, P)), []
    for t in range(M):
        k = [a_ for a_, (tt, _) in enumerate(idx) if tt == t]
        N = Q[np.ix_(k, k)] @ C[np.ix_(k, k)] @ Q[np.ix_(k, k)]
        rho = r[k] @ N @ r[k] / np.trace(N @ E[np.ix_(k, k)])
        Xq = X[k].T @ Q[np.ix_(k, k)]
        meat_t = Xq @ R[np.ix_(k, k)] @ Xq.T
        meat += rho * meat_t
        NR = N @ R[np.ix_(k, k)]
        v.append((rho * np.diag(Hi @ meat_t @ Hi.T), 2 * np.trace(NR @ NR) / np.trace(NR) ** 2))
    tot = sum(vt for vt, _ in v)
    spread = sum(vt**2 * rv for vt, rv in v)
    return Hi @ meat @ Hi.T, 2 * tot**2 / spread


@pytest.mark.parametrize("weighted", [True, False], ids=["wls-exact", "ols"])
@pytest.mark.parametrize("robust_mode", ["huber", "tukey"])
def test_sandwich_against_dense_definition(robust_mode, weighted):
    """H, B, the uncorrected sandwich and the reported per-test-scale sandwich with its
    Satterthwaite dof equal the dense computation to 1e-6 (central differences of step
    1e-6 on residuals of ~0.1: truncation ~1e-10 relative; the weights are piecewise
    smooth and no residual sits within 1e-5 of a kink)."""
    A, cov, e, kept = _problem(1, robust_mode)
    c = HUBER_C if robust_mode == "huber" else TUKEY_C
    out = robust_covariance(A, cov, e, kept, robust_mode, c, weighted=weighted,
                            fixed=np.eye(P))
    _, H = _dense(A, cov, e, kept, robust_mode, weighted)
    g = np.array([_score(A, cov, e, kept, robust_mode, weighted, t) for t in range(M)])
    Hi = np.linalg.inv(H)
    sandwich = Hi @ (g.T @ g) @ Hi.T
    np.testing.assert_allclose(out.sandwich, sandwich, rtol=1e-6,
                               atol=1e-6 * np.abs(sandwich).max())
    scaled, dof = _dense_scaled(A, cov, e, kept, robust_mode, weighted, H)
    np.testing.assert_allclose(out.cov, scaled, rtol=1e-6, atol=1e-6 * np.abs(scaled).max())
    np.testing.assert_allclose(out.dof, dof, rtol=1e-6)
    assert out.tests == M and np.all((out.dof > 1) & (out.dof < 6 * M))


def test_scaled_sandwich_on_gaussian_replicates():
    """Known values: M identical tests, unit weights (every |r| tiny), weighted: each test's
    scale is r^T R^-1 r over its expectation (n_t - p/M) ... and the dof are
    Satterthwaite's for M equal terms of relative variance 2/6: 6 M = 72."""
    A1 = np.random.default_rng(5).normal(size=(6, P))
    A = np.broadcast_to(A1, (M, 6, P)).copy()
    cov = np.broadcast_to(np.diag([1.0, 2.0, 0.5, 1.5, 1.0, 3.0]) * 1e-2, (M, 6, 6)).copy()
    sig = np.sqrt(np.diagonal(cov, axis1=-2, axis2=-1))
    e = np.full((M, 6), 0.3) * sig  # |r| = 0.3 < c: weights 1
    kept = np.ones((M, 6), bool)
    out = robust_covariance(A, cov, e, kept, "huber", HUBER_C, True, np.eye(P))
    np.testing.assert_allclose(out.dof, 6 * M, rtol=1e-12)
    # rho = (6 x 0.09) / (6 - P / M x ... ): the expectation of r^T r at x_hat is
    # n_t - p / M per test (the hat matrix's trace p shared by M equal tests)
    rho = 6 * 0.09 / (6 - P / M)
    Z = A1 / sig[0][:, None]
    np.testing.assert_allclose(out.cov, rho * np.linalg.inv(M * Z.T @ Z), rtol=1e-10)


def test_sandwich_is_the_same_block_by_block():
    """The streamed form (blocks of 5 tests: 5, 5, 2) equals one block, to 1e-12."""
    A, cov, e, kept = _problem(2, "huber")
    S = 0.01 * np.eye(P)
    one = robust_covariance(A, cov, e, kept, "huber", HUBER_C, True, np.eye(P), S=S)
    blocks = robust_covariance(A, cov, e, kept, "huber", HUBER_C, True, np.eye(P), S=S,
                               block=5)
    np.testing.assert_allclose(blocks.cov, one.cov, rtol=1e-12)
    np.testing.assert_allclose(blocks.sandwich, one.sandwich, rtol=1e-12)
    np.testing.assert_allclose(blocks.dof, one.dof, rtol=1e-12)


def test_sqrt_weight_derivative():
    """u = sqrt(w) and du/dr against central differences (away from the kinks)."""
    r = np.array([-9.0, -2.0, -0.7, 0.3, 1.9, 4.0, 6.0])
    for mode, w, c in (("huber", huber_weight, HUBER_C), ("tukey", tukey_weight, TUKEY_C)):
        u, du = sqrt_weight(mode, r, c)
        np.testing.assert_allclose(u**2, w(r), rtol=1e-14)
        h = 1e-6
        num = (sqrt_weight(mode, r + h, c)[0] - sqrt_weight(mode, r - h, c)[0]) / (2 * h)
        np.testing.assert_allclose(du, num, rtol=1e-6, atol=1e-9)


def _scripted(monkeypatch, changes):
    """Run robust._irls on a stand-in problem whose weights move by ``changes[i]`` at
    iteration i + 1 (then 0); returns its iterations or the refusal."""
    class T:
        measured = np.ones((1, 6), bool)
        d = np.zeros((1, 6))
        line = np.array([2])

    it = {"n": 0}
    monkeypatch.setattr(robust, "_weighted_fit",
                        lambda *a: type("F", (), {"x": np.zeros(1)})())
    monkeypatch.setattr(robust, "_model", lambda *a: (np.zeros((1, 6)), None))
    monkeypatch.setattr(robust, "_sigma", lambda *a: np.ones((1, 6)))

    def weight_fn(r, c):
        n = it["n"]
        it["n"] += 1
        return np.full((1, 6), 0.5 + (changes[n] if n < len(changes) else 0.0))

    base = np.full((1, 6), 0.5)
    # each call's weights differ from the previous call's by the difference of changes
    # misfit None: the prediction from _model (as for exact), no misfit iteration
    return robust._irls(None, T, (0,), None, "wls", weight_fn, 1.0, np.zeros(1), base,
                        None, None, None)


def test_reweighting_criterion(monkeypatch):
    """Past MAX_ITER (50) the reweighting goes on while the largest weight change halves
    every 10 iterations (here: a rate of 0.9 per iteration, settling to 1e-6 at 112), and
    is refused when it does not (an oscillation between two weight sets: at 50)."""
    # weights 0.5 + 0.9^n at call n: iteration k >= 2 moves them by 0.1 0.9^(k - 2)
    seq = [0.9**n for n in range(400)]
    n_it = _scripted(monkeypatch, seq)[3]
    expected = 2 + int(np.ceil(np.log(robust.WEIGHT_TOL / 0.1) / np.log(0.9)))
    assert n_it == expected == 112
    monkeypatch.undo()
    flip = [0.1 * ((n + 1) % 2) for n in range(400)]
    with pytest.raises(InputError, match="did not settle in 50 reweighting") as err:
        _scripted(monkeypatch, flip)
    assert err.value.where == "--robust"


@pytest.fixture(scope="module")
def large_campaign(kr240, w_eff):
    """400 tests (40 poses x 10 loads), 2 % of them with a 20-sigma tracker glitch."""
    from analysis.identification.io.measurements import TestArrays
    from analysis.identification.studies.robustness import sample_poses

    from ._sim import simulate
    from .test_robust import NOISE

    rng = np.random.default_rng(8)
    poses = sample_poses(kr240, 40, rng, min_inverse_condition=0.3)
    q = np.repeat(poses, 10, axis=0)
    w = w_eff * rng.uniform(0.3, 0.6, size=(len(q), 1)) * rng.choice([-1.0, 1.0], (len(q), 1))
    sim = simulate(kr240, q, w, kr240.nominal_stiffness, NOISE, seed=4)
    d = sim.d.copy()
    hit = rng.choice(len(q), 8, replace=False)
    d[hit, rng.integers(0, 3, 8)] += 20 * NOISE.translation_sigma
    names = np.repeat([f"Z{i + 1}" for i in range(len(poses))], 10)
    return TestArrays(pose=names, q=sim.q, w=sim.w, d=d, measured=sim.measured,
                      line=sim.line)


@pytest.mark.parametrize(("method", "mode"), [("ols", "huber"), ("wls", "tukey"),
                                              ("exact", "huber")])
def test_streamed_robust_equals_in_memory(kr240, large_campaign, method, mode, monkeypatch):
    """The robust fit of a campaign whose J, design and model Jacobian are made when sliced
    (LAZY_TESTS 300, blocks of 97 tests) gives the in-memory estimate and sandwich
    covariance, to 1e-8 relative (backward-stable factorisations of the same systems)."""
    from analysis.identification.estimate import identify
    from analysis.identification.estimators import fit_solvers
    from analysis.identification.linalg import lsq
    from analysis.identification.streaming import blocks, per_test
    from analysis.identification.streaming.per_test import PerTestJacobian

    from .test_robust import NOISE

    ref = identify(kr240, large_campaign, method, noise=NOISE, validate=False, robust=mode)
    monkeypatch.setattr(lsq, "TALL_ROWS", 600)
    monkeypatch.setattr(lsq, "TEST_BLOCK", 97)
    monkeypatch.setattr(blocks, "EVAL_BLOCK", 101)
    monkeypatch.setattr(per_test, "LAZY_TESTS", 300)
    assert isinstance(fit_solvers.jacobian_blocks(kr240, large_campaign.q), PerTestJacobian)
    res = identify(kr240, large_campaign, method, noise=NOISE, validate=False, robust=mode)
    np.testing.assert_allclose(res.x, ref.x, rtol=1e-8)
    np.testing.assert_allclose(res.cov_x, ref.cov_x, rtol=1e-8)
    assert res.robust["covariance"]["clusters"] == 400
    assert len(res.robust["down_weighted"]) >= 6  # the glitches found
