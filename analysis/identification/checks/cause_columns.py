"""Regressor columns of the alternatives to the joint-spring model (pure, batched).

Each function returns the columns B (m, 6, r) of one alternative model: the
extra displacement screw of P [m; rad] per unit of each extra parameter, so
that the alternative predicts ``f(x) + B beta``. The joint-spring model is
nested in each (beta = 0); :mod:`analysis.identification.checks.causes` tests
them on the residuals of the fit.

* link compliance (virtual-joint model): the extra displacement
  ``J_l C_l J_l^T w`` of a compliant link l, C_l a symmetric 6 x 6 compliance at
  its distal end (21 parameters per link), J_l (6 x 6) the Jacobian of P with
  respect to the six small motions of that end (translations along, rotations
  about, the axes of a frame fixed in link l);
* lost motion: joint j travels through its dead band 2 b_j when the torque its
  gear transmits changes sign between the reference and the loaded reading; the
  column is ``J[:, j] (s_load - s_ref) / 2`` (s = sign of the gear torque) and
  the parameter the dead band 2 b_j (rad); with the torques known to the wrench noise
  only, the expected step and its variance (:func:`lost_motion_moments`);
* compensator: a spring between links 1 and 2 whose stiffness and torque depend on
  q2: a compliance of joint 2 linear and quadratic in q2 (columns ``A[:, 2] t`` and
  ``A[:, 2] t^2``, t = q2 - mean, A the model's compliance columns) and a static
  deflection of joint 2 that follows q2 (``G t^k``, k = 0..2, G the derivative of the
  model displacement with respect to q2);
* units: a relative scale of the measured rotations to the translations and of
  the moments to the forces (a moment in N mm for N m, a rotation in urad for
  mrad): columns ``[0; pred_rot]`` and ``J X J^T [0; m]``.
"""

from __future__ import annotations

import numpy as np

from analysis.model.gravity import gear_flanks
from analysis.model.kinematics import chain_state, cross

#: compliant links tested, 0-based: link l is the body between joint l and joint l + 1
#: (links 2 and 3 of the arm: the upper arm and the forearm)
LINKS = (1, 2)


def _link_frame(origins: np.ndarray, axes: np.ndarray, link: int) -> tuple[np.ndarray, np.ndarray]:
    """(origin (m, 3), rotation (m, 3, 3)) of a frame fixed in link ``link``, at its distal
    end: origin at joint link+1's origin, z along joint link+1's axis, x along the
    body-fixed vector (joint link+1's origin minus joint link's, or joint link's axis) with
    the larger part normal to z (the same one at every pose: both are fixed in the link)."""
    o = origins[:, link + 1]
    z = axes[:, link + 1] / np.linalg.norm(axes[:, link + 1], axis=-1, keepdims=True)
    cands = [origins[:, link + 1] - origins[:, link], axes[:, link]]
    perp = [c - np.sum(c * z, axis=-1, keepdims=True) * z for c in cands]
    size = [float(np.linalg.norm(p[0])) for p in perp]
    x = perp[int(np.argmax(size))]
    x = x / np.linalg.norm(x, axis=-1, keepdims=True)
    y = cross(z, x)
    return o, np.stack([x, y, z], axis=-1)


def link_jacobian(origins: np.ndarray, axes: np.ndarray, tip: np.ndarray,
                  link: int) -> np.ndarray:
    """J_l (m, 6, 6): the twist [dp (m); dr (rad)] of P per small motion of link ``link``'s
    distal end, columns translations along and rotations about its frame's axes
    (:func:`_link_frame`), base-frame rows."""
    o, R = _link_frame(origins, axes, link)
    p = tip[:, :3, 3]
    J = np.zeros((o.shape[0], 6, 6))
    J[:, :3, :3] = R
    for k in range(3):
        u = R[:, :, k]
        J[:, :3, 3 + k] = cross(u, p - o)
        J[:, 3:, 3 + k] = u
    return J


def link_compliance_columns(robot, q: np.ndarray, w: np.ndarray,
                            links=LINKS) -> np.ndarray:
    """B (m, 6, 21 len(links)): d(J_l C_l J_l^T w)/dc for the 21 entries c of each link's
    symmetric compliance C_l (upper triangle, row-major; (m/N, m/(N m), rad/(N m)))."""
    st = chain_state(robot, np.asarray(q, dtype=float))
    w = np.asarray(w, dtype=float)
    return np.concatenate([symmetric_columns(link_jacobian(st.origins, st.axes, st.tip, link),
                                             w) for link in links], axis=-1)


