"""Covariance of a robust (Huber or Tukey) fit: the M-estimator sandwich, clustered by test.

The robust fit (:mod:`analysis.identification.estimators.irls`) solves, at its converged
weights, the estimating equation

    Psi(x) = sum_t g_t(x) = 0,   g_t = X_t^T h(r_t),   h(r) = U C^-1 U r,

one term per test t (its measured components kept by the fit), where

* r_t (n_t,) are the whitened residuals (d - f(x)) / sigma, sigma the noise model's
  standard deviation of each component (:func:`analysis.identification.noise.
  residual_covariance` at x);
* U = diag(u(r)) with u = sqrt(w) the square root of the robust weight (Huber
  u = min(1, sqrt(c/|r|)), Tukey u = max(0, 1 - (r/c)^2));
* for the weighted fits (wls, exact) C is the correlation matrix of the test's
  residual components (the wrench noise through the compliance correlates them) and
  X_t = diag(1/sigma) F_t, F_t (n_t, p) the model's Jacobian in x (the linear design A
  for wls); the fit's weight matrix is then diag(1/sigma) U C^-1 U diag(1/sigma), the
  noise covariance with component i's variance divided by w_i;
* for ols C = I and X_t = diag(sigma) F_t: h = w r = psi(r) and g_t = F_t^T diag(w) e_t,
  the unweighted fit with the robust weights.

With C = I, h_i = psi(r_i) (Huber psi(r) = max(-c, min(c, r)), Tukey's biweight
psi(r) = r (1 - (r/c)^2)^2): the classical M-estimator.

Linearised about the solution, x_hat - x = H^-1 Psi(x) with

    H = sum_t X_t^T M_t Z_t,   M_t = dh/dr = diag(u' o C^-1 U r) + U C^-1 diag(u + u' o r)

(the Gauss-Newton approximation: the derivatives of F, sigma and C in x are left
out; with C = I, M = diag(psi'(r)), and H = sum psi'(r) X^T X, Huber's "A"). Where the
fit corrects the wrench noise in the regressor
(:mod:`analysis.identification.corrections.wrench_eiv`: Psi(x) + S x = 0), H is H - S.
The tests are independent, but the components of one test are not (an F/T error moves
its whole regressor, and its six residuals share the wrench noise), so the variance of
Psi is estimated from the tests' scores, not the components' (cluster = test):

    B = sum_t g_t g_t^T (at x_hat),   cov(x_hat) = H^-1 B H^-T   (Huber's sandwich).

The reported covariance is not this B but a model-based meat with one scale per test.
With a few dozen tests, a B summed from G rank-one terms g_t g_t^T is a poor estimate:
a joint that rests on a few tests (unweighted ols at twice the loads: k1, k4) gets a
variance with 1.4-5.6 effective degrees of freedom, far fewer than the G - p = 9 of a
Student t (measured: z of k1 with an sd of 1.25, coverage 91.6 %; the cluster jackknife
CR3 used before). The noise model gives each test's score covariance up to a scale:
with the weights held fixed, h_t = Q_t r_t, Q_t = U C^-1 U, r_t the whitened residuals
of noise correlation R_t (= C_t for wls and exact), so

    Var(g_t) = rho_t X_t^T Q_t R_t Q_t X_t,

rho_t = 1 when the noise model holds. Each test's rho_t is estimated by the method of
moments from its own squared score, r_t^T N_t r_t = h_t^T C_t h_t (N_t = Q_t C_t Q_t),
over its expectation under the noise model at x_hat (the residuals shrunk by the test's
own leverage: r = e - Z (x_hat - x), x_hat - x = Hf^-1 sum_s X_s^T Q_s e_s at fixed
weights, Hf = sum X^T Q Z, Vf = Hf^-1 (sum X^T Q R Q X) Hf^-T):

    E_t = tr(N_t R_t) - 2 tr(N_t Z_t Hf^-1 X_t^T Q_t R_t) + tr(Z_t^T N_t Z_t Vf),
    rho_t = r_t^T N_t r_t / E_t,
    cov(x_hat) = H^-1 (sum_t rho_t X_t^T Q_t R_t Q_t X_t) H^-T.

A test's glitch that the weights do not remove (an F/T error moves the whole test's
regressor) raises its own rho_t, where the test's leverage puts it; the efficiency loss
of the M-estimator is in H (psi') and in rho (psi^2 over w^2 sigma^2). Each rho_t rests
on the test's n_t components instead of one direction, so the variance has many more
degrees of freedom; its t interval takes them per joint j by Satterthwaite's
approximation (2 E[v]^2 / Var[v] of v_j = sum_t rho_t a_tj, a_tj = (H^-1 X_t^T Q_t R_t
Q_t X_t H^-T)_jj, the rho_t independent with the relative variance of a Gaussian
quadratic form, 2 tr((N R)^2) / tr(N R)^2, leverage left out):

    nu_j = 2 (sum_t rho_t a_tj)^2 / sum_t (rho_t a_tj)^2 2 tr((N_t R_t)^2) / tr(N_t R_t)^2.

With the weights all 1 and the noise model exact (a Gaussian wls), rho_t ~ chi^2 / E_t
and cov(x_hat) tends to the fit's (A^T Sigma^-1 A)^-1; nu_j to 6 G for G equal tests.

Streamed: every sum is over tests, so the arrays (design, covariances, residuals)
are taken by blocks of tests (they may be made when sliced,
:mod:`analysis.identification.streaming.per_test`): two passes (H, Hf, B, then the scales),
memory independent of the number of tests beyond the (m, 6) residuals and weights.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from analysis.identification.linalg import lsq

#: the correction in results.json
CORRECTION = ("model-based meat with one scale per test: rho_t = r_t^T N_t r_t / E[...] "
              "under the noise model at fixed weights (leverage-corrected), cov = H^-1 "
              "(sum_t rho_t X_t^T Q_t R_t Q_t X_t) H^-T; Satterthwaite dof per joint")


def sqrt_weight(robust: str, r: np.ndarray, c: float) -> tuple[np.ndarray, np.ndarray]:
    """(u, du/dr): the square root u = sqrt(w) of the Huber or Tukey weight of whitened
    residuals r (any shape, dimensionless) and its derivative."""
    r = np.asarray(r, dtype=float)
    a = np.abs(r)
    if robust == "huber":
        out = a > c
        u = np.where(out, np.sqrt(c / np.where(out, a, 1.0)), 1.0)
        return u, np.where(out, -u / (2.0 * np.where(out, r, 1.0)), 0.0)
    if robust == "tukey":
        inside = a < c
        return (np.where(inside, 1.0 - (r / c) ** 2, 0.0),
                np.where(inside, -2.0 * r / c**2, 0.0))
    raise ValueError(f"unknown robust estimator {robust!r}")


@dataclass(frozen=True)
class RobustCovariance:
    """The sandwich of a robust fit: ``cov`` (p, p) the reported covariance of x
    ((rad/(N m))^2, the per-test-scale sandwich), ``sandwich`` (p, p) the cluster
    sandwich H^-1 B H^-T, ``fixed`` (p, p) the fixed-weight G Sigma G^T (the weights'
    dependence on the data left out), ``tests`` the tests G with a kept component;
    intervals use Student's t with ``dof_per_joint`` (p,) degrees of freedom
    (Satterthwaite, module docstring)."""

    cov: np.ndarray
    sandwich: np.ndarray
    fixed: np.ndarray
    tests: int
    dof_per_joint: np.ndarray

    @property
    def dof(self) -> np.ndarray:
        """(p,) degrees of freedom of each joint's Student t (Satterthwaite)."""
        return self.dof_per_joint

    def describe(self) -> dict:
        """JSON-ready: the form, the correction and how the se compare to the other forms."""
        se = np.sqrt(np.diag(self.cov))
        return {
            "form": "M-estimator sandwich H^-1 B H^-T, H = sum psi'-weighted X^T M X, "
                    "B = sum over tests of rho_t times the test's score covariance under "
                    "the noise model (tests independent)",
            "small_sample_correction": CORRECTION,
            "clusters": self.tests,
            "interval": ("Student t, each joint's degrees of freedom by Satterthwaite"
                         + ("" if self.tests > self.cov.shape[0] else
                            f" (G - p = {self.tests - self.cov.shape[0]}: too few tests, "
                            "refused unless accepted)")),
            "degrees_of_freedom": [float(v) for v in self.dof],
            # per identified joint, in the order of the joints
            "se_over_uncorrected_sandwich": [
                float(v) for v in se / np.sqrt(np.diag(self.sandwich))],
            "se_over_fixed_weights": [float(v) for v in se / np.sqrt(np.diag(self.fixed))],
        }


