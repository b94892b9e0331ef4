"""Forward kinematics and the kinematic Jacobian of the tool point P.

Two implementations of the same quantities:

* batched numpy functions over the chain extracted from the Pinocchio model
  (:class:`analysis.model.robot_model.Chain`): a whole grid of poses at once;
* per-pose Pinocchio calls (``pin_*``), the reference the batched code is
  tested against.

Conventions: J is 6 x n, rows ``[linear; angular]``, maps joint rates (rad/s)
to the twist ``[dp/dt (m/s); omega (rad/s)]`` of P, base-frame axes
(Pinocchio's ``LOCAL_WORLD_ALIGNED`` at P).
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
import pinocchio as pin

from analysis.model.robot_model import Chain, RobotModel


@dataclass(frozen=True)
class ChainState:
    """Kinematic state of a batch of poses (base frame, SI units).

    ``origins`` (..., n, 3) joint origins (m); ``axes`` (..., n, 3) joint axes;
    ``tip`` (..., 4, 4) pose of P.
    """

    origins: np.ndarray
    axes: np.ndarray
    tip: np.ndarray


def cross(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Cross product over the last axis (faster than np.cross on large batches)."""
    a0, a1, a2 = a[..., 0], a[..., 1], a[..., 2]
    b0, b1, b2 = b[..., 0], b[..., 1], b[..., 2]
    return np.stack([a1 * b2 - a2 * b1, a2 * b0 - a0 * b2, a0 * b1 - a1 * b0], axis=-1)


#: entries of a constant rotation below this, and of a constant translation below this
#: many metres, are taken as 0 (cos(pi/2) = 6e-17 in robot files): the change of the
#: model is below the rounding of the arithmetic, a signed permutation then composes with
#: a frame by reordering its columns, and a zero term costs no operation
_SNAP = 1e-15


@dataclass(frozen=True)
class NormalChain:
    """The chain rewritten with every joint axis along z (entry-major kinematics); made
    once per :class:`~analysis.model.robot_model.Chain`, as its ``normal``.

    Joint i's frame is turned by a constant rotation Q_i with Q_i e_z = its axis, so
    ``G_i = G_(i-1) L_i Rz(q_i)`` with ``L_i = Q_(i-1)^T P_i Q_i`` (P_i the placement);
    G_i has the origin of joint i's frame and the joint angles are unchanged.
    rot (n, 3, 3), pos (n, 3): the L_i (m); tip_rot (3, 3), tip_pos (3,): P in G_n (m).
    """

    rot: np.ndarray
    pos: np.ndarray
    tip_rot: np.ndarray
    tip_pos: np.ndarray


def _axis_frame(a: np.ndarray) -> np.ndarray:
    """A rotation Q with Q e_z = a (the identity when a is e_z)."""
    if np.array_equal(a, [0.0, 0.0, 1.0]):
        return np.eye(3)
    e = np.eye(3)[int(np.argmin(np.abs(a)))]
    u = np.cross(e, a)
    u /= np.linalg.norm(u)
    return np.column_stack([u, np.cross(a, u), a])


def _snap(m: np.ndarray) -> np.ndarray:
    return np.where(np.abs(m) < _SNAP, 0.0, m)


def normal_chain(chain: Chain) -> NormalChain:
    """``chain`` with every joint axis along z (:class:`NormalChain`); use
    ``chain.normal``, which makes it once per chain."""
    Q = [np.eye(3)] + [_axis_frame(np.asarray(a, dtype=float)) for a in chain.axes]
    P = chain.placements
    return NormalChain(
        np.array([_snap(Q[i].T @ P[i, :3, :3] @ Q[i + 1]) for i in range(chain.n)]),
        np.array([_snap(Q[i].T @ P[i, :3, 3]) for i in range(chain.n)]),
        _snap(Q[-1].T @ chain.tip[:3, :3]), _snap(Q[-1].T @ chain.tip[:3, 3]))


def _combine(cols: list, coef: np.ndarray):
    """sum_k coef[k] cols[k] for constant coefficients: zero terms skipped, +-1 not multiplied.

    0.0 when every coefficient is zero.
    """
    acc = None
    for a, col in zip(coef, cols, strict=True):
        if a == 0.0:
            continue
        term = col if a == 1.0 else (-col if a == -1.0 else a * col)
        acc = term if acc is None else acc + term
    return 0.0 if acc is None else acc


