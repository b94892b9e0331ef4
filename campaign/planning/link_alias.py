"""How much of the links' compliance a design's joint-only fit would read as joint compliance.

A link that bends moves P by ``B c`` (B the link regressor of the model classes,
:func:`analysis.identification.models.fit.link_columns`; c the entries of each link's
6 x 6 compliance at its distal frame). The joint-spring fit of a design (compliance
columns A = J diag(J^T w), weighted by the per-component sigmas) absorbs the part of B c
in A's span: its compliances move by ``dx = (A^T W A)^-1 A^T W B c`` and k by
``dk / k = -dx / x`` (first order). A design whose joint columns lie far from the
links' displacement separates the two effects: the planner prefers, among designs
equally good otherwise, the one with the smallest worst |dk / k|. The compliances c are
the protocol's assumed ones (its ``[fake_lab]`` links; none: not evaluated). Pure.
"""

from __future__ import annotations

import numpy as np

from analysis.identification.estimators.linear_model import design_block
from analysis.identification.models.fit import link_columns
from analysis.kinetostatics.realistic import LinkCompliance
from analysis.model.kinematics import jacobian
from analysis.model.robot_model import RobotModel


def link_entries(links: tuple[LinkCompliance, ...]) -> np.ndarray:
    """c (21 len(links),): each link's compliance, upper triangle row-major (the order of
    the link regressor's columns; m/N, rad/N, rad/(N m))."""
    return np.concatenate([np.asarray(lc.matrix, dtype=float)[np.triu_indices(6)]
                           for lc in links])


def link_alias(robot: RobotModel, q: np.ndarray, w: np.ndarray, k: np.ndarray,
               sigma: np.ndarray, links: tuple[LinkCompliance, ...]) -> np.ndarray:
    """(n,) dk / k of the joint-only fit of the tests (q (m, n) rad, w (m, 6) the wrench
    difference, N and N m) when the links have the compliances ``links``: the weighted
    least squares (sigma (6,) per component, m and rad) of the links' displacement on the
    joint columns at compliances 1/k (N m/rad). NaN for joints the tests do not identify."""
    q = np.atleast_2d(np.asarray(q, dtype=float))
    w = np.broadcast_to(np.asarray(w, dtype=float), (q.shape[0], 6))
    x = 1.0 / np.asarray(k, dtype=float)
    A = design_block(jacobian(robot, q), w) / sigma[None, :, None]
    B, _ = link_columns(robot, q, w, [lc.link for lc in links])
    d = (B @ link_entries(links)) / sigma[None, :]
    WA = A.reshape(-1, A.shape[-1])
    scale = np.linalg.norm(WA, axis=0)
    out = np.full(len(x), np.nan)
    ok = scale > 0
    sol, _, rank, _ = np.linalg.lstsq(WA[:, ok] / scale[ok], d.reshape(-1), rcond=None)
    if rank < int(ok.sum()):
        return out
    out[ok] = -(sol / scale[ok]) / x[ok]
    return out


def protocol_links(protocol, robot: RobotModel) -> tuple[LinkCompliance, ...]:
    """The link compliances the protocol's ``[fake_lab]`` assumes (its simulated lab's
    links, SI), or () when it has none."""
    if protocol.fake_lab is None:
        return ()
    links = protocol.fake_lab.effects().get("links", ())
    if not links:
        return ()
    from analysis.kinetostatics.realistic_lab import realistic_lab

    return realistic_lab(robot, {"links": links}).links


def design_alias(protocol, robot: RobotModel, q: np.ndarray, case: np.ndarray, k: np.ndarray,
                 sigma: np.ndarray, links: tuple[LinkCompliance, ...]) -> np.ndarray | None:
    """:func:`link_alias` of a design's tests (poses q (m, n), load cases ``case`` (m,) of
    ``protocol``: the wrench minus its preload), or None without assumed links."""
    if not links:
        return None
    w = protocol.wrenches()[case] - protocol.reference_wrenches()[case]
    return link_alias(robot, q, w, k, sigma, links)
