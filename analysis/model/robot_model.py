"""The robot model record shared by every computation.

A :class:`RobotModel` wraps a Pinocchio model of a serial chain of revolute
joints, the tool point P, joint limits, optional nominal joint stiffness and
characteristic length, and the offsets between the model's joint convention
and the controller's (teach pendant) convention.

Joint-angle conventions
-----------------------
``q_model`` is the joint variable of the kinematic model (for the KR240-2 the
angles of Dumas et al. 2011, in which the paper's Table 4 zones are written).
The controller shows ``q_ctrl = sign * q_model + offset``, per joint, plus an
optional linear coupling between joints (FANUC-style arms show J3 relative to
the horizontal, i.e. a combination of the model's q2 and q3): in general
``q_ctrl = M q_model + offset`` with ``M = diag(sign) + coupling``.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from functools import cached_property

import numpy as np
import pinocchio as pin

from analysis.errors import InputError


@dataclass(frozen=True)
class Chain:
    """Serial revolute chain extracted from a Pinocchio model, for batched numpy kinematics.

    Attributes
    ----------
    placements : (n, 4, 4) fixed transform of joint i's frame in joint i-1's frame
        (joint 0 in the base frame), before the joint rotation (m).
    axes : (n, 3) unit rotation axis of joint i in its own frame.
    tip : (4, 4) transform of the tool point P in the last joint's frame (m).
    """

    placements: np.ndarray
    axes: np.ndarray
    tip: np.ndarray

    @property
    def n(self) -> int:
        return self.axes.shape[0]

    @cached_property
    def normal(self):
        """The chain with every joint axis along z
        (:class:`analysis.model.kinematics.NormalChain`), made once per chain: the batched
        kinematics' constant frames (no module-level cache)."""
        from analysis.model.kinematics import normal_chain

        return normal_chain(self)


@dataclass(frozen=True)
class Inertials:
    """Mass model of the arm (SI), for the gravity torques (:mod:`analysis.model.gravity`).

    masses (n,) kg of link i, the body joint i moves; coms (n, 3) m, each link's centre of
    mass in joint i's body frame (the frame Pinocchio's joint i moves: modified DH frame i);
    tool_mass kg and tool_com (3,) m, the tool's centre of mass in the last joint's body
    frame; source: where the numbers come from (the robot file's ``[sources] masses``).
    """

    masses: np.ndarray
    coms: np.ndarray
    tool_mass: float
    tool_com: np.ndarray
    source: str = ""


@dataclass(frozen=True)
class Zone:
    """A box in joint space (model convention, rad): ``ranges[j] = (lo, hi)`` for joint index j."""

    name: str
    ranges: dict[int, tuple[float, float]]