def _block_terms(A, cov, resid, kept, robust, c, weighted):
    """Per test of one block (b tests): the score g = X^T h (b, p), H_t = -dg/dx = X^T M Z
    (b, p, p), and the fixed-weight pieces Q = U C^-1 U (h = Q r), the noise correlation R
    of the whitened residuals, X and Z (b, 6, p), Z = -dr/dx = diag(1/sigma) A (X = Z for
    the weighted fits); C, R the identity on the components not kept."""
    A = np.asarray(A, dtype=float)
    S = np.asarray(cov, dtype=float)
    sig = np.sqrt(np.where(kept, np.diagonal(S, axis1=-2, axis2=-1), 1.0))
    r = np.where(kept, resid, 0.0) / sig
    u, du = sqrt_weight(robust, r, c)
    u, du = u * kept, du * kept
    eye = np.eye(6)
    Z = A / sig[..., None] * kept[..., None]  # -dr/dx
    both = kept[..., :, None] & kept[..., None, :]
    R = np.where(both, S / (sig[..., :, None] * sig[..., None, :]), eye)
    if weighted:
        C, Ci = R, np.linalg.inv(R)  # C_kept^-1 on the kept block, identity elsewhere
        X = Z
    else:
        C = Ci = np.broadcast_to(eye, S.shape)
        X = A * sig[..., None] * kept[..., None]
    Civ = np.einsum("bij,bj->bi", Ci, u * r)
    h = u * Civ
    M = (du * Civ)[..., :, None] * eye + u[..., :, None] * Ci * (u + du * r)[..., None, :]
    g = np.einsum("bip,bi->bp", X, h)
    Ht = np.swapaxes(X, -1, -2) @ M @ Z
    Q = u[..., :, None] * Ci * u[..., None, :]
    return _Terms(g=g, Ht=Ht, Q=Q, C=C, R=R, X=X, Z=Z, r=r)


