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

Small-sample correction: at a few dozen tests the scores at x_hat are shrunk by
the test's own leverage (a test pulls the fit towards itself: the average shrink of
B is p / (number of tests), 40 % for 6 joints and 15 tests), which CR1's factor
G / (G - 1) (N - 1) / (N - p) does not undo. The cluster jackknife is used instead
(CR3, leave one test out): with x_(t) the fit without test t, one Newton step from
x_hat,

    x_(t) - x_hat = -(H - H_t)^-1 g_t,   H_t = X_t^T M_t X_t,
    cov(x_hat) = (G - 1) / G sum_t (x_(t) - x_hat - mean) (...)^T,

G the number of tests with a kept component. It tends to H^-1 B H^-T as the tests'
leverages go to 0 (large campaigns).

Streamed: every sum is over tests, so the arrays (design, covariances, residuals)
are taken by blocks of tests (they may be made when sliced,
:mod:`analysis.identification.streaming.per_test`): two passes (H, then the jackknife), memory
independent of the number of tests beyond the (m, 6) residuals and weights.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from analysis.identification.linalg import lsq

#: the correction in results.json
CORRECTION = ("cluster jackknife over tests (CR3): (G - 1)/G sum_t (x_(t) - x - mean)^2, "
              "x_(t) one Newton step without test t")


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
    ((rad/(N m))^2, the jackknife), ``sandwich`` (p, p) H^-1 B H^-T without the
    small-sample correction, ``fixed`` (p, p) the fixed-weight G Sigma G^T (the weights'
    dependence on the data left out), ``tests`` the clusters G; intervals use Student's t
    with :attr:`dof` degrees of freedom (the variance is estimated from G scores)."""

    cov: np.ndarray
    sandwich: np.ndarray
    fixed: np.ndarray
    tests: int

    @property
    def dof(self) -> int:
        """Degrees of freedom of the interval's Student t: tests G minus unknowns p."""
        return max(self.tests - self.cov.shape[0], 1)

    def describe(self) -> dict:
        """JSON-ready: the form, the correction and how the se compare to the other forms."""
        se = np.sqrt(np.diag(self.cov))
        return {
            "form": "M-estimator sandwich H^-1 B H^-T, H = sum psi'-weighted X^T M X, "
                    "B = sum over tests of the test's score g g^T (cluster = test)",
            "small_sample_correction": CORRECTION,
            "clusters": self.tests,
            "interval": (f"Student t with G - p = {self.dof} degrees of freedom"
                         if self.tests > self.cov.shape[0] else
                         f"Student t with 1 degree of freedom (G - p = "
                         f"{self.tests - self.cov.shape[0]}: too few tests, refused unless "
                         "accepted)"),
            "degrees_of_freedom": self.dof,
            # per identified joint, in the order of the joints
            "se_over_uncorrected_sandwich": [
                float(v) for v in se / np.sqrt(np.diag(self.sandwich))],
            "se_over_fixed_weights": [float(v) for v in se / np.sqrt(np.diag(self.fixed))],
        }


def _block_terms(A, cov, resid, kept, robust, c, weighted):
    """Per test of one block: score g = X^T h (b, p), H_t = -dg/dx = X^T M Z (b, p, p),
    Z = -dr/dx = diag(1/sigma) A (X = Z for the weighted fits)."""
    A = np.asarray(A, dtype=float)
    S = np.asarray(cov, dtype=float)
    sig = np.sqrt(np.where(kept, np.diagonal(S, axis1=-2, axis2=-1), 1.0))
    r = np.where(kept, resid, 0.0) / sig
    u, du = sqrt_weight(robust, r, c)
    u, du = u * kept, du * kept
    eye = np.eye(6)
    Z = A / sig[..., None] * kept[..., None]  # -dr/dx
    if weighted:
        both = kept[..., :, None] & kept[..., None, :]
        C = np.where(both, S / (sig[..., :, None] * sig[..., None, :]), eye)
        Ci = np.linalg.inv(C)  # C_kept^-1 on the kept block, identity elsewhere
        X = Z
    else:
        Ci = np.broadcast_to(eye, S.shape)
        X = A * sig[..., None] * kept[..., None]
    Civ = np.einsum("bij,bj->bi", Ci, u * r)
    h = u * Civ
    M = (du * Civ)[..., :, None] * eye + u[..., :, None] * Ci * (u + du * r)[..., None, :]
    g = np.einsum("bip,bi->bp", X, h)
    Ht = np.swapaxes(X, -1, -2) @ M @ Z
    return g, Ht


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
    for s in range(0, m, block):
        sl = slice(s, s + block)
        g, Ht = _block_terms(A[sl], cov[sl], resid[sl], kept[sl], robust, c, weighted)
        H += Ht.sum(axis=0)
        B += g.T @ g
    if S is not None:
        H = H - S
    Hi = np.linalg.inv(H)
    sandwich = Hi @ B @ Hi.T
    # second pass: the jackknife's leave-one-test-out steps
    G = int(np.any(kept, axis=1).sum())
    tot = np.zeros(p)
    sq = np.zeros((p, p))
    for s in range(0, m, block):
        sl = slice(s, s + block)
        g, Ht = _block_terms(A[sl], cov[sl], resid[sl], kept[sl], robust, c, weighted)
        delta = -np.linalg.solve(H - Ht, g[..., None])[..., 0]
        delta = delta * np.any(kept[sl], axis=1)[:, None]
        tot += delta.sum(axis=0)
        sq += delta.T @ delta
    mean = tot / max(G, 1)
    jack = (G - 1) / max(G, 1) * (sq - G * np.outer(mean, mean))
    return RobustCovariance(cov=0.5 * (jack + jack.T), sandwich=0.5 * (sandwich + sandwich.T),
                            fixed=fixed, tests=G)