@dataclass
class RobotModel:
    """A robot ready for kinetostatics (SI units, model joint convention)."""

    name: str
    model: pin.Model
    tip_frame: int
    lower: np.ndarray
    upper: np.ndarray
    chain: Chain
    nominal_stiffness: np.ndarray | None = None
    characteristic_length: float | None = None
    controller_sign: np.ndarray | None = None
    controller_offset: np.ndarray | None = None
    controller_coupling: np.ndarray | None = None  # (n, n), zero diagonal
    zones: list[Zone] = field(default_factory=list)
    sources: dict[str, str] = field(default_factory=dict)
    reference_poses: list[dict] = field(default_factory=list)
    source_file: str | None = None
    key: str = ""
    convention: str = ""
    notes: str = ""
    #: (n, n) covariance of the joint compliances x = 1/k ((rad/(N m))^2) of an identified
    #: model (``model.toml`` written by ``campaign analyze``); zero rows and columns for
    #: joints that keep their nominal stiffness. None for a nominal model.
    compliance_covariance: np.ndarray | None = None
    #: the ``[identification]`` table of an identified model (method, n_tests, source run,
    #: protocol hash, date...), as read from the file; None for a nominal model.
    identification: dict | None = None
    #: link masses and centres of mass and the tool mass (robot file ``mass``/``com``);
    #: None: no mass model (the gravity torques are refused)
    inertials: Inertials | None = None
    #: the ``[model_class]`` table of a model.toml written by ``campaign analyze --model``
    #: (link compliances, lost motion, compensator), as read; None: joint springs only
    model_class: dict | None = None

    def __post_init__(self) -> None:
        n = self.n
        if self.controller_sign is None:
            self.controller_sign = np.ones(n)
        if self.controller_offset is None:
            self.controller_offset = np.zeros(n)
        if self.controller_coupling is None:
            self.controller_coupling = np.zeros((n, n))

    @property
    def controller_matrix(self) -> np.ndarray:
        """M (n, n) of ``q_ctrl = M q_model + offset``."""
        return np.diag(self.controller_sign) + self.controller_coupling

    @property
    def n(self) -> int:
        """Number of joints."""
        return self.chain.n

    @property
    def chain_length(self) -> float:
        """Sum of the fixed link translations from joint 1 to P (m): the arm's reach
        (P's largest distance from joint 1's origin) is at most this, and close to it for
        an industrial arm. Used to judge whether lengths and deflections are plausible."""
        links = np.linalg.norm(self.chain.placements[1:, :3, 3], axis=-1).sum()
        return float(links + np.linalg.norm(self.chain.tip[:3, 3]))

    def to_controller(self, q: np.ndarray) -> np.ndarray:
        """Model joint angles (rad) -> controller (teach pendant) angles (rad)."""
        return np.asarray(q, dtype=float) @ self.controller_matrix.T + self.controller_offset

    def from_controller(self, q_ctrl: np.ndarray) -> np.ndarray:
        """Controller (teach pendant) angles (rad) -> model joint angles (rad)."""
        shifted = np.asarray(q_ctrl, dtype=float) - self.controller_offset
        return shifted @ np.linalg.inv(self.controller_matrix).T

    def check_q(self, q: np.ndarray, where: str = "q") -> np.ndarray:
        """Validate joint angles: shape (..., n) and finite; returns a float array."""
        arr = np.asarray(q, dtype=float)
        if arr.ndim == 0 or arr.shape[-1] != self.n:
            raise InputError(
                f"expected {self.n} joint angles for {self.name}, got shape {arr.shape}",
                where=where,
            )
        if not np.all(np.isfinite(arr)):
            raise InputError("joint angles must be finite numbers", where=where)
        return arr

    def map_limits(self) -> tuple[np.ndarray, np.ndarray]:
        """Joint ranges (rad) to map or search: the limits, or one turn (-pi..pi) for a
        joint turning more than a full turn (the kinematics are periodic in each angle)."""
        lo, hi = self.lower.copy(), self.upper.copy()
        wide = hi - lo > 2 * np.pi
        lo[wide], hi[wide] = -np.pi, np.pi
        return lo, hi

    def within_limits(self, q: np.ndarray, margin: float = 0.0) -> np.ndarray:
        """Boolean mask (...,): all joints inside [lower + margin, upper - margin] (rad)."""
        q = np.asarray(q, dtype=float)
        return np.all((q >= self.lower + margin) & (q <= self.upper - margin), axis=-1)


def _axis_of(joint: pin.JointModel) -> np.ndarray:
    short = joint.shortname()
    if short == "JointModelRX":
        return np.array([1.0, 0.0, 0.0])
    if short == "JointModelRY":
        return np.array([0.0, 1.0, 0.0])
    if short == "JointModelRZ":
        return np.array([0.0, 0.0, 1.0])
    if short == "JointModelRevoluteUnaligned":
        axis = np.asarray(joint.extract().axis, dtype=float)
        return axis / np.linalg.norm(axis)
    raise InputError(
        f"joint type {short} is not supported: expected a revolute joint with limits "
        "(continuous and prismatic joints are not part of the stiffness model)"
    )


def chain_from_pinocchio(model: pin.Model, tip_frame: int) -> Chain:
    """Extract the serial revolute chain from the base to ``tip_frame``.

    The model must contain only the chain's joints (lock others beforehand).
    """
    placements, axes = [], []
    for jid in range(1, model.njoints):
        if model.parents[jid] != jid - 1:
            raise InputError("the kinematic tree is not a serial chain to the tip frame")
        placements.append(model.jointPlacements[jid].homogeneous)
        axes.append(_axis_of(model.joints[jid]))
    frame = model.frames[tip_frame]
    if frame.parentJoint != model.njoints - 1:
        raise InputError(f"tip frame {frame.name!r} is not on the last joint of the chain")
    return Chain(np.array(placements), np.array(axes), frame.placement.homogeneous.copy())
