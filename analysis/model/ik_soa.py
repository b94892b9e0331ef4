"""Closed-form inverse kinematics of a spherical wrist, structure of arrays.

The batched solver behind ``IKSolver(kind="spherical_wrist")``, written for speed:
every vector is a tuple of three arrays (x, y, z components, any broadcastable
shape) and every rotation by a joint is a planar rotation of two components, so
a solve is a few hundred component-wise operations per target, with no
(..., 3, 3) matrix products.

The chain is first *normalised*: each joint frame is turned by a constant
rotation Q_i so that its axis is the frame's z axis, i.e.
``G_i = G_(i-1) L_i Rz(q_i)`` with ``L_i = Q_(i-1)^T P_i Q_i`` (P_i the joint
placement of :class:`analysis.model.robot_model.Chain`). The frames G_i are the
joint frames of :mod:`analysis.model.kinematics` turned by Q_i (same origins,
same joint angles). The solution keeps the cosines and sines of the joint
angles, so the caller gets joint axes and origins in the base frame (hence the
Jacobian of P) from the intermediate frames of the IK, without running the
general chain kinematics again.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

Vec = tuple  # (x, y, z): arrays or floats, broadcastable

#: Entries of a constant rotation below this are taken as 0 (cos(pi/2) = 6e-17 in
#: robot files); the change of the model is below the rounding of the arithmetic.
_SNAP = 1e-15


def _snap(m: np.ndarray) -> np.ndarray:
    m = np.array(m, dtype=float)
    m[np.abs(m) < _SNAP] = 0.0
    return m


def cmv(m: np.ndarray, v: Vec) -> Vec:
    """Constant matrix (3, 3) times an SoA vector; zero and unit entries cost nothing."""
    return tuple(_row(m[i], v) for i in range(3))


def _row(r: np.ndarray, v: Vec):
    """Constant row (3,) dot an SoA vector, skipping zero entries."""
    acc = None
    for j in range(3):
        a = r[j]
        if a == 0.0:
            continue
        term = v[j] if a == 1.0 else (-v[j] if a == -1.0 else a * v[j])
        acc = term if acc is None else acc + term
    return 0.0 if acc is None else acc


def cdot(a: np.ndarray, v: Vec):
    """Constant vector (3,) dot an SoA vector."""
    return _row(a, v)


def rz(c, s, v: Vec) -> Vec:
    """Rz(q) v for cos q = c, sin q = s."""
    return (c * v[0] - s * v[1], s * v[0] + c * v[1], v[2])


def rzt(c, s, v: Vec) -> Vec:
    """Rz(q)^T v."""
    return (c * v[0] + s * v[1], c * v[1] - s * v[0], v[2])


def dot(a: Vec, b: Vec):
    return a[0] * b[0] + a[1] * b[1] + a[2] * b[2]


def cross(a: Vec, b: Vec) -> Vec:
    return (a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0])


def _frame_for_axis(a: np.ndarray) -> np.ndarray:
    """A rotation Q with Q e_z = a (the identity when a is already e_z)."""
    if np.allclose(a, [0.0, 0.0, 1.0], atol=0.0, rtol=0.0):
        return np.eye(3)
    e = np.eye(3)[int(np.argmin(np.abs(a)))]
    x = np.cross(e, a)
    x /= np.linalg.norm(x)
    return np.column_stack([x, np.cross(a, x), a])


def _cos_sin_branch(a, b, rhs, sign: int, slack: float):
    """cos t, sin t of ``t = atan2(b, a) + sign acos(rhs / rho)`` (a cos t + b sin t = rhs),
    without the angle; ok is False where |rhs| > rho beyond rounding or rho <= slack."""
    rho2 = a * a + b * b
    root = np.sqrt(np.maximum(rho2 - rhs * rhs, 0.0))
    ok = (rho2 > slack * slack) & (rhs * rhs <= rho2 * (1.0 + 1e-12) ** 2)
    inv = 1.0 / np.where(rho2 > 0.0, rho2, 1.0)
    if sign < 0:
        root = -root
    return (a * rhs - b * root) * inv, (b * rhs + a * root) * inv, ok


def _unit(c, s):
    """(c, s) / |(c, s)|: cosine and sine of atan2(s, c); (1, 0) where both vanish."""
    n = np.sqrt(c * c + s * s)
    zero = n == 0.0
    if np.any(zero):
        n = np.where(zero, 1.0, n)
        return np.where(zero, 1.0, c / n), np.where(zero, 0.0, s / n)
    inv = 1.0 / n
    return c * inv, s * inv


def rzc(c, s, w: np.ndarray) -> Vec:
    """Rz(q) w for a constant vector w (3,); zero entries cost nothing."""
    return (_row(np.array([w[0], -w[1], 0.0]), (c, s, 0.0)),
            _row(np.array([w[1], w[0], 0.0]), (c, s, 0.0)), float(w[2]))


def apply(cols: list, v: Vec) -> Vec:
    """Matrix given by its columns (SoA vectors) times v; float zero entries of v skipped."""
    out = None
    for col, vi in zip(cols, v, strict=True):
        if isinstance(vi, float) and vi == 0.0:
            continue
        term = tuple(vi * col[i] for i in range(3))
        out = term if out is None else tuple(out[i] + term[i] for i in range(3))
    return (0.0, 0.0, 0.0) if out is None else out


@dataclass(frozen=True)
class NormalChain:
    """A 6R chain with axes 2, 3 parallel and a spherical wrist, normalised (module doc).

    rot (6, 3, 3), pos (6, 3): the constant parts L_i (m); wrist (3,): the wrist
    centre in G_3 (m); tool (3,): the vector from P to the wrist centre in the
    frame of P (m); k6z, k6x (3,): G_6's z and x axes in the frame of P;
    lateral: the wrist centre's coordinate along axis 2 in G_1 (m); s3: +1 or
    -1, axis 3 along or against axis 2.
    """

    rot: np.ndarray
    pos: np.ndarray
    wrist: np.ndarray
    tool: np.ndarray
    k6z: np.ndarray
    k6x: np.ndarray
    lateral: float
    s3: int

    @classmethod
    def build(cls, placements: np.ndarray, axes: np.ndarray, tip: np.ndarray,
              wrist_in_6: np.ndarray, wrist_in_3: np.ndarray) -> NormalChain:
        """From the chain (placements (6, 4, 4), local axes (6, 3), tip (4, 4)) and the
        wrist centre in the (unnormalised) joint frames 6 and 3 (m)."""
        Q = [np.eye(3)] + [_frame_for_axis(a) for a in axes]
        rot = np.array([_snap(Q[i].T @ placements[i, :3, :3] @ Q[i + 1]) for i in range(6)])
        pos = np.array([Q[i].T @ placements[i, :3, 3] for i in range(6)])
        tip_rot = Q[6].T @ tip[:3, :3]
        tip_pos = Q[6].T @ tip[:3, 3]
        w6 = Q[6].T @ wrist_in_6
        wrist = Q[3].T @ wrist_in_3
        s3 = int(round(rot[2][2, 2]))
        u = rot[1][:, 2]
        lateral = float(u @ pos[1] + pos[2][2] + s3 * wrist[2])
        return cls(rot, pos, wrist, tip_rot.T @ (w6 - tip_pos), tip_rot[2].copy(),
                   tip_rot[0].copy(), lateral, s3)


@dataclass
class WristSolution:
    """Joint angles q[i] (rad, [-pi, pi]) with the cos c[i] and sin s[i] of q1..q5
    (arrays), ok (bool array; arm_ok on the arm's shape and wrist_ok), the wrist
    centre (base frame, m), frame4: the columns (base frame) of G_3 L_4, whose z
    axis is joint axis 4, and the chain they belong to."""

    chain: NormalChain
    q: list
    c: list
    s: list
    ok: np.ndarray
    centre: Vec
    frame4: list | None = None
    arm_ok: np.ndarray | None = None
    wrist_ok: np.ndarray | None = None

    def to_base(self, v: Vec, frame: int) -> Vec:
        """Components in the base frame of a vector given in G_frame (frame = 0..5)."""
        for i in range(frame - 1, -1, -1):
            v = cmv(self.chain.rot[i], rz(self.c[i], self.s[i], v))
        return v

    def axes_and_origins(self, upto: int = 6) -> tuple[list, list]:
        """Joint axes z_i and origins o_i (base frame, m) of joints 1..upto."""
        L = self.chain
        z, o = [], []
        origin: Vec = (0.0, 0.0, 0.0)
        for i in range(upto):
            step = self.to_base(tuple(L.pos[i]), i)
            origin = tuple(origin[j] + step[j] for j in range(3))
            o.append(origin)
            z.append(self.to_base(tuple(L.rot[i][:, 2]), i))
        return z, o


def solve_wrist(chain: NormalChain, centre: Vec, z6: Vec, x6: Vec,
                flags: tuple[int, int, int]) -> WristSolution:
    """Closed-form IK from the wrist centre and the z and x axes of G_6 (base frame).

    shoulder, elbow, wrist = flags pick the sign in front of the arc-cosine of
    the q1, q3 and wrist equations. Arrays may have different broadcastable
    shapes (the arm part is computed on the shape of ``centre``).
    """
    L = chain
    shoulder, elbow, wrist = flags
    # q1: axis 2 (u in G_1) keeps the wrist centre at a fixed coordinate ``lateral``
    e = cmv(L.rot[0].T, tuple(centre[j] - L.pos[0][j] for j in range(3)))
    u = L.rot[1][:, 2]
    a1 = u[0] * e[0] + u[1] * e[1]
    b1 = u[0] * e[1] - u[1] * e[0]
    c1, s1, ok1 = _cos_sin_branch(a1, b1, L.lateral - u[2] * e[2], shoulder, 1e-9)
    # q2, q3: planar two-link problem in the xy plane of G_2
    E = rzt(c1, s1, e)
    f = cmv(L.rot[1].T, tuple(E[j] - L.pos[1][j] for j in range(3)))
    t = L.pos[2][:2]
    R2 = L.rot[2][:2, :2]
    w = L.wrist[:2]
    T = R2.T @ t
    k = 0.5 * (f[0] * f[0] + f[1] * f[1] - t @ t - w @ w)
    A, B = float(T @ w), float(T[1] * w[0] - T[0] * w[1])
    c3, s3, ok3 = _cos_sin_branch(np.full_like(k, A), np.full_like(k, B), k,
                                  elbow * L.s3, 1e-12)
    wr = (c3 * w[0] - s3 * w[1], s3 * w[0] + c3 * w[1])
    ux = t[0] + R2[0, 0] * wr[0] + R2[0, 1] * wr[1]
    uy = t[1] + R2[1, 0] * wr[0] + R2[1, 1] * wr[1]
    c2, s2 = _unit(ux * f[0] + uy * f[1], ux * f[1] - uy * f[0])
    cs_c, cs_s = [c1, c2, c3], [s1, s2, s3]
    sol = WristSolution(chain, [], cs_c, cs_s, ok1 & ok3, centre)
    # wrist, in the frame F = G_3 L_4 whose z axis is axis 4 (columns in the base
    # frame, arm shape): Rz(q4) R(w2, q5) x = y (Paden-Kahan 2), then q6 (sub-problem 1)
    F = [sol.to_base(tuple(L.rot[3][:, i]), 3) for i in range(3)]
    sol.frame4 = F
    y = tuple(dot(F[i], z6) for i in range(3))
    w2 = L.rot[4][:, 2]
    x = L.rot[4] @ L.rot[5][:, 2]
    c12 = float(w2[2])
    den = c12 * c12 - 1.0
    wx = float(w2 @ x)
    alpha = (c12 * wx - y[2]) / den
    beta = (c12 * y[2] - wx) / den
    n12 = np.array([-w2[1], w2[0], 0.0])  # e_z x w2
    g2 = (x @ x - alpha * alpha - beta * beta - 2.0 * alpha * beta * c12) / (n12 @ n12)
    gamma = np.sqrt(np.maximum(g2, 0.0))
    if wrist < 0:
        gamma = -gamma
    z = (beta * w2[0] + gamma * n12[0], beta * w2[1] + gamma * n12[1],
         alpha + beta * w2[2])
    # q5 about w2 takes x to z: atan2((x_p x z) . w2, x_p . z), x_p = x without its w2 part
    xp = x - wx * w2
    c5, s5 = _unit(cdot(xp, z), cdot(np.cross(w2, xp), z))
    # q4 about e_z takes z to y
    c4, s4 = _unit(z[0] * y[0] + z[1] * y[1], z[0] * y[1] - z[1] * y[0])
    cs_c += [c4, c5]
    cs_s += [s4, s5]
    # q6: (F Rz(q4) L_5 Rz(q5) L_6)^T x6 = Rz(q6) e_x
    v = tuple(dot(F[i], x6) for i in range(3))
    v = cmv(L.rot[5].T, rzt(c5, s5, cmv(L.rot[4].T, rzt(c4, s4, v))))
    sol.q = [np.arctan2(cs_s[i], cs_c[i]) for i in range(5)] + [np.arctan2(v[1], v[0])]
    sol.arm_ok = sol.ok
    sol.wrist_ok = g2 > -1e-9
    sol.ok = sol.arm_ok & sol.wrist_ok
    return sol