def symmetric_columns(J: np.ndarray, w: np.ndarray) -> np.ndarray:
    """B (m, 6, 21): d(J C J^T w)/dc for the 21 entries c of a symmetric 6 x 6 C (upper
    triangle, row-major), J (m, 6, 6) the Jacobian of P for the six virtual motions of a
    frame, w (m, 6) the wrench at P: the regressor of one compliant link in that frame."""
    u = np.einsum("mra,mr->ma", J, w)  # the wrench at the link's end, its frame's axes
    cols = []
    for a in range(6):
        for b in range(a, 6):
            c = J[:, :, a] * u[:, b, None]
            if a != b:
                c = c + J[:, :, b] * u[:, a, None]
            cols.append(c)
    return np.stack(cols, axis=-1)


def lost_motion_columns(J: np.ndarray, tau_ref: np.ndarray,
                        tau_load: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(B (m, 6, 6), flips (m, 6) bool): per joint j the column ``J[:, j] (s_load - s_ref)/2``
    (zero where joint j's gear keeps its flank), s the flank (:func:`gear_flanks`) at the
    reference and at the loaded reading (N m, (m, 6) each); the parameter is the dead band
    2 b_j (rad), positive when the joint moves towards its new torque."""
    s_ref, s_load = gear_flanks(tau_ref), gear_flanks(tau_load)
    step = (s_load - s_ref) / 2.0
    return J * step[:, None, :], step != 0


def lost_motion_moments(J: np.ndarray, tau_ref: np.ndarray, tau_load: np.ndarray,
                        sigma_ref: np.ndarray, sigma_load: np.ndarray
                        ) -> tuple[np.ndarray, np.ndarray]:
    """(B (m, 6, 6), var (m, 6)): :func:`lost_motion_columns` when each torque (N m,
    (m, 6)) is known to a Gaussian standard deviation (``sigma_ref``, ``sigma_load``, N m,
    (m, 6)): B per joint j ``J[:, j] E[(s_load - s_ref)/2]`` and var the variance of that
    step, ``(Var s_ref + Var s_load) / 4`` (the readings' noises independent), s's moments
    from :func:`analysis.model.gravity.flank_moments`. The displacement of a band 2b_j is
    then 2b_j B[..., j] on average with covariance (2b_j)^2 var J_j J_j^T; where both
    flanks are decided B is :func:`lost_motion_columns`' and var 0, bit for bit."""
    from analysis.model.gravity import flank_moments

    m_ref, v_ref = flank_moments(tau_ref, sigma_ref)
    m_load, v_load = flank_moments(tau_load, sigma_load)
    return J * ((m_load - m_ref) / 2.0)[:, None, :], (v_ref + v_load) / 4.0


def compensator_columns(A: np.ndarray, G: np.ndarray, q: np.ndarray, joint: int) -> np.ndarray:
    """B (m, 6, 5): a spring on ``joint`` whose stiffness and torque depend on q_j. The model's
    compliance column of that joint (A (m, 6)) times (q_j - mean) and its square (a
    compliance linear and quadratic in q_j), and the displacement's derivative with respect
    to that joint's angle (G (m, 6), per rad) times 1, (q_j - mean) and its square (the
    spring's torque deflects the gear at both readings: the arm stands at q_j plus a
    static deflection that follows q_j)."""
    t = q[:, joint] - np.mean(q[:, joint])
    return np.stack([A * t[:, None], A * (t**2)[:, None], G, G * t[:, None],
                     G * (t**2)[:, None]], axis=-1)


def units_columns(J: np.ndarray, x: np.ndarray, w: np.ndarray,
                  predicted: np.ndarray) -> np.ndarray:
    """B (m, 6, 2): the prediction's rotation rows alone (a scale of the measured rotations)
    and the linear model's response to the moments alone (a scale of the moments)."""
    rot = np.zeros_like(predicted)
    rot[:, 3:] = predicted[:, 3:]
    wm = np.zeros_like(w)
    wm[:, 3:] = w[:, 3:]
    mom = np.einsum("mrj,j,msj,ms->mr", J, x, J, wm)
    return np.stack([rot, mom], axis=-1)
