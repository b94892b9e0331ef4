"""Validation by prediction on held-out poses (leave one pose out).

Each distinct pose in turn (tests at joint angles equal to within the encoder
noise, :mod:`analysis.identification.poses`, named by their labels) is removed,
the joint compliances are identified from the other tests with the same estimator, and the held-out
displacements are predicted (linear model for ols/wls, exact equilibrium for
exact). Reported per held-out pose: RMS prediction error of the translations
(m) and rotations (rad), and the RMS of the errors divided by the
measurement sigma (about 1 for a model that predicts to within the noise;
somewhat more because the estimate itself is uncertain).

For ols the refits are one batched computation: with the thin QR ``A = Q R``
of the full stacked design and ``U = A R^-1``, removing the rows H of a pose
gives ``x_-H = R^-1 (I - U_H^T U_H)^-1 (Q^T d - U_H^T d_H)``: a p x p solve per
pose (its conditioning is that of the pose's leverage, not A's squared). For
exact, each refit starts from the full-data estimate (warm start).
"""

from __future__ import annotations

import numpy as np
import pandas as pd

from analysis.errors import InputError
from analysis.identification.exact_fit import model_displacement
from analysis.identification.fitting import (
    COND_LIMIT,
    check_identifiable,
    check_tests,
    fit,
    fit_exact,
)
from analysis.identification.linear_model import design_block
from analysis.identification.measurements import TestArrays
from analysis.identification.noise import NoiseModel, residual_covariance
from analysis.identification.poses import group_names, pose_groups, pose_tolerance
from analysis.model.kinematics import jacobian
from analysis.model.robot_model import RobotModel


def _rms(values: np.ndarray) -> float:
    return float(np.sqrt(np.mean(values**2))) if values.size else float("nan")


def leave_one_pose_out(
    robot: RobotModel,
    tests: TestArrays,
    method: str,
    joints: tuple[int, ...],
    noise: NoiseModel,
    batched: bool = True,
) -> pd.DataFrame | None:
    """Table of held-out prediction errors, or None with fewer than 3 distinct poses.

    ``batched=False`` refits from scratch for every pose (the reference path).
    """
    group = pose_groups(tests.q, pose_tolerance(noise))
    names = group_names(tests.pose, group)
    if len(names) < 3:
        return None
    if batched and method == "ols":
        try:
            check_tests(robot, tests, joints)  # row checks hold for every subset then
        except InputError:
            batched = False
        else:
            return _ols_batched(robot, tests, group, names, joints, noise)
    start = None
    if batched and method == "exact":
        try:
            start = fit(robot, tests, joints, noise, method).x
        except InputError:
            start = None
    rows = []
    for g, label in enumerate(names):
        held = group == g
        train, test = tests.subset(~held), tests.subset(held)
        row = {"held_out_pose": label, "n_tests": int(held.sum())}
        try:
            check_tests(robot, train, joints, noise)
            J = jacobian(robot, train.q)
            A = design_block(J, train.w)[..., list(joints)] * train.measured[..., None]
            check_identifiable(A, joints)
            if start is not None:
                x_p = fit_exact(robot, train, joints, noise, start).x
            else:
                x_p = fit(robot, train, joints, noise, method).x
        except InputError as err:
            rows.append({**row, "rms_translation_m": np.nan, "rms_rotation_rad": np.nan,
                         "rms_normalized": np.nan, "note": str(err)})
            continue
        x = np.zeros(6)
        x[list(joints)] = x_p
        if method == "exact":
            pred, _ = model_displacement(robot, test.q, x, test.w, with_jacobian=False)
        else:
            pred = np.einsum("mrj,j->mr", design_block(jacobian(robot, test.q), test.w), x)
        err = np.where(test.measured, test.d - pred, np.nan)
        Jt = jacobian(robot, test.q)
        C = np.einsum("...ij,j,...kj->...ik", Jt, x, Jt)
        sig = np.sqrt(np.diagonal(residual_covariance(noise, C, test.w), axis1=-2, axis2=-1))
        norm = err / sig
        rows.append({
            **row,
            "rms_translation_m": _rms(err[:, :3][test.measured[:, :3]]),
            "rms_rotation_rad": _rms(err[:, 3:][test.measured[:, 3:]]),
            "rms_normalized": _rms(norm[test.measured]),
            "note": "",
        })
    return pd.DataFrame(rows)


