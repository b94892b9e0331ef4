"""Inverse kinematics of the tool point P, batched over many target poses.

Three solvers, chosen from the geometry of the chain (not from the robot's name,
so an identified or user-written model with other lengths is solved the same way):

* ``spherical_wrist``: axes 2 and 3 parallel, axes 4, 5, 6 meeting in one point
  (KR240-2, FANUC S-420F, PUMA 560). Closed form: the wrist centre fixes q1
  (lateral-offset equation), q2, q3 (planar two-link problem), then the wrist
  rotation gives q4, q5 (Paden-Kahan sub-problem 2) and q6 (sub-problem 1).
* ``parallel_axes``: axes 2, 3, 4 parallel and axes 5, 6 meeting in one point
  (the Universal Robots geometry). Closed form: the intersection of axes 5 and 6
  fixes q1, the tool axis fixes q5 and q6, then q2, q3 (planar) and q4.
* ``numerical``: any other 6R chain (URDF or robot file): batched damped least
  squares on the Jacobian of :mod:`analysis.model.kinematics`, from seeds.

Every solution is checked against forward kinematics: a solution whose pose of P
differs from the target by more than 1e-9 m or 1e-9 rad is marked not found.

Configuration flags ``(shoulder, elbow, wrist)``, each +1 or -1, pick one of the
eight closed-form branches: the sign in front of the arc-cosine of the q1
equation (shoulder), of the q3 equation (elbow) and of the wrist sub-problem
(wrist). A branch is continuous in the target pose away from the boundary of the
workspace and from singular poses, so a path solved with fixed flags has no
configuration flip. Angles are in the model convention (rad), wrapped to
(-pi, pi]; :func:`fit_limits` moves them by whole turns into the joint limits.
"""

from __future__ import annotations

import itertools
from dataclasses import dataclass

import numpy as np

from analysis.model.ik_soa import NormalChain, solve_wrist
from analysis.model.kinematics import pose_difference, tool_pose
from analysis.model.robot_model import RobotModel

#: FK round-trip tolerance of an accepted solution (m for position, rad for rotation).
FK_TOL = 1e-9
#: Every configuration (shoulder, elbow, wrist) of a closed-form solver.
ALL_FLAGS: tuple[tuple[int, int, int], ...] = tuple(itertools.product((1, -1), repeat=3))


def _rot(axis: np.ndarray, angle: np.ndarray) -> np.ndarray:
    """Rotation matrices (..., 3, 3) about a fixed unit axis (3,) by angles (...)."""
    k = np.array([[0.0, -axis[2], axis[1]], [axis[2], 0.0, -axis[0]], [-axis[1], axis[0], 0.0]])
    s, c = np.sin(angle)[..., None, None], np.cos(angle)[..., None, None]
    return np.eye(3) + s * k + (1.0 - c) * (k @ k)


