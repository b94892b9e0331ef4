"""What a real arm adds to the joint springs: link compliance, lost motion, an axis-2
gravity compensator and gravity; the true displacement of P the simulated lab shows.

CONTRACT (issue 31; the simulated lab and the studies of the refusals call these names):

* :class:`RealisticLab`, a frozen record of the effects: ``links`` (tuple of
  :class:`LinkCompliance`: a 6x6 compliance per flexible link at its distal frame),
  ``lost_motion`` ((n,) rad, the FULL dead band 2b of each gear, or None),
  ``compensator`` (:class:`Compensator` or None), ``gravity`` ("off"; "flanks": gravity,
  from the robot file's mass model, decides the gear flanks only; "on": it also loads the
  joint springs, the arm sags at both readings), ``gravity_vector`` (m/s^2, base frame).
  ``RealisticLab()`` has every effect off; :attr:`RealisticLab.active` says whether any is on.
* :func:`load_torques` (robot, lab, q (N, n), w (N, 6)) -> (N, n) N m: J^T w - g(q) +
  tau_c(q), the torque on each gear at the commanded pose, whose sign decides its flank;
  :func:`flanks` -> (N, n) in {-1, 0, +1}.
* :func:`joint_deflection` (robot, lab, k, q, w) -> (N, n) rad: output angle minus the
  motor-side (encoder) angle, lost motion included;
* :func:`true_tool_poses` (robot, lab, k, q, w) -> (N, 4, 4): the pose of P the tracker sees;
* :func:`displacement` (robot, lab, k, q, w_ref, w) -> (N, 6): the true displacement of P,
  loaded minus reference reading, [dp (m); rotation vector (rad)], base frame (the
  quantity the campaign measures; ``w_ref`` is the reference (preload) wrench, zeros for
  an unloaded reference).
* also :func:`lost_motion_offset`, :func:`link_twist`, :func:`compensator_for` /
  :func:`compensator_torque`, :func:`beam_compliance`, :func:`box_section`,
  :func:`link_beam_compliance`; a lab from a protocol's SI settings:
  :func:`analysis.kinetostatics.realistic_lab.realistic_lab` (robot, effects).

Shapes: q (N, n) joint angles (rad, model convention: the motor-side angles the encoders
read), wrenches (N, 6) or (6,) [f (N); m (N m)] at P, base frame, k (n,) joint stiffness
(N m/rad). All SI.

Model
-----
* Joints: ``theta = q + s + dq`` with the elastic deflection from
  ``K dq = J(theta)^T w - g(theta) + tau_c(theta)`` (g only with gravity "on") (Newton, its Jacobian
  ``K - K_C + dg/dq - dtau_c/dq``) and the lost-motion offset ``s_i = (2b_i / 2)
  sign(tau_i)``: the output rests on the flank of the torque the load puts on the gear,
  ``tau = load_torques(q, w)`` at the commanded pose (the flank is decided there, not at
  the deflected one: it differs only for a torque within a deflection's change of zero).
  A torque of magnitude <= :data:`FLANK_TOLERANCE` leaves the output mid-band (s = 0):
  joint 1 (vertical axis) with no load, gravity off. A joint whose torque changes sign
  between two readings travels the full band 2b, in the direction of the new torque.
  With gravity and the compensator off, ``dq`` is exactly
  :func:`~analysis.kinetostatics.equilibrium.solve_deflection` at ``q + s`` (so every effect
  at zero gives today's numbers bit for bit).
* Links (virtual-joint model, Pashkevich et al. 2009): link l (the body joint l moves)
  bends at its distal frame D_l (joint l+1's frame before its rotation; P's frame for the
  last link) by ``C_l J_l^T w`` under the wrench at P, so P moves by the twist
  ``sum_l J_l C_l J_l^T w``, J_l the 6x6 Jacobian of P for the six virtual motions of D_l
  (translations along its axes, rotations about them). Linear: evaluated at the joints'
  equilibrium and composed with it; the second-order coupling (link deflection times
  joint deflection over the reach, below 1e-7 m at a lab's loads) is neglected. The
  weight of the links beyond l bends them equally at both readings and cancels in the
  displacement to first order: it is not applied.
* Compensator: a compression spring between a point on the proximal link and a point on
  the link its joint moves (:class:`Compensator`); its torque and stiffness enter the
  joint equilibrium and the flank torque.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from analysis.kinetostatics.equilibrium import (
    deflection_with_joint_torques,
    deflection_with_joint_torques_cases,
    solve_deflection,
)
from analysis.model.gravity import (
    STANDARD_GRAVITY,
    body_frames,
    gear_flanks,
    gravity_stiffness,
    gravity_torques,
)
from analysis.model.kinematics import chain_state, jacobian, pose_difference
from analysis.model.robot_model import RobotModel

#: values of :attr:`RealisticLab.gravity`
GRAVITY_MODES = ("off", "flanks", "on")



@dataclass(frozen=True)
class LinkCompliance:
    """Compliance of one flexible link at its distal frame.

    link: 1-based number of the link (the body joint ``link`` moves); matrix (6, 6):
    [translation (m); rotation (rad)] of the distal frame per [force (N); moment (N m)]
    there, all in the distal frame's axes; symmetric, positive semi-definite.
    """

    link: int
    matrix: np.ndarray


@dataclass(frozen=True)
class Compensator:
    """An axis gravity compensator: a compression spring between two attachment points.

    joint: 0-based index of the joint it acts on (1 for axis 2). base_point (3,) m: the
    spring's end on the proximal link, in the joint's frame before its rotation (the
    joint's body frame at q = 0); arm_point (3,) m: its end on the link the joint moves, in
    that link's body frame. rate (N/m) and preload (N): the spring pushes its ends apart
    with ``F = preload + rate (extended_length - L)``; extended_length (m) is the spring's
    longest length over the joint's range, where it holds its preload
    (:func:`compensator_for`).
    """

    joint: int
    base_point: np.ndarray
    arm_point: np.ndarray
    rate: float
    preload: float
    extended_length: float
    axis: np.ndarray = field(default_factory=lambda: np.array([0.0, 0.0, 1.0]))


@dataclass(frozen=True)
class RealisticLab:
    """The effects of a real arm beyond joint springs; every one off by default."""

    links: tuple[LinkCompliance, ...] = ()
    #: (n,) rad: full dead band 2b of each gear (None: no lost motion)
    lost_motion: np.ndarray | None = None
    compensator: Compensator | None = None
    #: "off"; "flanks": gravity decides the gear flanks only (the springs carry the test
    #: wrench alone, as in the joint-spring model: isolates lost motion); "on": gravity
    #: also loads the springs (the arm sags at both readings). Needs the mass model.
    gravity: str = "off"
    gravity_vector: np.ndarray = field(default_factory=lambda: STANDARD_GRAVITY.copy())

    @property
    def active(self) -> bool:
        """Any effect on (a lab with none gives exactly the joint-spring model's numbers)."""
        return bool(self.links or self.lost_motion is not None
                    or self.compensator is not None or self.gravity != "off")

    def __post_init__(self) -> None:
        if self.gravity not in GRAVITY_MODES:
            raise ValueError(f"gravity {self.gravity!r}: expected one of "
                             f"{', '.join(GRAVITY_MODES)}")


def _spring_length_sq(base: np.ndarray, arm: np.ndarray, axis: np.ndarray,
                      q: np.ndarray) -> np.ndarray:
    """Squared spring length (N,) (m^2) at joint angles q (N,) (rad)."""
    b = _rotate(axis, q, arm)
    return np.sum((b - base) ** 2, axis=-1)


def _rotate(axis: np.ndarray, q: np.ndarray, v: np.ndarray) -> np.ndarray:
    """v (3,) turned by angles q (N,) about the unit axis (3,): (N, 3) (Rodrigues)."""
    c, s = np.cos(q)[:, None], np.sin(q)[:, None]
    return v * c + np.cross(axis, v) * s + axis * (axis @ v) * (1.0 - c)


def compensator_for(robot: RobotModel, joint: int, base_point, arm_point, rate: float,
                    preload: float) -> Compensator:
    """A :class:`Compensator` on 0-based ``joint`` of ``robot``, its extended length the
    spring's longest over the joint's range (exact: L^2 = const - 2 a.b(q) is a shifted
    cosine of q, largest at a range end or where the cosine is -1)."""
    axis = np.asarray(robot.chain.axes[joint], dtype=float)
    a, b = np.asarray(base_point, dtype=float), np.asarray(arm_point, dtype=float)
    lo, hi = float(robot.lower[joint]), float(robot.upper[joint])
    # a.b(q) = a.b_par + cos q a.b_perp + sin q a.(axis x b): minimal at q = phi + pi
    b_par = axis * (axis @ b)
    phi = np.arctan2(a @ np.cross(axis, b), a @ (b - b_par))
    cands = [lo, hi]
    first = phi + np.pi + 2 * np.pi * np.ceil((lo - phi - np.pi) / (2 * np.pi))
    cands += [t for t in np.arange(first, hi, 2 * np.pi) if lo <= t <= hi]
    length = float(np.sqrt(np.max(_spring_length_sq(a, b, axis, np.array(cands)))))
    return Compensator(joint, a, b, float(rate), float(preload), length, axis)


def compensator_torque(comp: Compensator, qj: np.ndarray, preload=None,
                       rate=None) -> tuple[np.ndarray, np.ndarray]:
    """Torque tau_c (N,) (N m) the spring puts on the link its joint moves, about +axis,
    and its derivative dtau_c/dq (N,) (N m/rad), at joint angles qj (N,) (rad).

    tau_c = F axis.(a x b)/L with b = b(q) the arm point turned by q, L = |b - a|,
    F = preload + rate (extended_length - L) (compression: pushes b away from a).
    ``preload`` (N) and ``rate`` (N/m), scalars or arrays that broadcast against (N,)
    (one spring per angle, or (G, 1): G springs, results (G, N)), replace the
    compensator's own when given.
    """
    qj = np.atleast_1d(np.asarray(qj, dtype=float))
    preload = comp.preload if preload is None else preload
    rate = comp.rate if rate is None else rate
    a, e = comp.base_point, comp.axis
    b = _rotate(e, qj, comp.arm_point)
    db = np.cross(e, b)  # db/dq
    d = b - a
    L = np.sqrt(np.sum(d * d, axis=-1))
    F = preload + rate * (comp.extended_length - L)
    h = np.cross(a, b) @ e
    dh = np.cross(a, db) @ e
    dL = np.sum(d * db, axis=-1) / L
    tau = F * h / L
    dtau = (-rate * dL * h + F * dh) / L - F * h * dL / L**2
    return tau, dtau


def load_torques(robot: RobotModel, lab: RealisticLab, q: np.ndarray,
                 w: np.ndarray) -> np.ndarray:
    """J(q)^T w - g(q) + tau_c(q) (N, n) (N m) at the commanded pose q (N, n) (rad): the
    torque each gear carries (gravity unless ``lab.gravity`` is "off"), whose sign decides
    its flank; positive turns the output in +q."""
    q = np.atleast_2d(np.asarray(q, dtype=float))
    w = np.broadcast_to(np.asarray(w, dtype=float), (q.shape[0], 6))
    tau = np.einsum("pri,pr->pi", jacobian(robot, q), w)
    if lab.gravity != "off":
        tau = tau - gravity_torques(robot, q, lab.gravity_vector)
    if lab.compensator is not None:
        j = lab.compensator.joint
        tau[:, j] += compensator_torque(lab.compensator, q[:, j])[0]
    return tau


def flanks(robot: RobotModel, lab: RealisticLab, q: np.ndarray, w: np.ndarray) -> np.ndarray:
    """Flank (N, n) each gear rests on at q under w: +1, -1, or 0 (mid-band, a torque of
    at most :data:`FLANK_TOLERANCE`)."""
    tau = load_torques(robot, lab, q, w)
    return gear_flanks(tau)


def lost_motion_offset(robot: RobotModel, lab: RealisticLab, q: np.ndarray,
                       w: np.ndarray) -> np.ndarray:
    """s (N, n) (rad): the output's offset from the motor side within the dead band,
    half the band on the side of the gear's torque (0 without lost motion)."""
    q = np.atleast_2d(np.asarray(q, dtype=float))
    if lab.lost_motion is None:
        return np.zeros(q.shape)
    return 0.5 * np.asarray(lab.lost_motion, dtype=float) * flanks(robot, lab, q, w)


def joint_deflection(robot: RobotModel, lab: RealisticLab, k: np.ndarray, q: np.ndarray,
                     w: np.ndarray, tol: float = 1e-14, max_iter: int = 60) -> np.ndarray:
    """Output minus motor-side angle (N, n) (rad) at commanded q (N, n) under w (N, 6):
    the lost-motion offset s plus the elastic deflection of
    ``K dq = J^T w - g + tau_c`` at theta = q + s + dq (see the module docstring).

    Raises :class:`~analysis.kinetostatics.equilibrium.EquilibriumError` when Newton's
    method does not converge.
    """
    q = np.atleast_2d(np.asarray(q, dtype=float))
    N, n = q.shape
    w = np.ascontiguousarray(np.broadcast_to(np.asarray(w, dtype=float), (N, 6)))
    k = np.asarray(k, dtype=float)
    s = lost_motion_offset(robot, lab, q, w)
    base = q + s
    if lab.gravity != "on" and lab.compensator is None:
        return s + solve_deflection(robot, base, k, w)
    def torques(theta: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        tau = np.zeros((N, n))
        dtau = np.zeros((N, n, n))
        if lab.gravity == "on":
            tau -= gravity_torques(robot, theta, lab.gravity_vector)
            dtau -= gravity_stiffness(robot, theta, lab.gravity_vector)
        if lab.compensator is not None:
            j = lab.compensator.joint
            tc, dtc = compensator_torque(lab.compensator, theta[:, j])
            tau[:, j] += tc
            dtau[:, j, j] += dtc
        return tau, dtau

    return s + deflection_with_joint_torques(robot, base, k, w, torques, tol, max_iter)


def distal_frames(robot: RobotModel, theta: np.ndarray, link: int) -> np.ndarray:
    """Pose (N, 4, 4) of link ``link``'s (1-based) distal frame at joint angles theta (N, n):
    joint link+1's frame before its rotation, or P's frame for the last link."""
    theta = np.atleast_2d(np.asarray(theta, dtype=float))
    chain = robot.chain
    if link == robot.n:
        return chain_state(robot, theta).tip
    R, o = body_frames(robot, theta)
    P = chain.placements[link]
    T = np.zeros((theta.shape[0], 4, 4))
    T[:, :3, :3] = R[:, link - 1] @ P[:3, :3]
    T[:, :3, 3] = o[:, link - 1] + R[:, link - 1] @ P[:3, 3]
    T[:, 3, 3] = 1.0
    return T


def virtual_jacobian(distal: np.ndarray, p: np.ndarray) -> np.ndarray:
    """J_l (N, 6, 6): the twist of P (at p (N, 3), base axes) per virtual motion of the
    distal frame ``distal`` (N, 4, 4): [translations along its axes; rotations about them].
    J_l = [[R, -[p - o]x R], [0, R]]."""
    R, o = distal[:, :3, :3], distal[:, :3, 3]
    r = p - o
    skew = np.zeros((len(r), 3, 3))
    skew[:, 0, 1], skew[:, 0, 2], skew[:, 1, 2] = -r[:, 2], r[:, 1], -r[:, 0]
    skew[:, 1, 0], skew[:, 2, 0], skew[:, 2, 1] = r[:, 2], -r[:, 1], r[:, 0]
    J = np.zeros((len(r), 6, 6))
    J[:, :3, :3] = R
    J[:, :3, 3:] = -skew @ R
    J[:, 3:, 3:] = R
    return J


def link_twist(robot: RobotModel, lab: RealisticLab, theta: np.ndarray,
               w: np.ndarray) -> np.ndarray:
    """sum_l J_l C_l J_l^T w (N, 6): displacement of P [m; rad] by the links' bending at
    output angles theta (N, n) under w (N, 6) or (6,)."""
    theta = np.atleast_2d(np.asarray(theta, dtype=float))
    w = np.broadcast_to(np.asarray(w, dtype=float), (theta.shape[0], 6))
    out = np.zeros((theta.shape[0], 6))
    if not lab.links:
        return out
    p = chain_state(robot, theta).tip[:, :3, 3]
    for lc in lab.links:
        J = virtual_jacobian(distal_frames(robot, theta, lc.link), p)
        out += np.einsum("pij,jk,plk,pl->pi", J, np.asarray(lc.matrix, float), J, w)
    return out


def _rotvec_matrix(v: np.ndarray) -> np.ndarray:
    """Rotation matrices (N, 3, 3) of rotation vectors v (N, 3) (rad)."""
    t = np.sqrt(np.sum(v * v, axis=-1))[:, None, None]
    k = np.zeros((len(v), 3, 3))
    k[:, 0, 1], k[:, 0, 2], k[:, 1, 2] = -v[:, 2], v[:, 1], -v[:, 0]
    k[:, 1, 0], k[:, 2, 0], k[:, 2, 1] = v[:, 2], -v[:, 1], v[:, 0]
    safe = np.where(t > 0, t, 1.0)
    a = np.where(t > 1e-8, np.sin(safe) / safe, 1.0 - t**2 / 6)
    b = np.where(t > 1e-8, (1.0 - np.cos(safe)) / safe**2, 0.5 - t**2 / 24)
    return np.eye(3) + a * k + b * (k @ k)


def apply_twist(T: np.ndarray, twist: np.ndarray) -> np.ndarray:
    """Poses (N, 4, 4) displaced by small twists (N, 6) [dp (m); rotation vector (rad)],
    base frame: position + dp, orientation exp(rotation) R."""
    T = np.array(T, dtype=float)
    T[:, :3, :3] = _rotvec_matrix(twist[:, 3:]) @ T[:, :3, :3]
    T[:, :3, 3] += twist[:, :3]
    return T


def true_tool_poses(robot: RobotModel, lab: RealisticLab, k: np.ndarray, q: np.ndarray,
                    w: np.ndarray) -> np.ndarray:
    """Pose of P (N, 4, 4), base frame, at commanded q (N, n) under w: the joints'
    equilibrium (:func:`joint_deflection`) and the links' bending (:func:`link_twist`)."""
    q = np.atleast_2d(np.asarray(q, dtype=float))
    theta = q + joint_deflection(robot, lab, k, q, w)
    T = chain_state(robot, theta).tip
    if lab.links:
        T = apply_twist(T, link_twist(robot, lab, theta, w))
    return T


def displacement(robot: RobotModel, lab: RealisticLab, k: np.ndarray, q: np.ndarray,
                 w_ref: np.ndarray, w: np.ndarray) -> np.ndarray:
    """True displacement of P (N, 6) [m; rad], loaded (w) minus reference (w_ref) reading,
    at commanded q (N, n) (rad); wrenches (N, 6) or (6,) [N; N m] at P, base frame."""
    q = np.atleast_2d(np.asarray(q, dtype=float))
    return pose_difference(true_tool_poses(robot, lab, k, q, w_ref),
                           true_tool_poses(robot, lab, k, q, w))


def displacement_cases(robot: RobotModel, lab: RealisticLab, k: np.ndarray, q: np.ndarray,
                       w_ref: np.ndarray, w: np.ndarray,
                       springs: np.ndarray | None = None) -> np.ndarray:
    """:func:`displacement` (C, N, 6) [m; rad] of C cases at once, case c with joint
    stiffness k[c] (k (C, n), N m/rad) and, when ``springs`` (C, 2) is given, the
    compensator's (preload (N), rate (N/m)) replaced by springs[c]; the same commanded q
    (N, n) (rad) and wrenches w_ref, w ((N, 6) or (6,), [N; N m]) for all. For a lab with
    gravity and a compensator only (no links, no lost motion): the finite differences of
    a fit in one Newton loop (:func:`~analysis.kinetostatics.equilibrium.
    deflection_with_joint_torques_cases`), each case's numbers those of its own
    :func:`displacement` call."""
    if lab.links or lab.lost_motion is not None:
        raise ValueError("displacement_cases: links and lost motion are not supported")
    q = np.atleast_2d(np.asarray(q, dtype=float))
    N, n = q.shape
    k = np.atleast_2d(np.asarray(k, dtype=float))
    C = k.shape[0]
    if springs is not None and lab.compensator is None:
        raise ValueError("displacement_cases: springs given without a compensator")
    readings = [np.ascontiguousarray(np.broadcast_to(np.asarray(v, dtype=float), (N, 6)))
                for v in (w_ref, w)]
    s = lost_motion_offset(robot, lab, q, readings[0])  # zeros (no lost motion)
    base = q + s
    if lab.gravity != "on" and lab.compensator is None:
        raise ValueError("displacement_cases: needs gravity on or a compensator")
    # cases 2c and 2c + 1: case c's reference and loaded readings
    qc = np.broadcast_to(base, (2 * C, N, n))
    wc = np.tile(np.stack(readings), (C, 1, 1))
    kc = np.repeat(k, 2, axis=0)
    sp = None if springs is None else np.repeat(np.asarray(springs, dtype=float), 2, axis=0)

    def torques(theta: np.ndarray, live: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        tau = np.zeros((theta.shape[0], n))
        dtau = np.zeros((theta.shape[0], n, n))
        if lab.gravity == "on":
            tau -= gravity_torques(robot, theta, lab.gravity_vector)
            dtau -= gravity_stiffness(robot, theta, lab.gravity_vector)
        if lab.compensator is not None:
            j = lab.compensator.joint
            pr = (None, None) if sp is None else (np.repeat(sp[live, 0], N),
                                                  np.repeat(sp[live, 1], N))
            tc, dtc = compensator_torque(lab.compensator, theta[:, j], *pr)
            tau[:, j] += tc
            dtau[:, j, j] += dtc
        return tau, dtau

    dq = deflection_with_joint_torques_cases(robot, qc, kc, wc, torques)
    theta = q + (s + dq)  # as true_tool_poses: q + joint_deflection
    tips = chain_state(robot, theta.reshape(-1, n)).tip.reshape(C, 2, N, 4, 4)
    return pose_difference(tips[:, 0], tips[:, 1])


def beam_compliance(length: float, E: float, G: float, I: float, J: float,
                    A: float) -> np.ndarray:
    """6x6 tip compliance of a straight cantilever (SI) in a frame at its tip with x along
    the beam (root to tip), symmetric section (I about both bending axes):
    axial L/(EA), torsion L/(GJ), bending L^3/(3EI) (force), L/(EI) (moment) and the
    coupling L^2/(2EI) (Euler-Bernoulli). Rows [dx; rotation], columns [force; moment]."""
    L = float(length)
    C = np.zeros((6, 6))
    C[0, 0] = L / (E * A)
    C[3, 3] = L / (G * J)
    C[1, 1] = C[2, 2] = L**3 / (3 * E * I)
    C[4, 4] = C[5, 5] = L / (E * I)
    c = L**2 / (2 * E * I)
    C[1, 5] = C[5, 1] = c     # force along y turns the tip about +z
    C[2, 4] = C[4, 2] = -c    # force along z turns the tip about -y
    return C


def box_section(width: float, wall: float) -> tuple[float, float, float]:
    """(I (m^4), J (m^4), A (m^2)) of a square hollow box of outer side ``width`` and wall
    ``wall`` (m): I = (w^4 - (w - 2t)^4)/12, thin-wall torsion J = t (w - t)^3,
    A = w^2 - (w - 2t)^2."""
    w, t = float(width), float(wall)
    inner = w - 2 * t
    return (w**4 - inner**4) / 12, t * (w - t) ** 3, w**2 - inner**2


def link_beam_compliance(robot: RobotModel, link: int, E: float, G: float, I: float,
                         J: float, A: float, length: float | None = None) -> np.ndarray:
    """6x6 compliance of link ``link`` (1-based) at its distal frame, the link taken as a
    cantilever from joint ``link``'s origin to the distal frame's origin (its length, unless
    ``length`` (m) is given), :func:`beam_compliance` turned into the distal frame's axes."""
    zero = np.zeros((1, robot.n))
    D = distal_frames(robot, zero, link)[0]
    _, o = body_frames(robot, zero)
    axis_base = D[:3, 3] - o[0, link - 1]
    span = float(np.linalg.norm(axis_base))
    if span < 1e-9 and length is None:
        raise ValueError(f"link {link} has no length between its joints: give its length")
    u = D[:3, :3].T @ (axis_base / span if span >= 1e-9 else D[:3, 0])
    # a frame with x along the beam, in the distal frame's axes
    e = np.eye(3)[int(np.argmin(np.abs(u)))]
    y = np.cross(u, e)
    y /= np.linalg.norm(y)
    Rb = np.column_stack([u, y, np.cross(u, y)])
    C = beam_compliance(span if length is None else length, E, G, I, J, A)
    T = np.zeros((6, 6))
    T[:3, :3] = T[3:, 3:] = Rb
    return T @ C @ T.T