@dataclass(frozen=True)
class ChainStateEM:
    """:class:`ChainState` of N poses, entry-major (the pose index last and contiguous).

    ``origins`` (3, n, N) joint origins (m); ``axes`` (3, n, N) joint axes;
    ``rot`` (3, 3, N) orientation and ``pos`` (3, N) position (m) of P; ``frames``
    {i: (3, 3, N)} the orientation of joint i's frame (0-based) before its rotation, for
    the joints asked for (``keep`` of :func:`chain_state_em`; the distal frames of the
    compliant links).
    """

    origins: np.ndarray
    axes: np.ndarray
    rot: np.ndarray
    pos: np.ndarray
    frames: dict = field(default_factory=dict)

    def tip(self) -> np.ndarray:
        """Pose of P (N, 4, 4)."""
        N = self.pos.shape[-1]
        tip = np.zeros((N, 4, 4))
        tip[:, :3, :3] = np.moveaxis(self.rot, -1, 0)
        tip[:, :3, 3] = self.pos.T
        tip[:, 3, 3] = 1.0
        return tip

    def batch_first(self, batch: tuple) -> ChainState:
        """The same state as a :class:`ChainState` over the leading axes ``batch``."""
        n = self.axes.shape[1]
        return ChainState(
            np.ascontiguousarray(self.origins.T).reshape(*batch, n, 3),
            np.ascontiguousarray(self.axes.T).reshape(*batch, n, 3),
            self.tip().reshape(*batch, 4, 4))


#: |dq| (rad) up to which :func:`joint_cos_sin` uses the series (truncation < 1e-18 relative)
SERIES_ANGLE = 0.1


def joint_cos_sin(q: np.ndarray, dq: np.ndarray | None = None,
                  base: tuple[np.ndarray, np.ndarray] | None = None
                  ) -> tuple[np.ndarray, np.ndarray]:
    """cos and sin of the joint angles q + dq (rad), any shape.

    ``base``: (cos q, sin q), already computed. With it and every |dq| <=
    :data:`SERIES_ANGLE`, the angle-sum formulas with Taylor series of cos dq - 1 and
    sin dq (a few multiply-adds instead of two transcendental calls, which cost most
    of a forward kinematics pass) give cos(q + dq) to a few ulps: the deflected angles
    of a Newton solve cost no new cos/sin.
    """
    if dq is None:
        return (np.cos(q), np.sin(q)) if base is None else base
    if base is None or not np.all(np.abs(dq) <= SERIES_ANGLE):
        a = q + dq
        return np.cos(a), np.sin(a)
    c0, s0 = base
    d2 = dq * dq
    # sin d = d (1 - d^2/6 + ... + d^8/9!), cos d - 1 = d^2 (-1/2 + ... + d^8/10!)
    sd = dq + dq * d2 * (-1 / 6 + d2 * (1 / 120 + d2 * (-1 / 5040 + d2 * (1 / 362880))))
    cm = d2 * (-1 / 2 + d2 * (1 / 24 + d2 * (-1 / 720 + d2 * (1 / 40320
                                                             - d2 / 3628800))))
    return c0 + (c0 * cm - s0 * sd), s0 + (s0 * cm + c0 * sd)