def _dot(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    return np.einsum("...i,...i->...", a, b)


def _mv(m: np.ndarray, v: np.ndarray) -> np.ndarray:
    """m (..., 3, 3) @ v (..., 3)."""
    return np.einsum("...ij,...j->...i", m, v)


def _mtv(m: np.ndarray, v: np.ndarray) -> np.ndarray:
    """m^T (..., 3, 3) @ v (..., 3)."""
    return np.einsum("...ji,...j->...i", m, v)


def _subproblem1(axis: np.ndarray, u: np.ndarray, v: np.ndarray) -> np.ndarray:
    """Angle (...) of the rotation about unit ``axis`` taking u's direction to v's
    (components perpendicular to the axis); 0 when either component vanishes."""
    vp = v - _dot(v, axis)[..., None] * axis
    up = u - _dot(u, axis)[..., None] * axis
    return np.arctan2(_dot(np.cross(up, vp), np.broadcast_to(axis, up.shape)), _dot(up, vp))


def _acos_branch(a: np.ndarray, b: np.ndarray, c: np.ndarray, sign: int, slack: float):
    """Solutions of ``a cos t + b sin t = c``: t = atan2(b, a) + sign acos(c / rho).

    Returns (t, ok): ok is False where |c| > rho (out of reach) beyond ``slack``
    (relative), or rho vanishes (singular: the equation does not fix t).
    """
    rho = np.hypot(a, b)
    ratio = c / np.where(rho > 0, rho, 1.0)
    ok = (rho > slack) & (np.abs(ratio) <= 1.0 + 1e-12)
    t = np.arctan2(b, a) + sign * np.arccos(np.clip(ratio, -1.0, 1.0))
    return t, ok


def _wrap(q: np.ndarray) -> np.ndarray:
    """Angles wrapped to (-pi, pi]."""
    return np.pi - np.mod(np.pi - q, 2 * np.pi)


def _closest_point(points: np.ndarray, dirs: np.ndarray) -> tuple[np.ndarray, float]:
    """Least-squares point nearest to lines (p_i, d_i), and its largest distance (m)."""
    A = np.zeros((3, 3))
    rhs = np.zeros(3)
    for p, d in zip(points, dirs, strict=True):
        proj = np.eye(3) - np.outer(d, d)
        A += proj
        rhs += proj @ p
    x = np.linalg.lstsq(A, rhs, rcond=None)[0]
    dist = max(np.linalg.norm((np.eye(3) - np.outer(d, d)) @ (x - p))
               for p, d in zip(points, dirs, strict=True))
    return x, float(dist)


@dataclass(frozen=True)
class _Frames:
    """Frame poses of a chain at q = 0: rot[i], pos[i] of joint i's frame after its
    rotation (i = 0..n-1), world axes and origins."""

    rot: np.ndarray
    pos: np.ndarray
    axis: np.ndarray
    origin: np.ndarray


def _zero_frames(robot: RobotModel) -> _Frames:
    ch = robot.chain
    rot, pos = np.eye(3), np.zeros(3)
    rots, poss, axes, origins = [], [], [], []
    for i in range(ch.n):
        pos = pos + rot @ ch.placements[i, :3, 3]
        rot = rot @ ch.placements[i, :3, :3]
        axes.append(rot @ ch.axes[i])
        origins.append(pos.copy())
        rots.append(rot.copy())
        poss.append(pos.copy())
    return _Frames(np.array(rots), np.array(poss), np.array(axes), np.array(origins))


def _parallel(a: np.ndarray, b: np.ndarray, tol: float = 1e-9) -> int:
    """+1 or -1 when unit vectors a and b are parallel or anti-parallel, else 0."""
    c = float(a @ b)
    if abs(abs(c) - 1.0) > tol:
        return 0
    return 1 if c > 0 else -1


@dataclass(frozen=True)
class IKSolver:
    """Batched inverse kinematics of one robot (see the module docstring).

    Build with :meth:`for_robot`; ``kind`` is ``"spherical_wrist"``,
    ``"parallel_axes"`` or ``"numerical"``.
    """

    robot: RobotModel
    kind: str
    point_local: np.ndarray | None = None  # wrist centre / axes-5-6 point in frame 6 (m)
    lateral: float = 0.0  # (point - o1) . axis2 at q = 0 (m)
    s3: int = 1  # axis 3 (and 4) parallel (+1) or anti-parallel (-1) to axis 2
    s4: int = 1
    planar_w: np.ndarray | None = None  # the planar problem's end point in frame 3 (m)
    point_in_4: np.ndarray | None = None  # parallel_axes: the axes-5-6 point in frame 4 (m)
    axis2_in_4: np.ndarray | None = None  # parallel_axes: axis 2 in frame 4 coordinates
    normal: NormalChain | None = None  # spherical_wrist: the normalised chain (ik_soa)

    @property
    def flags(self) -> tuple[tuple[int, int, int], ...]:
        """The configurations this solver distinguishes (one for the numerical solver)."""
        return ALL_FLAGS if self.kind != "numerical" else ((0, 0, 0),)

    @classmethod
    def for_robot(cls, robot: RobotModel) -> IKSolver:
        """Inspect the chain geometry at q = 0 and pick the closed form that applies."""
        ch = robot.chain
        if ch.n != 6:
            return cls(robot, "numerical")
        f = _zero_frames(robot)
        scale = max(1.0, float(np.abs(ch.placements[:, :3, 3]).sum()))
        s3 = _parallel(f.axis[1], f.axis[2])
        if _parallel(f.axis[0], f.axis[1]) or not s3:
            return cls(robot, "numerical")
        p0 = f.origin[0]
        u2 = f.axis[1]
        wrist, dist = _closest_point(f.origin[3:], f.axis[3:])
        if dist <= 1e-12 * scale and not _parallel(f.axis[3], f.axis[4]) \
                and not _parallel(f.axis[4], f.axis[5]):
            local6 = f.rot[5].T @ (wrist - f.pos[5])
            w3 = f.rot[2].T @ (wrist - f.pos[2])
            normal = NormalChain.build(ch.placements, ch.axes, ch.tip, local6, w3)
            return cls(robot, "spherical_wrist", point_local=local6,
                       lateral=float((wrist - p0) @ u2), s3=s3,
                       planar_w=ch.placements[2, :3, :3] @ w3, normal=normal)
        s4 = _parallel(f.axis[1], f.axis[3])
        x56, dist = _closest_point(f.origin[4:], f.axis[4:])
        if s4 and dist <= 1e-12 * scale and not _parallel(f.axis[4], f.axis[5]) \
                and not _parallel(f.axis[3], f.axis[4]):
            local6 = f.rot[5].T @ (x56 - f.pos[5])
            in4 = f.rot[3].T @ (x56 - f.pos[3])
            return cls(robot, "parallel_axes", point_local=local6,
                       lateral=float((x56 - p0) @ u2), s3=s3, s4=s4,
                       planar_w=ch.placements[2, :3, :3] @ ch.placements[3, :3, 3],
                       point_in_4=in4, axis2_in_4=f.rot[3].T @ u2)
        return cls(robot, "numerical")

    # -- closed-form pieces -------------------------------------------------------------

    def _q1(self, point: np.ndarray, sign: int):
        """q1 from the lateral offset of a point that q2..q6 keep at a fixed distance
        along axis 2: (R(z1, q1) u2_0) . (point - o1) = lateral."""
        ch = self.robot.chain
        R1p = ch.placements[0, :3, :3]
        z1 = R1p @ ch.axes[0]
        u2 = R1p @ ch.placements[1, :3, :3] @ ch.axes[1]
        p = point - ch.placements[0, :3, 3]
        u_par = (u2 @ z1) * z1
        u_perp = u2 - u_par
        a = p @ u_perp
        b = p @ np.cross(z1, u_perp)
        c = self.lateral - (u2 @ z1) * (p @ z1)
        t, ok = _acos_branch(a, b, c, sign, 1e-9)
        return t, ok

    def _q23(self, q1: np.ndarray, point: np.ndarray, sign: int):
        """q2, q3 placing the planar problem's end point at ``point`` (world, m)."""
        ch = self.robot.chain
        F1 = ch.placements[0, :3, :3] @ _rot(ch.axes[0], q1)
        o2 = ch.placements[0, :3, 3] + _mv(F1, np.broadcast_to(ch.placements[1, :3, 3],
                                                               point.shape))
        F2 = F1 @ ch.placements[1, :3, :3]
        a = ch.axes[1]
        v = _mtv(F2, point - o2)
        t = ch.placements[2, :3, 3]
        w = self.planar_w
        t_p = t - (t @ a) * a
        w_p = w - (w @ a) * a
        v_p = v - _dot(v, a)[..., None] * a
        A = t_p @ w_p
        B = t_p @ np.cross(a, w_p)
        C = 0.5 * (_dot(v_p, v_p) - t_p @ t_p - w_p @ w_p)
        theta, ok = _acos_branch(np.full_like(C, A), np.full_like(C, B), C, sign, 1e-12)
        u = t + _mv(_rot(a, theta), np.broadcast_to(w, v.shape))
        q2 = _subproblem1(a, u, v)
        return q2, self.s3 * theta, ok

    def _arm_rotation(self, q1, q2, q3) -> np.ndarray:
        """World rotation of frame 3 (after q3)."""
        ch = self.robot.chain
        R = ch.placements[0, :3, :3] @ _rot(ch.axes[0], q1)
        R = R @ ch.placements[1, :3, :3] @ _rot(ch.axes[1], q2)
        return R @ ch.placements[2, :3, :3] @ _rot(ch.axes[2], q3)

    def _solve_spherical(self, T: np.ndarray, flags: tuple[int, int, int]):
        """The structure-of-arrays solver of :mod:`analysis.model.ik_soa` on poses T."""
        L = self.normal
        R, p = T[..., :3, :3], T[..., :3, 3]

        def turn(v):  # R v for a constant v, as three arrays
            return tuple(R[..., i, :] @ v for i in range(3))

        tool = turn(L.tool)
        centre = tuple(p[..., i] + tool[i] for i in range(3))
        sol = solve_wrist(L, centre, turn(L.k6z), turn(L.k6x), flags)
        q = np.stack(np.broadcast_arrays(*sol.q), axis=-1)
        return _wrap(q), np.broadcast_to(sol.ok, q.shape[:-1])

    def _solve_parallel(self, T: np.ndarray, flags: tuple[int, int, int]):
        ch = self.robot.chain
        shoulder, elbow, wrist = flags
        R6 = T[..., :3, :3] @ ch.tip[:3, :3].T
        o6 = T[..., :3, 3] - _mv(R6, np.broadcast_to(ch.tip[:3, 3], T.shape[:-2] + (3,)))
        X = o6 + _mv(R6, np.broadcast_to(self.point_local, o6.shape))
        q1, ok1 = self._q1(X, shoulder)
        R1p = ch.placements[0, :3, :3]
        u2w = _mv(R1p @ _rot(ch.axes[0], q1),
                  np.broadcast_to(ch.placements[1, :3, :3] @ ch.axes[1], X.shape))
        P5, P6 = ch.placements[4, :3, :3], ch.placements[5, :3, :3]
        a4, a5, a6 = ch.axes[3], ch.axes[4], ch.axes[5]
        b = P5 @ a5
        x = P5 @ P6 @ a6
        u = self.axis2_in_4
        x_p = x - (b @ x) * b
        d = _dot(_mv(R6, np.broadcast_to(a6, X.shape)), u2w)
        q5, ok5 = _acos_branch(np.full_like(d, x_p @ u), np.full_like(d, np.cross(b, x_p) @ u),
                               d - (b @ x) * (b @ u), wrist, 1e-12)
        v = _mtv(np.broadcast_to(P6, R6.shape),
                 _mtv(_rot(a5, q5), np.broadcast_to(P5.T @ u, X.shape)))
        y = _mtv(R6, u2w)
        q6 = _subproblem1(a6, y, v)
        R4 = R6 @ np.swapaxes(P5 @ _rot(a5, q5) @ P6 @ _rot(a6, q6), -1, -2)
        o4 = X - _mv(R4, np.broadcast_to(self.point_in_4, X.shape))
        q2, q3, ok2 = self._q23(q1, o4, elbow)
        R3 = self._arm_rotation(q1, q2, q3)
        M = np.swapaxes(R3 @ ch.placements[3, :3, :3], -1, -2) @ R4
        r = _perpendicular(a4)
        q4 = _subproblem1(a4, np.broadcast_to(r, X.shape), _mv(M, np.broadcast_to(r, X.shape)))
        q = np.stack([q1, q2, q3, q4, q5, q6], axis=-1)
        return _wrap(q), ok1 & ok5 & ok2

    # -- public ---------------------------------------------------------------------------

    def solve(
        self, T: np.ndarray, flags: tuple[int, int, int] = (1, 1, 1),
        seed: np.ndarray | None = None, check: bool = True,
    ) -> tuple[np.ndarray, np.ndarray]:
        """Joint angles (..., 6) (rad, model convention, wrapped) reaching poses T (..., 4, 4).

        Parameters
        ----------
        T : target poses of P in the base frame (m).
        flags : (shoulder, elbow, wrist) branch of a closed-form solver; ignored
            by the numerical solver, which starts from ``seed`` (..., 6) instead
            (default: the middle of the joint ranges).
        check : compare the forward kinematics of the solution with T.

        Returns
        -------
        (q, ok) : ``ok`` (...) is False where no solution of this branch exists or
        the solution misses T by more than :data:`FK_TOL`; q is NaN there.
        """
        T = np.asarray(T, dtype=float)
        with np.errstate(invalid="ignore", divide="ignore"):
            if self.kind == "spherical_wrist":
                q, ok = self._solve_spherical(T, flags)
            elif self.kind == "parallel_axes":
                q, ok = self._solve_parallel(T, flags)
            else:
                q, ok = solve_numerical(self.robot, T, seed)
        ok = ok & np.all(np.isfinite(q), axis=-1)
        if check:
            ok = ok & fk_matches(self.robot, np.where(ok[..., None], q, 0.0), T)
        return np.where(ok[..., None], q, np.nan), ok


def _perpendicular(a: np.ndarray) -> np.ndarray:
    """A unit vector perpendicular to unit vector a."""
    e = np.eye(3)[int(np.argmin(np.abs(a)))]
    r = np.cross(a, e)
    return r / np.linalg.norm(r)


def fk_matches(robot: RobotModel, q: np.ndarray, T: np.ndarray, tol: float = FK_TOL):
    """True (...) where the forward kinematics of q reaches T within ``tol`` (m, rad)."""
    err = pose_error(tool_pose(robot, q), T)
    return (err[0] <= tol) & (err[1] <= tol)


def pose_error(T_a: np.ndarray, T_b: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(position error (m), rotation error (rad)) between poses (..., 4, 4).

    The rotation error is ``|R_a^T R_b - I|_F / sqrt(2)``, equal to 2 sin(angle / 2):
    exact for small angles and cheaper than a rotation vector.
    """
    dp = np.linalg.norm(T_a[..., :3, 3] - T_b[..., :3, 3], axis=-1)
    rel = np.swapaxes(T_a[..., :3, :3], -1, -2) @ T_b[..., :3, :3]
    dr = np.linalg.norm(rel - np.eye(3), axis=(-2, -1)) / np.sqrt(2.0)
    return dp, dr


def solve_numerical(
    robot: RobotModel, T: np.ndarray, seed: np.ndarray | None = None,
    max_iter: int = 100, damping: float = 1e-6,
) -> tuple[np.ndarray, np.ndarray]:
    """Batched damped least squares: q (..., n) with tool_pose(q) = T, from ``seed``.

    Each step solves ``(J^T J + lambda^2 I) dq = J^T e`` with e the displacement
    screw from the current pose to the target (base frame); converges where the
    seed lies in the basin of a solution. Returns (q wrapped, converged).
    """
    from analysis.model.kinematics import jacobian

    T = np.asarray(T, dtype=float)
    shape = T.shape[:-2]
    if seed is None:
        lo, hi = robot.map_limits()
        seed = 0.5 * (lo + hi)
    q = np.broadcast_to(np.asarray(seed, dtype=float), (*shape, robot.n)).copy()
    eye = np.eye(robot.n)
    done = np.zeros(shape, dtype=bool)
    for _ in range(max_iter):
        e = pose_difference(tool_pose(robot, q), T)
        done = np.max(np.abs(e), axis=-1) <= 1e-13
        if np.all(done):
            break
        J = jacobian(robot, q)
        Jt = np.swapaxes(J, -1, -2)
        dq = np.linalg.solve(Jt @ J + damping**2 * eye, (Jt @ e[..., None]))[..., 0]
        # Limit the step so a far seed does not jump across branches.
        big = np.max(np.abs(dq), axis=-1, keepdims=True)
        dq = np.where(big > 0.5, dq * 0.5 / np.maximum(big, 1e-300), dq)
        q = np.where(done[..., None], q, q + dq)
    return _wrap(q), np.ones(shape, dtype=bool)


def fit_limits(robot: RobotModel, q: np.ndarray, margin: float = 0.0):
    """Move each wrapped angle by whole turns into [lower + margin, upper - margin].

    Returns (q_fitted, ok): where several turns fit, the one nearest the middle of
    the range is taken; ``ok`` (...) is False where some joint fits in no turn
    (that joint keeps its input value).
    """
    lo, hi = robot.lower + margin, robot.upper - margin
    mid = 0.5 * (lo + hi)
    best = np.full_like(q, np.nan)
    gap = np.full_like(q, np.inf)
    for k in (-2, -1, 0, 1, 2):
        cand = q + 2 * np.pi * k
        inside = (cand >= lo) & (cand <= hi)
        d = np.abs(cand - mid)
        take = inside & (d < gap)
        best = np.where(take, cand, best)
        gap = np.where(take, d, gap)
    ok = np.all(np.isfinite(best), axis=-1)
    return np.where(np.isfinite(best), best, q), ok
