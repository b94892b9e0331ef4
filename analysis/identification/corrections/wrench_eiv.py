"""Errors in the measured wrench (errors-in-variables): the bias they cause and its correction.

The regressor of the linear model, ``A(w) = J diag(J^T w)`` (column j:
``J_j (J_j . w)``, :func:`analysis.identification.estimators.linear_model.design_block`), is
built from the *measured* wrench ``w_m = w + e_w``. Since A is linear in w,
``A(w_m) = A(w) + A(e_w)`` and, for any weights W independent of e_w,

    E[A_m^T W A_m] = A^T W A + S,    E[A_m^T W d] = A^T W A x,

    S = sum_tests E[A(e_w)^T W A(e_w)],
    S_jk = sum_tests (J_j^T W J_k) (J_j^T Sigma_w J_k)

(a Hadamard product of two p x p matrices per test; ``Sigma_w`` (6, 6) the
covariance of the wrench reading, N^2 and (N m)^2). The least-squares estimate
of the compliances x is therefore attenuated, ``x_hat -> (N + S)^-1 N x`` with
``N = A^T W A``: a relative bias of order ``(sigma_w / |w|)^2``. With the default
force/torque figures (15.6 N, 2.5 N m against loads of 1-2.5 kN and 100-300 N m)
that is 1e-4..5e-4 of x: invisible at tens of tests, several standard errors at
1e5 (the standard error falls as 1/sqrt(m), the bias does not).

The corrected (bias-compensated) least squares solves
``(A_m^T W A_m - S) x = A_m^T W d``, i.e. from the plain solution x_hat and
``bread = (A_m^T W A_m)^-1``:

    x_c = (I - bread S)^-1 x_hat,    bread_c = (A_m^T W A_m - S)^-1 = (I - bread S)^-1 bread.

For the Gauss-Newton fit of the exact model the score ``F^T W (d - f(x))`` has
the same expectation ``-S x`` (f is linear in w up to the ~1 % linearisation
term), and the corrected estimating equation is ``F^T W (d - f(x)) + S x = 0``.
One Newton step on it from the uncorrected minimum (where the score is 0) is
the same formula with ``bread = (F^T W F)^-1``; its error is second order in the
shift (~1e-8 of x).

Joint-angle (encoder) noise enters A through J(q_m) the same way, with
relative size ``(sigma_q * d ln J / dq)^2 ~ (5e-6)^2``: measured on 1e5 simulated
KR240-2 tests, switching it off moves no (k - k_true) / se by more than 0.01; its
bias is estimated and added to the intervals as a systematic term by
:mod:`analysis.identification.corrections.encoder_eiv`. Displacement noise does not enter A.

Units: J rows m/rad (translations) and rad/rad (rotations); W the inverse of the
residual covariance (1/m^2, 1/rad^2; identity for OLS); S has the units of
A^T W A.
"""

from __future__ import annotations

import numpy as np

#: tests per block (the (block, 6, p) temporaries stay in cache; no (m, m) array anywhere)
EIV_BLOCK = 8192