def chain_state_em(robot: RobotModel, q: np.ndarray,
                   cos_sin: tuple[np.ndarray, np.ndarray] | None = None,
                   keep: tuple[int, ...] = ()) -> ChainStateEM:
    """Forward kinematics of N poses, entry-major: q (n, N) joint angles (rad).

    ``cos_sin``: (cos q, sin q) (n, N) when the caller has them (:func:`joint_cos_sin`);
    then q is not read, and cos q and sin q may also be two sequences of n entries, each
    a float (a joint at the same angle in every pose) or an (N,) array, with q any
    (n, N) array (only its shape is read). ``keep``: joints (0-based) whose full frame
    orientation before their rotation is kept (:attr:`ChainStateEM.frames`). The one
    forward-kinematics kernel: frames are kept as three
    column vectors (3, N) and each joint turns two of them (planar rotation), so a
    pose costs a few dozen vectorised operations over the whole batch and no
    (N, 3, 3) matrix products; frames stay (3, 1) columns up to the first joint whose
    angle varies (then constant joints cost no operation over the batch).
    """
    nc = robot.chain.normal
    if cos_sin is None:
        cos, sin = joint_cos_sin(np.asarray(q, dtype=float))
        n, N = cos.shape
    else:
        cos, sin = cos_sin
        n = len(cos)
        N = cos.shape[1] if isinstance(cos, np.ndarray) else np.shape(q)[-1]
    origins = np.empty((3, n, N))
    axes = np.empty((3, n, N))
    frames: dict[int, np.ndarray] = {}
    # columns of the base frame G_0 = I, broadcast against the (3, N) columns that follow
    G = list(np.eye(3)[:, :, None])
    pos = np.zeros((3, 1))
    for i in range(n):
        pos = pos + _combine(G, nc.pos[i])
        A = [_combine(G, nc.rot[i][:, j]) for j in range(3)]  # G_(i-1) L_i
        origins[:, i] = pos
        axes[:, i] = A[2]
        if i in keep:
            frames[i] = np.stack([np.broadcast_to(a, (3, N)) for a in A], axis=1)
        c, s = cos[i], sin[i]
        G = [c * A[0] + s * A[1], c * A[1] - s * A[0], A[2]]
    rot = np.empty((3, 3, N))
    for j in range(3):
        rot[:, j] = _combine(G, nc.tip_rot[:, j])
    tip_pos = np.empty((3, N))
    tip_pos[...] = pos + _combine(G, nc.tip_pos)  # (3, 1) only for a chain of no joint
    return ChainStateEM(origins, axes, rot, tip_pos, frames)


def jacobian_em(state: ChainStateEM) -> np.ndarray:
    """J (6, n, N) entry-major from a :class:`ChainStateEM`: column i = [w_i x (p - o_i); w_i]."""
    z = state.axes
    d = state.pos[:, None, :] - state.origins
    E = np.empty((6,) + z.shape[1:])
    E[0] = z[1] * d[2] - z[2] * d[1]
    E[1] = z[2] * d[0] - z[0] * d[2]
    E[2] = z[0] * d[1] - z[1] * d[0]
    E[3:] = z
    return E


def chain_state(robot: RobotModel, q: np.ndarray) -> ChainState:
    """Joint origins and axes and the tool pose, batched over the leading axes of q."""
    q = np.asarray(q, dtype=float)
    n = robot.chain.n
    return chain_state_em(robot, q.reshape(-1, n).T).batch_first(q.shape[:-1])


def tool_pose(robot: RobotModel, q: np.ndarray) -> np.ndarray:
    """Homogeneous transform (..., 4, 4) of P in the base frame (m), batched."""
    return chain_state(robot, q).tip


def jacobian_from_state(state: ChainState) -> np.ndarray:
    """J (..., 6, n) from a :class:`ChainState`: column i = [w_i x (p - o_i); w_i]."""
    p = state.tip[..., None, :3, 3]
    lin = cross(state.axes, p - state.origins)
    return np.concatenate([np.swapaxes(lin, -1, -2), np.swapaxes(state.axes, -1, -2)], axis=-2)


def jacobian(robot: RobotModel, q: np.ndarray) -> np.ndarray:
    """Kinematic Jacobian J (..., 6, n) of P, rows [linear; angular], base axes."""
    q = np.asarray(q, dtype=float)
    n = robot.chain.n
    E = jacobian_em(chain_state_em(robot, q.reshape(-1, n).T))
    return np.ascontiguousarray(np.moveaxis(E, -1, 0)).reshape(*q.shape[:-1], 6, n)


def pin_tool_pose(robot: RobotModel, q: np.ndarray) -> np.ndarray:
    """Pose of P (4, 4) at one configuration, computed by Pinocchio."""
    data = robot.model.createData()
    pin.framesForwardKinematics(robot.model, data, np.asarray(q, dtype=float))
    return data.oMf[robot.tip_frame].homogeneous.copy()