@dataclass(frozen=True)
class _Terms:
    """:func:`_block_terms`' per-test arrays of one block."""

    g: np.ndarray
    Ht: np.ndarray
    Q: np.ndarray
    C: np.ndarray
    R: np.ndarray
    X: np.ndarray
    Z: np.ndarray
    r: np.ndarray


def _test_scales(t: _Terms, Hf_inv: np.ndarray, Vf: np.ndarray):
    """Per test of a block: (rho (b,), its relative variance under the noise model (b,),
    the test's model meat X^T Q R Q X (b, p, p)).

    rho = r^T N r / E[r^T N r], N = Q C Q (r^T N r = h^T C h, the test's squared score),
    the expectation under the noise model with the weights held fixed, at the fitted
    x_hat (the residuals r = e - Z (x_hat - x) shrunk by the test's own leverage):
    tr(N R) - 2 tr(N Z Hf^-1 X^T Q R) + tr(Z^T N Z Vf)."""
    Xt = np.swapaxes(t.X, -1, -2)
    N = t.Q @ t.C @ t.Q
    obs = np.einsum("bi,bij,bj->b", t.r, N, t.r)
    NR = N @ t.R
    QR = t.Q @ t.R
    cross = np.einsum("bij,bji->b", N, (t.Z @ Hf_inv) @ (Xt @ QR))
    quad = np.einsum("bij,bji->b", N, (t.Z @ Vf) @ np.swapaxes(t.Z, -1, -2))
    expect = np.einsum("bii->b", NR) - 2.0 * cross + quad
    ok = expect > 0
    rho = np.where(ok, obs / np.where(ok, expect, 1.0), 0.0)
    tr2 = np.einsum("bij,bji->b", NR, NR)
    tr1 = np.einsum("bii->b", NR)
    relvar = np.where(tr1 > 0, 2.0 * tr2 / np.where(tr1 > 0, tr1, 1.0) ** 2, 0.0)
    meat = Xt @ QR @ t.Q @ t.X
    return rho, relvar, meat