def wrench_eiv_matrix(J: np.ndarray, wrench_cov: np.ndarray, Linv: np.ndarray | None = None,
                      measured: np.ndarray | None = None, group: np.ndarray | None = None,
                      n_groups: int = 0, block: int = EIV_BLOCK,
                      cols: list[int] | None = None) -> np.ndarray:
    """S (..., p, p) = sum_tests (J^T W J) o (J^T Sigma_w J) (Hadamard product), blockwise.

    Parameters
    ----------
    J : (..., m, 6, p) the columns of the Jacobian of the identified joints (m/rad, rad/rad).
    wrench_cov : covariance of each wrench reading (N^2, N^2 m, (N m)^2): (..., m, 6, 6),
        or its diagonal (..., m, 6), or one (6,) for all tests.
    Linv : (..., m, 6, 6) whitening factors, W = Linv^T Linv (rows of unmeasured
        components zero), or None for W = diag(measured) (OLS).
    measured : (..., m, 6) bool, used when ``Linv`` is None (all measured if None too).
    group, n_groups : one campaign only (J (m, 6, p)): sum per group instead, group (m,)
        ints in [0, n_groups) -> (n_groups, p, p) (leave-one-pose-out folds).
    cols : the columns of J to use (J then holds all the joints' columns, (..., m, 6, n)),
        taken block by block: no copy of the columns of 1e6 tests (0.3 GB); None: all.

    Returns the expectation of ``A(e_w)^T W A(e_w)`` summed over the tests, the
    amount by which the normal matrix built from measured wrenches exceeds the
    noise-free one on average (units of A^T W A).
    """
    if not hasattr(J, "_make"):  # a per-test J made when sliced stays as it is
        J = np.asarray(J, dtype=float)
    cov = np.asarray(wrench_cov, dtype=float)
    m, p = J.shape[-3], J.shape[-1] if cols is None else len(cols)
    S = np.zeros((n_groups, p, p) if group is not None else J.shape[:-3] + (p, p))
    for s in range(0, m, block):
        sl = slice(s, s + block)
        Jb = J[sl] if J.ndim == 3 else J[..., sl, :, :]
        if cols is not None:
            Jb = Jb[..., cols]
        if Linv is not None:
            B = (Linv[sl] if Linv.ndim == 3 else Linv[..., sl, :, :]) @ Jb
        elif measured is not None:
            B = Jb * measured[..., sl, :, None]
        else:
            B = Jb
        P = np.swapaxes(B, -1, -2) @ B  # J^T W J per test
        if cov.ndim >= 2 and cov.shape[-2:] == (6, 6) and cov.ndim == J.ndim:
            Q = np.swapaxes(Jb, -1, -2) @ (cov[..., sl, :, :] @ Jb)
        else:
            diag = cov[..., sl, :] if cov.ndim == J.ndim - 1 else cov
            Q = np.swapaxes(Jb, -1, -2) @ (Jb * diag[..., :, None])
        if group is None:
            S += np.sum(P * Q, axis=-3)
        else:
            np.add.at(S, group[sl], P * Q)
    return S


def corrected(x: np.ndarray, bread: np.ndarray, S: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(x_c, bread_c): the bias-compensated solution and (N - S)^-1, from x (..., p),
    bread = N^-1 (..., p, p) and S (..., p, p) (module docstring)."""
    p = x.shape[-1]
    M = np.eye(p) - bread @ S
    return np.linalg.solve(M, x[..., None])[..., 0], np.linalg.solve(M, bread)


def shift_summary(joints: tuple[int, ...], x: np.ndarray, shift: np.ndarray, se_x: np.ndarray,
                  noise) -> dict:
    """What the correction did, for results.json and the warnings.

    ``x`` (p,) the corrected compliances, ``shift`` (p,) x minus the uncorrected ones,
    ``se_x`` (p,) their standard errors (rad/(N m)); ``noise`` the
    :class:`~analysis.identification.noise.NoiseModel` whose F/T figures S rests on.
    The shift of k is ``1/x - 1/(x - shift)`` (N m/rad), in units of se_k = se_x / x^2.
    """
    x = np.asarray(x, dtype=float)
    raw = x - shift
    with np.errstate(divide="ignore", invalid="ignore"):
        dk = 1.0 / x - 1.0 / raw
        dk_se = dk / (se_x / x**2)
    finite = np.where(np.isfinite(dk_se), np.abs(dk_se), -1.0)
    worst = int(np.argmax(finite))
    rel = ""
    if noise.force_relative or noise.moment_relative:
        rel = (f" + {100 * noise.force_relative:.3g} % / {100 * noise.moment_relative:.3g} % "
               "of the reading")
    note = (f"wrench noise errors-in-variables corrected with the F/T noise figures "
            f"({noise.force_sigma:.3g} N, {noise.moment_sigma:.3g} N m per component{rel}): "
            f"shift of k up to {finite[worst]:.2g} se (joint {joints[worst] + 1}, "
            f"{100 * dk[worst] * x[worst]:+.2g} %); wrong F/T figures leave a bias of this "
            "order")

    def num(v):
        return float(v) if np.isfinite(v) else None

    out: list = [None] * 6
    rel_k: list = [None] * 6
    for i, j in enumerate(joints):
        out[j] = num(dk_se[i])
        rel_k[j] = num(dk[i] * x[i])
    return {"corrected": True, "force_sigma_N": noise.force_sigma,
            "moment_sigma_Nm": noise.moment_sigma,
            "force_relative_percent": 100 * noise.force_relative,
            "moment_relative_percent": 100 * noise.moment_relative,
            "shift_of_k_in_se": out, "relative_shift_of_k": rel_k,
            "max_abs_shift_in_se": num(finite[worst]), "note": note}