def pin_jacobian(robot: RobotModel, q: np.ndarray) -> np.ndarray:
    """J (6, n) at one configuration, computed by Pinocchio (LOCAL_WORLD_ALIGNED at P)."""
    data = robot.model.createData()
    q = np.asarray(q, dtype=float)
    pin.computeJointJacobians(robot.model, data, q)
    pin.updateFramePlacements(robot.model, data)
    return pin.getFrameJacobian(
        robot.model, data, robot.tip_frame, pin.ReferenceFrame.LOCAL_WORLD_ALIGNED
    ).copy()


#: rotations of more than this angle (rad) go to Pinocchio's SO(3) logarithm, one at a time:
#: near pi the skew part of R no longer determines the axis accurately
LOG_NEAR_PI = 2.5


def rotation_vector(rot: np.ndarray) -> np.ndarray:
    """Rotation vector (..., 3) (rad) of rotation matrices (..., 3, 3).

    Batched SO(3) logarithm: with v the axial vector of (R - R^T)/2 (|v| = sin theta)
    and c = (tr R - 1)/2 = cos theta, theta = atan2(|v|, c) and the vector is
    v theta/|v| (1 when v = 0), accurate to rounding wherever theta is away from pi.
    Angles above :data:`LOG_NEAR_PI` go to Pinocchio's ``log3`` one matrix at a time
    (scipy's Rotation gives the same numbers, but importing scipy.spatial costs about
    0.35 s of CPU, paid by every command that reports a deflection).
    """
    rot = np.asarray(rot, dtype=float)
    v = 0.5 * np.stack([rot[..., 2, 1] - rot[..., 1, 2], rot[..., 0, 2] - rot[..., 2, 0],
                        rot[..., 1, 0] - rot[..., 0, 1]], axis=-1)
    s = np.sqrt(np.sum(v * v, axis=-1))
    c = 0.5 * (rot[..., 0, 0] + rot[..., 1, 1] + rot[..., 2, 2] - 1.0)
    theta = np.arctan2(s, c)
    with np.errstate(divide="ignore", invalid="ignore"):
        ratio = np.where(s > 0, theta / np.where(s > 0, s, 1.0), 1.0)
    vec = v * ratio[..., None]
    far = ~(theta <= LOG_NEAR_PI)  # NaN input too: log3 decides
    if np.any(far):
        flat = rot.reshape(-1, 3, 3)
        out = vec.reshape(-1, 3)
        for i in np.flatnonzero(far.reshape(-1)):
            out[i] = pin.log3(flat[i])
        vec = out.reshape(vec.shape)
    return vec


def pose_difference(t_from: np.ndarray, t_to: np.ndarray) -> np.ndarray:
    """Displacement screw (..., 6) from pose ``t_from`` to ``t_to`` (4x4, base frame).

    ``[p_to - p_from (m); rotvec(R_to R_from^T) (rad)]``: the small rotation
    vector is expressed in the base frame, as the paper's delta_X.
    """
    t_from, t_to = np.broadcast_arrays(np.asarray(t_from, dtype=float),
                                       np.asarray(t_to, dtype=float))
    batch = t_to.shape[:-2]

    def em(t):  # (3, 3, N) rotation and (3, N) position views
        flat = t.reshape(-1, 4, 4)
        return np.moveaxis(flat[:, :3, :3], 0, -1), flat[:, :3, 3].T

    return pose_difference_em(*em(t_from), *em(t_to)).reshape(*batch, 6)


def pose_difference_em(rot_from: np.ndarray, pos_from: np.ndarray, rot_to: np.ndarray,
                       pos_to: np.ndarray) -> np.ndarray:
    """:func:`pose_difference` of N pose pairs given entry-major: rotations (3, 3, N),
    positions (3, N) (m); returns (N, 6)."""
    out = np.empty((pos_to.shape[-1], 6))
    out[:, :3] = (pos_to - pos_from).T
    rel = np.empty((3, 3) + pos_to.shape[1:])  # R_to R_from^T
    tmp = np.empty(pos_to.shape[1:])
    for i in range(3):
        for j in range(3):
            np.multiply(rot_to[i, 0], rot_from[j, 0], out=rel[i, j])
            for k in (1, 2):
                np.multiply(rot_to[i, k], rot_from[j, k], out=tmp)
                rel[i, j] += tmp
    out[:, 3:] = rotation_vector(np.moveaxis(rel, -1, 0))
    return out
