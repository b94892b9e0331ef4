"""The robot as a simulator description needs it: the record the MJCF, URDF and SDF writers read.

:func:`sim_model` turns a :class:`~analysis.model.robot_model.RobotModel` (standard DH,
modified DH or URDF: all reach here as the same serial chain of revolute joints) and its
joint stiffness into a :class:`SimModel`: one link per joint whose frame is the joint's
frame (the joint turns about ``axis`` at the link's origin), each link placed in its
parent's frame at zero joint angle, the flange and the tool point P as frames of the last
link. Joint angles are the model's (``theta = q + theta0`` folded into the placements);
SI units throughout (m, rad, kg, N m/rad).

What no simulator format carries (the covariance of an identified model, the pendant
convention, zones...) is listed in :attr:`SimModel.left_out`, and each writer puts the
list in a comment.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from analysis.model.robot_model import RobotModel

#: placeholder mass (kg) and principal moments (kg m^2) of a link whose robot file gives
#: no inertial: MuJoCo refuses a moving body of zero mass, so one is needed; it is a
#: stated placeholder, not a property of the robot
PLACEHOLDER_MASS_KG = 1.0
PLACEHOLDER_INERTIA_KG_M2 = 0.01


@dataclass(frozen=True)
class Inertial:
    """Mass properties of one link in the link's frame.

    mass_kg; com_m (3,): centre of mass (m); inertia_kg_m2 (3, 3): rotational inertia
    about the centre of mass, link axes (kg m^2); placeholder: not from the robot file.
    """

    mass_kg: float
    com_m: np.ndarray
    inertia_kg_m2: np.ndarray
    placeholder: bool


@dataclass(frozen=True)
class SimJoint:
    """One revolute joint and the link it moves.

    placement (4, 4): the link's frame in its parent link's frame at zero joint angle (m);
    axis (3,): unit joint axis in the link's frame; lower_rad, upper_rad: limits in the
    model's joint variable; stiffness_Nm_per_rad: the joint spring (None: no spring).
    """

    name: str
    link: str
    placement: np.ndarray
    axis: np.ndarray
    lower_rad: float
    upper_rad: float
    stiffness_Nm_per_rad: float | None
    inertial: Inertial


@dataclass(frozen=True)
class SimModel:
    """A serial robot ready for a simulator description (SI units).

    base_link: name of the fixed base link; joints: base to tip; tool (4, 4): P in the
    last link's frame (m); flange (4, 4) or None: the flange in the last link's frame;
    header: lines saying what the file is (source, report_id, units, stiffness source);
    left_out: what the robot model has and no simulator format carries; notes: what the
    file holds that is not the robot model's (placeholders) and how to use it.
    """

    name: str
    base_link: str
    joints: tuple[SimJoint, ...]
    tool: np.ndarray
    flange: np.ndarray | None
    header: tuple[str, ...]
    left_out: tuple[str, ...]
    notes: tuple[str, ...] = ()

    @property
    def springs(self) -> bool:
        """Every joint has a spring (the stiffness model); else none has."""
        return all(j.stiffness_Nm_per_rad is not None for j in self.joints)

    @property
    def placeholder_inertials(self) -> bool:
        """Some link's inertial is the stated placeholder."""
        return any(j.inertial.placeholder for j in self.joints)


def _inertial(inertia) -> Inertial:
    """The link's Pinocchio inertia (link frame), or the placeholder when it has no mass."""
    mass = float(inertia.mass)
    if mass > 0.0:
        return Inertial(mass, np.array(inertia.lever, dtype=float),
                        np.array(inertia.inertia, dtype=float), placeholder=False)
    return Inertial(PLACEHOLDER_MASS_KG, np.zeros(3),
                    PLACEHOLDER_INERTIA_KG_M2 * np.eye(3), placeholder=True)


def _flange(robot: RobotModel) -> np.ndarray | None:
    model = robot.model
    if not model.existFrame("flange"):
        return None
    frame = model.frames[model.getFrameId("flange")]
    if frame.parentJoint != model.njoints - 1:
        return None
    return frame.placement.homogeneous.copy()


def left_out_items(robot: RobotModel) -> list[str]:
    """What ``robot`` holds that no simulator description carries, one phrase each."""
    items = []
    if robot.compliance_covariance is not None:
        items.append("the covariance of the identified compliances ([identification] of "
                     "the model file): the springs here are the point estimates")
    M = robot.controller_matrix
    if not (np.array_equal(M, np.eye(robot.n)) and not np.any(robot.controller_offset)):
        sign = ", ".join(f"{int(s):+d}" for s in robot.controller_sign)
        offset = ", ".join(f"{np.degrees(o):g}" for o in robot.controller_offset)
        coupled = " plus a coupling between joints" if np.any(
            robot.controller_coupling) else ""
        items.append("the teach-pendant convention: joint values here are the model's; "
                     f"pendant = sign q + offset, sign [{sign}], offset [{offset}] deg"
                     f"{coupled}")
    if robot.zones:
        items.append("the joint-space zones (" + ", ".join(z.name for z in robot.zones) + ")")
    if robot.characteristic_length is not None:
        items.append(f"the characteristic length ({robot.characteristic_length:g} m)")
    return items


def sim_model(robot: RobotModel, stiffness: np.ndarray | None,
              header: list[str] | tuple[str, ...]) -> SimModel:
    """The :class:`SimModel` of ``robot`` with joint stiffness ``stiffness`` (n,) (N m/rad;
    None: no springs) and the file's ``header`` lines.

    Links are named ``link1..linkn``, joints ``joint1..jointn``; the base link ``base``.
    Inertials come from the robot model's bodies (a URDF's, or a robot file's once it has
    them); a body without mass gets the placeholder of :data:`PLACEHOLDER_MASS_KG`.
    """
    chain = robot.chain
    k = None if stiffness is None else np.asarray(stiffness, dtype=float)
    joints = []
    for i in range(chain.n):
        joints.append(SimJoint(
            name=f"joint{i + 1}", link=f"link{i + 1}",
            placement=np.array(chain.placements[i], dtype=float),
            axis=np.array(chain.axes[i], dtype=float),
            lower_rad=float(robot.lower[i]), upper_rad=float(robot.upper[i]),
            stiffness_Nm_per_rad=None if k is None else float(k[i]),
            inertial=_inertial(robot.model.inertias[i + 1])))
    notes = ["K_C, the stiffness the load adds through the changing geometry, is not a "
             "parameter: a simulator that applies the load at the deflected pose reproduces "
             "it"]
    empty = [j.link for j in joints if j.inertial.placeholder]
    if empty:
        notes.append(f"placeholder inertials: the robot model has no mass properties for "
                     f"{', '.join(empty)}; each gets {PLACEHOLDER_MASS_KG:g} kg at the link "
                     f"origin and {PLACEHOLDER_INERTIA_KG_M2:g} kg m^2 about each axis, which "
                     "MuJoCo needs for a moving body: replace them before simulating "
                     "dynamics or gravity (statics without gravity do not depend on them)")
    return SimModel(name=robot.name, base_link="base", joints=tuple(joints),
                    tool=np.array(chain.tip, dtype=float), flange=_flange(robot),
                    header=tuple(header), left_out=tuple(left_out_items(robot)),
                    notes=tuple(notes))