def _ols_batched(robot, tests, fold, labels, joints, noise) -> pd.DataFrame:
    """Leave-one-pose-out for ols in one batched computation (see the module docstring)."""
    from scipy.linalg import solve_triangular

    cols = list(joints)
    J = jacobian(robot, tests.q)
    A = design_block(J, tests.w)[..., cols] * tests.measured[..., None]  # (m, 6, p)
    dz = np.where(tests.measured, tests.d, 0.0)
    m, p = A.shape[0], A.shape[-1]
    scale = np.linalg.norm(A.reshape(-1, p), axis=0)
    scale = np.where(scale > 0, scale, 1.0)
    Q, R = np.linalg.qr(A.reshape(-1, p) / scale)
    c = Q.T @ dz.reshape(-1)
    U = solve_triangular(R, (A.reshape(-1, p) / scale).T, trans="T").T.reshape(m, 6, p)
    P = len(labels)  # fold: the pose group of each test, as in the reference path
    S = np.zeros((P, p, p))
    np.add.at(S, fold, np.einsum("mri,mrj->mij", U, U))
    t = np.zeros((P, p))
    np.add.at(t, fold, np.einsum("mri,mr->mi", U, dz))
    with np.errstate(divide="ignore", invalid="ignore"):
        lev = np.linalg.eigvalsh(S)[:, -1]  # largest leverage of each pose block
    ok = lev < 1.0 - 1e-10
    # Training-set condition of the column-scaled A without forming it: its Gram matrix
    # is R^T (I - S_h) R = M_h^T M_h with M_h = chol(I - S_h)^T R (p x p).
    cond = np.full(P, np.inf)
    if ok.any():
        Lh = np.linalg.cholesky(np.eye(p) - S[ok])
        M = np.swapaxes(Lh, -1, -2) @ R
        norms = np.linalg.norm(M, axis=-2)
        sv = np.linalg.svd(M / np.where(norms > 0, norms, 1.0)[:, None, :], compute_uv=False)
        with np.errstate(divide="ignore"):
            cond[ok] = np.where(np.all(norms > 0, axis=-1), sv[:, 0] / sv[:, -1], np.inf)
    # Per-fold refusals of the reference path that depend on the training subset.
    n_eq = int(tests.measured.sum()) - np.bincount(fold, tests.measured.sum(axis=1), P)
    # folds are whole pose groups, so every training set keeps P - 1 >= 2 distinct poses
    suspect = ~ok | (cond > COND_LIMIT) | (n_eq < p)
    notes = [""] * P
    for h in np.flatnonzero(suspect):
        # the reference path's own checks give the message (and the verdict)
        train = fold != h
        try:
            check_tests(robot, tests.subset(train), joints)
            check_identifiable(A[train], joints)
        except InputError as err:
            notes[h], ok[h] = str(err), False
            continue
        if not ok[h]:
            notes[h] = "the other poses cannot identify the compliances (leverage 1)"
    z = np.zeros((P, p))
    z[ok] = np.linalg.solve(np.eye(p) - S[ok], (c - t[ok])[..., None])[..., 0]
    x_p = solve_triangular(R, z.T).T / scale  # (P, p)
    x = np.zeros((P, 6))
    x[:, cols] = x_p
    xt = x[fold]  # the held-out estimate used for each test
    pred = np.einsum("mrj,mj->mr", design_block(J, tests.w), xt)
    err = np.where(tests.measured, tests.d - pred, np.nan)
    C = np.einsum("mij,mj,mkj->mik", J, xt, J)
    sig = np.sqrt(np.diagonal(residual_covariance(noise, C, tests.w), axis1=-2, axis2=-1))
    norm = err / sig
    rows = []
    for h, label in enumerate(labels):
        held = fold == h
        row = {"held_out_pose": label, "n_tests": int(held.sum())}
        if not ok[h]:
            rows.append({**row, "rms_translation_m": np.nan, "rms_rotation_rad": np.nan,
                         "rms_normalized": np.nan, "note": notes[h]})
            continue
        meas = tests.measured[held]
        e = err[held]
        rows.append({
            **row,
            "rms_translation_m": _rms(e[:, :3][meas[:, :3]]),
            "rms_rotation_rad": _rms(e[:, 3:][meas[:, 3:]]),
            "rms_normalized": _rms(norm[held][meas]),
            "note": "",
        })
    return pd.DataFrame(rows)