def robust_covariance(A, cov, resid: np.ndarray, kept: np.ndarray, robust: str, c: float,
                      weighted: bool, fixed: np.ndarray, S: np.ndarray | None = None,
                      block: int | None = None) -> RobustCovariance:
    """The sandwich covariance of a robust fit (module docstring).

    Parameters
    ----------
    A : (m, 6, p) the model's Jacobian in x at the solution (m or rad per rad/(N m)),
        zero rows where not measured; may be made when sliced.
    cov : (m, 6, 6) the noise model's unweighted residual covariance at the solution
        (m^2, rad^2); may be made when sliced.
    resid : (m, 6) d - f(x) at the solution (m, rad); any value where not kept.
    kept : (m, 6) bool, measured components with a weight > 0.
    robust, c : "huber" or "tukey" and its tuning constant.
    weighted : True for wls and exact (weights from the noise covariance), False for ols.
    fixed : (p, p) the fixed-weight covariance G Sigma G^T, reported beside.
    S : (p, p) the errors-in-variables matrix the fit's estimating equation adds
        (:func:`analysis.identification.corrections.wrench_eiv.wrench_eiv_matrix` with the
        fit's weights), or None.
    block : tests per block (default :data:`analysis.identification.linalg.lsq.TEST_BLOCK`).
    """
    m, p = A.shape[0], A.shape[-1]
    block = lsq.TEST_BLOCK if block is None else block
    H = np.zeros((p, p))
    B = np.zeros((p, p))
    Hf = np.zeros((p, p))
    K = np.zeros((p, p))
    for s in range(0, m, block):
        sl = slice(s, s + block)
        t = _block_terms(A[sl], cov[sl], resid[sl], kept[sl], robust, c, weighted)
        H += t.Ht.sum(axis=0)
        B += t.g.T @ t.g
        Xt = np.swapaxes(t.X, -1, -2)
        Hf += (Xt @ t.Q @ t.Z).sum(axis=0)
        K += (Xt @ t.Q @ t.R @ t.Q @ t.X).sum(axis=0)
    if S is not None:
        H = H - S
    Hi = np.linalg.inv(H)
    sandwich = Hi @ B @ Hi.T
    Hf_inv = np.linalg.inv(Hf)
    Vf = Hf_inv @ K @ Hf_inv.T
    # second pass: each test's scale rho_t and the per-joint Satterthwaite sums
    meat = np.zeros((p, p))
    total = np.zeros(p)  # sum_t rho_t v_tj, v_t = diag(H^-1 meat_t H^-T)
    spread = np.zeros(p)  # sum_t (rho_t v_tj)^2 relvar_t
    G = 0
    for s in range(0, m, block):
        sl = slice(s, s + block)
        t = _block_terms(A[sl], cov[sl], resid[sl], kept[sl], robust, c, weighted)
        rho, relvar, meat_t = _test_scales(t, Hf_inv, Vf)
        G += int(np.any(kept[sl], axis=1).sum())
        meat += np.einsum("b,bpq->pq", rho, meat_t)
        v = rho[:, None] * np.einsum("jp,bpq,jq->bj", Hi, meat_t, Hi)
        total += v.sum(axis=0)
        spread += (v**2 * relvar[:, None]).sum(axis=0)
    cov_x = Hi @ meat @ Hi.T
    dof = np.where(spread > 0, 2.0 * total**2 / np.where(spread > 0, spread, 1.0), np.inf)
    return RobustCovariance(cov=0.5 * (cov_x + cov_x.T),
                            sandwich=0.5 * (sandwich + sandwich.T), fixed=fixed, tests=G,
                            dof_per_joint=np.maximum(dof, 1.0))
