"""Robot description files (TOML or YAML) and URDF loading.

File format (every number in the units the file declares)::

    name = "My robot"
    aliases = ["myrobot"]             # names accepted by --robot
    convention = "modified_dh"        # or "standard_dh"
    length_unit = "mm"                # "m" or "mm"
    angle_unit = "deg"                # "deg" or "rad"
    stiffness_unit = "N m/rad"        # or "kN m/rad"
    limits_convention = "controller"  # joint limits as the pendant shows them, or "model"
    characteristic_length = 682       # optional, length_unit

    [[joints]]                        # six of them, base to tip
    alpha = 0                         # standard_dh: a, alpha, d, theta0
    d = 0                             # modified_dh: alpha, d, r, theta0
    r = 0
    theta0 = 0                        # constant offset: theta = q + theta0
    lower = -185                      # joint limits, angle_unit
    upper = 185
    stiffness = 1409800               # optional nominal stiffness, stiffness_unit
    controller_sign = 1               # q_ctrl = sign * q_model + offset
    controller_offset = 0             # angle_unit
    controller_coupling = { q2 = 1 }  # optional: q_ctrl += 1 * q2_model (coupled axes)
    mass = 250                        # optional: mass (kg) of link i, the body joint i moves
    com = [410, 0, 0]                 # its centre of mass in joint i's body frame, length_unit
                                      # (modified_dh: DH frame i; standard_dh: frame i-1
                                      # turned by q_i); all six links or none

    [tool]                            # tool point P in the flange frame
    xyz = [0, 0, 100]                 # length_unit
    rpy = [0, 0, 0]                   # angle_unit, fixed-axis roll-pitch-yaw
    mass = 60                         # optional tool mass (kg), with the link masses only
    com = [0, 0, 150]                 # its centre of mass in the flange frame, length_unit

    [[zones]]                         # optional joint-space boxes, model convention
    name = "zone 1"
    ranges = { q2 = [0, 110], q3 = [-245, -170] }

    [[reference_poses]]               # optional published FK checks (tests use them)
    q = [0, 0, 0, 0, 0, 0]            # model convention, angle_unit
    position = [1, 2, 3]              # of P, length_unit
    source = "..."

    [sources]                         # where every number comes from
    geometry = "..."

    [identification]                  # optional: written by `campaign analyze` (model.toml)
    quantity = "compliance"           # the covariance is of x = 1/k, not of k
    covariance_unit = "(rad/(N m))^2"
    covariance = [[...], ...]         # 6 x 6, symmetric, positive semi-definite (the
                                      # correlation matrix's eigenvalues >= -1e-9);
                                      # zero rows/columns for joints_nominal
    joints_identified = [1, 2, 3, 4, 5, 6]
    joints_nominal = []               # joints whose stiffness is the nominal one
    method = "exact"                  # estimator of campaign analyze
    covariance_source = "model"       # "model" (known sigmas) or "residual"
    n_tests = 15
    source_run = "path/to/run"
    protocol_sha256 = "..."
    date = "2025-01-01T12:00:00Z"     # when the model was written (UTC)

    [model_class]                     # optional, format version 2: written by `campaign
    version = 2                       # analyze --model` when it chose more than the
    name = "links+lost-motion"        # joint springs; files without it (version 1) are
    lost_motion_rad = [...]           # the joint-spring model. Dead bands 2b (rad, 0 =
    compensator = {c1 = ..., c2 = ..., q2ref_rad = ...}   # not identified); k2(q2) law
    notes = ["..."]
    [[model_class.links]]             # link compliance at its distal frame (joint
    link = 2                          # link+1's frame before its rotation), 6 x 6 SI,
    compliance = [[...], ...]         # [m; rad] per [N; N m]; used by campaign stiffness
                                      # and maps (analysis/kinetostatics/link_compliance.py)
    [model_class.link_covariance]     # optional: the identified link entries' names
    parameters = ["C2[1,1]", ...]     # (C<link>[a,b], 1-based), their covariance (SI)
    matrix = [[...], ...]             # and their cross-covariance with x1..x6 = 1/k
    joint_cross = [[...], ...]        # (6 rows): propagated into the K_X and deflection
                                      # intervals; without it the links count as exact
    [model_class.compensator_covariance]  # optional: the law's identified c1, c2, their
    parameters = ["c1", "c2"]         # covariance (SI), cross-covariance with x1..x6
    matrix = [[...], ...]             # (6 rows) and with the link entries above
    joint_cross = [[...], ...]        # (link_cross, one row per link entry); without it
    link_cross = [[...], ...]         # c1, c2 count as exact
"""

from __future__ import annotations

import re
from pathlib import Path
from typing import Literal

import numpy as np
import pinocchio as pin
from pydantic import BaseModel, ConfigDict, Field, ValidationError, field_validator, model_validator

from analysis.choices import GEOMETRY_CONVENTIONS
from analysis.errors import InputError
from analysis.file_errors import input_error_from_validation, read_mapping_file
from analysis.model.dh import DHRow, build_dh_model
from analysis.model.robot_model import Inertials, RobotModel, Zone, chain_from_pinocchio

_LENGTH = {"m": 1.0, "mm": 1e-3}
_ANGLE = {"rad": 1.0, "deg": np.pi / 180.0}
_STIFF = {"N m/rad": 1.0, "kN m/rad": 1e3}


class _Strict(BaseModel):
    model_config = ConfigDict(extra="forbid", allow_inf_nan=False)


class JointSpec(_Strict):
    alpha: float = 0.0
    a: float = 0.0
    d: float = 0.0
    r: float = 0.0
    theta0: float = 0.0
    lower: float
    upper: float
    stiffness: float | None = Field(default=None, gt=0)
    controller_sign: Literal[1, -1] = 1
    controller_offset: float = 0.0
    controller_coupling: dict[str, float] = {}
    mass: float | None = Field(default=None, ge=0)
    com: tuple[float, float, float] | None = None

    @field_validator("controller_coupling")
    @classmethod
    def _coupling_keys(cls, value: dict) -> dict:
        for key in value:
            if not (key.startswith("q") and key[1:].isdigit() and 1 <= int(key[1:]) <= 6):
                raise ValueError(f"coupling key {key!r}: expected q1..q6")
        return value

    @model_validator(mode="after")
    def _limits_ordered(self) -> JointSpec:
        if self.lower >= self.upper:
            raise ValueError(f"lower limit {self.lower} must be below upper limit {self.upper}")
        return self


class ToolSpec(_Strict):
    xyz: tuple[float, float, float] = (0.0, 0.0, 0.0)
    rpy: tuple[float, float, float] = (0.0, 0.0, 0.0)
    mass: float = Field(default=0.0, ge=0)
    com: tuple[float, float, float] = (0.0, 0.0, 0.0)


class ZoneSpec(_Strict):
    name: str
    ranges: dict[str, tuple[float, float]]

    @field_validator("ranges")
    @classmethod
    def _keys(cls, value: dict) -> dict:
        for key, (lo, hi) in value.items():
            if not (key.startswith("q") and key[1:].isdigit()):
                raise ValueError(f"zone range key {key!r}: expected q1..q6")
            if lo >= hi:
                raise ValueError(f"zone range {key} = [{lo}, {hi}]: expected low < high")
        return value


class ReferencePose(_Strict):
    q: list[float]
    position: tuple[float, float, float]
    source: str


#: Tolerance of the positive semi-definiteness check of a covariance: the smallest
#: eigenvalue of its correlation matrix (unit diagonal, so the check does not depend
#: on the joints' very different compliance scales) must be >= -PSD_TOLERANCE. A
#: covariance written by ``campaign analyze`` (17 significant digits) is PSD to ~1e-15.
PSD_TOLERANCE = 1e-9


def covariance_psd_problem(cov: np.ndarray) -> str | None:
    """Why the symmetric ``cov`` (n, n) with a non-negative diagonal is not a covariance
    (not positive semi-definite within :data:`PSD_TOLERANCE`), or None when it is one.

    A joint with zero variance must have zero covariances (its correlation is
    undefined, and any non-zero entry makes the matrix indefinite); the others are
    checked through the eigenvalues of their correlation matrix.
    """
    var = np.diag(cov)
    zero = var == 0
    for j in np.flatnonzero(zero):
        if np.any(cov[j] != 0):
            return (f"covariance is not positive semi-definite: joint {j + 1} has zero "
                    "variance but a non-zero covariance with another joint")
    keep = np.flatnonzero(~zero)
    if keep.size == 0:
        return None
    s = np.sqrt(var[keep])
    corr = cov[np.ix_(keep, keep)] / np.outer(s, s)
    smallest = float(np.linalg.eigvalsh(corr)[0])
    if smallest < -PSD_TOLERANCE:
        worst = float(np.linalg.eigvalsh(cov)[0])
        return (f"covariance is not positive semi-definite: its smallest eigenvalue is "
                f"{worst:.3g} (rad/(N m))^2 (correlation matrix: {smallest:.3g}, tolerance "
                f"-{PSD_TOLERANCE:g}); intervals from it would be meaningless")
    return None


def compliance_interval_problem(stiffness: np.ndarray, cov: np.ndarray, ident) -> str | None:
    """Why an identified model's covariance gives no stiffness interval, or None.

    For each identified joint the compliance x = 1/k (rad/(N m)) and its standard
    deviation sqrt(cov_jj) give the interval x +- z sd at the file's confidence (z: the
    normal's critical value, the smallest the analysis uses: a model written by
    ``campaign analyze`` passed this check with its own, larger or equal, critical
    value). An interval that reaches zero holds every stiffness up to infinity: the
    intervals derived from it (deflection, K_X) would be numbers without meaning."""
    from scipy.special import ndtri

    z = float(ndtri(0.5 + ident.confidence / 2))
    for j in ident.joints_identified:
        x, sd = 1.0 / stiffness[j - 1], float(np.sqrt(cov[j - 1, j - 1]))
        if not x - z * sd > 0:
            return (f"joint {j}: the compliance's {ident.confidence:.0%} interval reaches "
                    f"zero (its standard deviation is {sd / x:.3g} times the compliance "
                    f"1/k = {x:.4g} rad/(N m)): the covariance gives no stiffness interval; "
                    "campaign analyze writes none like it (an edited file?)")
    return None


class IdentificationSpec(_Strict):
    """``[identification]``: where an identified stiffness comes from and its covariance."""

    quantity: Literal["compliance"]
    covariance_unit: Literal["(rad/(N m))^2"]
    covariance: list[list[float]]
    joints_identified: list[int] = Field(min_length=1)
    joints_nominal: list[int] = []
    method: str
    covariance_source: str = "model"
    confidence: float = Field(default=0.95, gt=0, lt=1)
    n_tests: int = Field(ge=1)
    n_poses: int | None = Field(default=None, ge=1)
    source_run: str
    protocol_sha256: str = ""
    date: str
    software: str = ""
    notes: list[str] = []

    @field_validator("covariance")
    @classmethod
    def _covariance(cls, value: list[list[float]]) -> list[list[float]]:
        n = len(value)
        if n == 0 or any(len(row) != n for row in value):
            raise ValueError("covariance must be a square matrix (one row per joint)")
        cov = np.array(value, dtype=float)
        if not np.allclose(cov, cov.T, rtol=1e-9, atol=0.0):
            raise ValueError("covariance must be symmetric")
        if np.any(np.diag(cov) < 0):
            raise ValueError("covariance has a negative variance on its diagonal")
        problem = covariance_psd_problem(cov)
        if problem:
            raise ValueError(problem)
        return value

    @model_validator(mode="after")
    def _shape(self) -> IdentificationSpec:
        n = len(self.covariance)
        cov = np.array(self.covariance, dtype=float)
        for name, joints in (("joints_identified", self.joints_identified),
                             ("joints_nominal", self.joints_nominal)):
            if any(not 1 <= j <= n for j in joints) or len(set(joints)) != len(joints):
                raise ValueError(f"{name}: expected distinct joint numbers 1..{n}")
        if set(self.joints_identified) & set(self.joints_nominal):
            raise ValueError("a joint cannot be both identified and nominal")
        for j in self.joints_nominal:
            if np.any(cov[j - 1] != 0):
                raise ValueError(f"joint {j} is nominal but has a non-zero covariance row")
        return self


class LinkComplianceSpec(_Strict):
    """``[[model_class.links]]``: link ``link`` (1-based) compliance at its distal frame
    (joint link+1's frame before its rotation), 6 x 6 SI [m; rad] per [N; N m]."""

    link: int = Field(ge=1)
    compliance: list[list[float]]

    @field_validator("compliance")
    @classmethod
    def _square(cls, value: list[list[float]]) -> list[list[float]]:
        c = np.array(value, dtype=float)
        if c.shape != (6, 6):
            raise ValueError("compliance must be 6 x 6")
        if not np.allclose(c, c.T, rtol=1e-9, atol=0.0):
            raise ValueError("compliance must be symmetric")
        return value


class LinkCovarianceSpec(_Strict):
    """``[model_class.link_covariance]``: the identified link entries ``C<link>[a,b]``
    (1-based), their covariance (L x L, SI) and their cross-covariance with the joint
    compliances x1..x6 = 1/k (6 x L, SI)."""

    parameters: list[str]
    matrix: list[list[float]]
    joint_cross: list[list[float]]

    @model_validator(mode="after")
    def _shapes(self) -> LinkCovarianceSpec:
        n = len(self.parameters)
        m = np.array(self.matrix, dtype=float).reshape(-1)
        if m.size != n * n or np.array(self.joint_cross, dtype=float).shape != (6, n):
            raise ValueError(f"link_covariance: matrix must be {n} x {n} and joint_cross "
                             f"6 x {n} ({n} parameters)")
        bad = [p for p in self.parameters if not re.fullmatch(r"C\d\[[1-6],[1-6]\]", p)]
        if bad:
            raise ValueError(f"link_covariance: parameter {bad[0]!r} is not C<link>[a,b]")
        return self


class CompensatorCovarianceSpec(_Strict):
    """``[model_class.compensator_covariance]``: the compensator law's identified
    parameters (c1 rad/(N m) per rad, c2 per rad^2), their covariance (m x m, SI), their
    cross-covariance with the joint compliances x1..x6 = 1/k (6 x m) and with the
    entries of ``[model_class.link_covariance]`` (L x m, its order; empty without)."""

    parameters: list[Literal["c1", "c2"]]
    matrix: list[list[float]]
    joint_cross: list[list[float]]
    link_cross: list[list[float]] = []

    @model_validator(mode="after")
    def _shapes(self) -> CompensatorCovarianceSpec:
        m = len(self.parameters)
        if (np.array(self.matrix, dtype=float).reshape(-1).size != m * m
                or np.array(self.joint_cross, dtype=float).shape != (6, m)):
            raise ValueError(f"compensator_covariance: matrix must be {m} x {m} and "
                             f"joint_cross 6 x {m} ({m} parameters)")
        if self.link_cross and np.array(self.link_cross, dtype=float).shape[-1] != m:
            raise ValueError(f"compensator_covariance: link_cross must have {m} columns")
        return self


class ModelClassSpec(_Strict):
    """``[model_class]`` (model.toml, format version 2): the model class ``campaign
    analyze --model`` chose beyond the joint springs. A file without it (version 1, every
    file written before) is the joint-spring model."""

    version: Literal[2] = 2
    name: str
    links: list[LinkComplianceSpec] = []
    lost_motion_rad: list[float] = []
    compensator: dict[str, float | str] = {}
    link_covariance: LinkCovarianceSpec | None = None
    compensator_covariance: CompensatorCovarianceSpec | None = None
    notes: list[str] = []

    @model_validator(mode="after")
    def _law_link_cross(self) -> ModelClassSpec:
        cc = self.compensator_covariance
        if cc is not None and cc.link_cross:
            L = 0 if self.link_covariance is None else len(self.link_covariance.parameters)
            if len(cc.link_cross) != L:
                raise ValueError(f"compensator_covariance: link_cross has "
                                 f"{len(cc.link_cross)} rows, link_covariance {L} parameters")
        return self


class RobotFile(_Strict):
    name: str
    aliases: list[str] = []
    convention: Literal[GEOMETRY_CONVENTIONS]
    length_unit: Literal["m", "mm"]
    angle_unit: Literal["deg", "rad"]
    stiffness_unit: Literal["N m/rad", "kN m/rad"] = "N m/rad"
    limits_convention: Literal["model", "controller"] = "model"
    characteristic_length: float | None = Field(default=None, gt=0)
    joints: list[JointSpec] = Field(min_length=6, max_length=6)
    tool: ToolSpec = ToolSpec()
    zones: list[ZoneSpec] = []
    reference_poses: list[ReferencePose] = []
    sources: dict[str, str]
    notes: str = ""
    identification: IdentificationSpec | None = None
    model_class: ModelClassSpec | None = None

    @model_validator(mode="after")
    def _convention_fields(self) -> RobotFile:
        unused = "r" if self.convention == "standard_dh" else "a"
        for i, joint in enumerate(self.joints):
            if getattr(joint, unused) != 0.0:
                used = "a, alpha, d, theta0" if unused == "r" else "alpha, d, r, theta0"
                raise ValueError(
                    f"joints[{i}].{unused} is not a {self.convention} parameter "
                    f"(expected {used})"
                )
        given = [j.mass is not None for j in self.joints]
        if any(given) and not all(given):
            raise ValueError("give the mass of every link (joints[i].mass) or of none: "
                             "a partial mass model would put the missing links' weight at 0")
        if any(j.mass is not None and j.com is None for j in self.joints):
            raise ValueError("a link with a mass needs its centre of mass (joints[i].com)")
        if (self.tool.mass or any(self.tool.com)) and not all(given):
            raise ValueError("[tool] mass needs the link masses (joints[i].mass and com)")
        return self


def _rpy_matrix(rpy: np.ndarray) -> np.ndarray:
    return pin.rpy.rpyToMatrix(float(rpy[0]), float(rpy[1]), float(rpy[2]))


def robot_from_spec(spec: RobotFile, source_file: str | None = None, key: str = "") -> RobotModel:
    """Build a :class:`RobotModel` from a validated robot file."""
    ls, ang = _LENGTH[spec.length_unit], _ANGLE[spec.angle_unit]
    rows = [
        DHRow(alpha=j.alpha * ang, a=j.a * ls, d=j.d * ls, r=j.r * ls, theta0=j.theta0 * ang)
        for j in spec.joints
    ]
    sign = np.array([j.controller_sign for j in spec.joints], dtype=float)
    offset = np.array([j.controller_offset for j in spec.joints]) * ang
    lower = np.array([j.lower for j in spec.joints]) * ang
    upper = np.array([j.upper for j in spec.joints]) * ang
    coupling = np.zeros((len(spec.joints), len(spec.joints)))
    for i, j in enumerate(spec.joints):
        for key, factor in j.controller_coupling.items():
            k = int(key[1:]) - 1
            if k == i:
                raise InputError(f"joints[{i}].controller_coupling: a joint cannot be coupled "
                                 "to itself (use controller_sign)", where=source_file)
            coupling[i, k] = factor
    if abs(np.linalg.det(np.diag(sign) + coupling)) < 1e-9:
        raise InputError("controller_coupling makes the pendant convention singular: two "
                         "pendant angles would describe the same pose", where=source_file)
    if coupling.any() and spec.limits_convention == "controller":
        raise InputError("with controller_coupling, give the joint limits in the model "
                         'convention (limits_convention = "model"): coupled pendant limits '
                         "are not a box in the model's angles", where=source_file)
    if spec.limits_convention == "controller":
        a, b = sign * (lower - offset), sign * (upper - offset)
        lower, upper = np.minimum(a, b) + 0.0, np.maximum(a, b) + 0.0  # no -0.0
    tool = pin.SE3(_rpy_matrix(np.array(spec.tool.rpy) * ang), np.array(spec.tool.xyz) * ls)
    model, tip = build_dh_model(rows, spec.convention, tool, lower, upper, name=spec.name)
    stiff = [j.stiffness for j in spec.joints]
    nominal = None
    if all(s is not None for s in stiff):
        nominal = np.array(stiff, dtype=float) * _STIFF[spec.stiffness_unit]
    zones = []
    for z in spec.zones:
        ranges = {}
        for k, (lo, hi) in z.ranges.items():
            j = int(k[1:]) - 1
            if not 0 <= j < 6:
                raise InputError(f"zone {z.name!r}: joint {k} does not exist", where=source_file)
            ranges[j] = (lo * ang, hi * ang)
        zones.append(Zone(z.name, ranges))
    refs = [
        {"q": np.array(r.q) * ang, "position": np.array(r.position) * ls, "source": r.source}
        for r in spec.reference_poses
    ]
    cov = None
    if spec.identification is not None:
        cov = np.array(spec.identification.covariance, dtype=float)
        if cov.shape != (len(spec.joints),) * 2:
            raise InputError(f"[identification] covariance is {cov.shape[0]} x {cov.shape[1]}; "
                             f"the robot has {len(spec.joints)} joints", where=source_file)
        if nominal is None:
            raise InputError("[identification] needs the stiffness of every joint "
                             "(identified or nominal)", where=source_file)
        problem = compliance_interval_problem(nominal, cov, spec.identification)
        if problem:
            raise InputError(f"[identification] {problem}", where=source_file)
    inertials = None
    if spec.joints[0].mass is not None:
        flange = model.frames[model.getFrameId("flange")].placement.homogeneous
        inertials = Inertials(
            masses=np.array([j.mass for j in spec.joints], dtype=float),
            coms=np.array([j.com for j in spec.joints], dtype=float) * ls,
            tool_mass=float(spec.tool.mass),
            tool_com=flange[:3, :3] @ (np.array(spec.tool.com) * ls) + flange[:3, 3],
            source=spec.sources.get("masses", ""))
    return RobotModel(
        name=spec.name,
        model=model,
        tip_frame=tip,
        lower=lower,
        upper=upper,
        chain=chain_from_pinocchio(model, tip),
        nominal_stiffness=nominal,
        characteristic_length=(
            None if spec.characteristic_length is None else spec.characteristic_length * ls
        ),
        controller_sign=sign,
        controller_offset=offset,
        controller_coupling=coupling,
        zones=zones,
        sources=dict(spec.sources),
        reference_poses=refs,
        source_file=source_file,
        key=key,
        convention=spec.convention,
        notes=spec.notes,
        compliance_covariance=cov,
        identification=(None if spec.identification is None
                        else spec.identification.model_dump()),
        inertials=inertials,
        model_class=None if spec.model_class is None else spec.model_class.model_dump(),
    )


def load_robot_file(path: str | Path, key: str = "") -> RobotModel:
    """Load a TOML or YAML robot description file (see module docstring)."""
    path = Path(path)
    data, text = read_mapping_file(path, "robot file")
    try:
        spec = RobotFile.model_validate(data)
    except ValidationError as err:
        raise input_error_from_validation(err, str(path), text) from None
    robot = robot_from_spec(spec, source_file=str(path), key=key or path.stem)
    _check_reach(spec, robot, str(path), text)
    _check_stiffness(spec, robot, str(path), text)
    return robot


#: Chain lengths (m, :attr:`RobotModel.chain_length`) plausible for an industrial arm:
#: from a small desktop arm (~0.2 m) to the largest floor-mounted arms (~5 m), with a
#: margin. Lengths typed in mm under ``length_unit = "m"`` give ~1000 m, lengths in m
#: under ``"mm"`` ~0.003 m: both far outside.
REACH_RANGE_M = (0.05, 10.0)


#: Joint stiffness plausible for an industrial arm (N m/rad): from a small arm's wrist
#: (PUMA 560 joint 5: 101 N m/rad) to far above the largest arms' base joints (~1e7).
STIFFNESS_RANGE_NM_PER_RAD = (10.0, 1e9)


def _line(path: str, text: str, loc: tuple) -> str:
    from analysis.file_errors import toml_line, yaml_line

    finder = yaml_line if path.endswith((".yaml", ".yml")) else toml_line
    line = finder(text, loc)
    return f"{path}:{line}" if line else path


def _check_stiffness(spec: RobotFile, robot: RobotModel, path: str, text: str) -> None:
    """Refuse a nominal joint stiffness outside the plausible range, naming the unit."""
    k = robot.nominal_stiffness
    if k is None:
        return
    lo, hi = STIFFNESS_RANGE_NM_PER_RAD
    bad = np.flatnonzero((k < lo) | (k > hi))
    if bad.size == 0:
        return
    j = int(bad[0])
    hint = ""
    if k[j] > hi and spec.stiffness_unit == "kN m/rad":
        hint = ': are the values in N m/rad? (set stiffness_unit = "N m/rad")'
    elif k[j] < lo and spec.stiffness_unit == "N m/rad":
        hint = ': are the values in kN m/rad? (set stiffness_unit = "kN m/rad")'
    raise InputError(
        f"joints[{j}].stiffness = {spec.joints[j].stiffness:g} {spec.stiffness_unit} is "
        f"{k[j]:.4g} N m/rad, implausible for an industrial arm's joint (expected "
        f"{lo:g}..{hi:g} N m/rad){hint}", where=_line(path, text, ("stiffness_unit",)))


def _check_reach(spec: RobotFile, robot: RobotModel, path: str, text: str) -> None:
    """Refuse a robot file whose reach is implausible, naming the likely unit mix-up."""
    reach = robot.chain_length
    lo, hi = REACH_RANGE_M
    if lo <= reach <= hi:
        return
    lengths = [(abs(getattr(j, f)), f"joints[{i}].{f}") for i, j in enumerate(spec.joints)
               for f in ("a", "d", "r")]
    lengths += [(abs(v), f"tool.xyz[{i}]") for i, v in enumerate(spec.tool.xyz)]
    value, key = max(lengths)
    where = _line(path, text, ("length_unit",))
    other = "mm" if spec.length_unit == "m" else "m"
    raise InputError(
        f"length_unit = \"{spec.length_unit}\": the chain's link lengths add up to "
        f"{reach:.4g} m, implausible for an industrial arm (expected {lo:g}..{hi:g} m); "
        f"{key} = {value:g}: are the lengths in {other}? (set length_unit = \"{other}\")",
        where=where)


def check_urdf_text(path: Path) -> None:
    """``FILE:LINE`` messages for what the URDF parser reports without a line: XML that is
    not well formed, and a joint whose parent or child link is not defined.

    Raises
    ------
    InputError
        Naming the file and line.
    """
    import xml.parsers.expat

    try:
        data = path.read_bytes()
    except OSError as err:
        raise InputError(f"cannot read the URDF: {err.strerror}", where=str(path)) from None
    links: set[str] = set()
    joints: list[dict] = []
    stack: list[str] = []
    parser = xml.parsers.expat.ParserCreate()

    def start(tag: str, attrs: dict) -> None:
        line = parser.CurrentLineNumber
        if len(stack) == 1 and tag == "link":
            links.add(attrs.get("name", ""))
        elif len(stack) == 1 and tag == "joint":
            joints.append({"name": attrs.get("name", "?"), "line": line})
        elif len(stack) == 2 and stack[-1] == "joint" and tag in ("parent", "child"):
            joints[-1][tag] = (attrs.get("link", ""), line)
        stack.append(tag)

    parser.StartElementHandler = start
    parser.EndElementHandler = lambda tag: stack.pop()
    try:
        parser.Parse(data, True)
    except xml.parsers.expat.ExpatError as err:
        raise InputError(f"not well-formed XML: {xml.parsers.expat.ErrorString(err.code)} "
                         f"(column {err.offset + 1})", where=f"{path}:{err.lineno}") from None
    for joint in joints:
        for role in ("parent", "child"):
            if role not in joint:
                raise InputError(f"joint {joint['name']!r} has no {role} link",
                                 where=f"{path}:{joint['line']}")
            link, line = joint[role]
            if link not in links:
                raise InputError(f"joint {joint['name']!r}: {role} link {link!r} is not "
                                 "defined (no <link name=...> of that name)",
                                 where=f"{path}:{line}")


def _tip_frame_id(model, tip: str) -> int:
    """Index of the frame named ``tip``: a link's frame first, then an operational frame,
    a fixed joint's, a moving joint's.

    URDFs often name a fixed joint after the link it carries (Pinocchio then has two
    frames of one name, and looking it up without a type raises); both are one placement.
    """
    for kind in (pin.FrameType.BODY, pin.FrameType.OP_FRAME, pin.FrameType.FIXED_JOINT,
                 pin.FrameType.JOINT, pin.FrameType.SENSOR):
        if model.existFrame(tip, kind):
            return model.getFrameId(tip, kind)
    return model.getFrameId(tip)


def load_urdf(path: str | Path, tip: str, name: str | None = None) -> RobotModel:
    """Load a URDF and keep the serial chain of revolute joints from the base to ``tip``.

    Joints not on the chain (grippers, fingers) are locked at zero. Limits come
    from the URDF. No nominal stiffness: give it on the command line.
    """
    path = Path(path)
    if not path.is_file():
        raise InputError("URDF file not found", where=str(path))
    check_urdf_text(path)
    try:
        full = pin.buildModelFromUrdf(str(path))
    except (RuntimeError, ValueError) as err:
        raise InputError(f"cannot parse URDF: {err}", where=str(path)) from err
    if not full.existFrame(tip):
        names = sorted({f.name for f in full.frames if f.name != "universe"})
        raise InputError(
            f"no frame named {tip!r} in the URDF (frames: {', '.join(names)})", where="--tip"
        )
    fid = _tip_frame_id(full, tip)
    support = set(full.supports[full.frames[fid].parentJoint])
    lock = [j for j in range(1, full.njoints) if j not in support]
    model = pin.buildReducedModel(full, lock, pin.neutral(full)) if lock else full
    tip_id = _tip_frame_id(model, tip)
    return RobotModel(
        name=name or model.name or path.stem,
        model=model,
        tip_frame=tip_id,
        lower=np.array(model.lowerPositionLimit, dtype=float),
        upper=np.array(model.upperPositionLimit, dtype=float),
        chain=chain_from_pinocchio(model, tip_id),
        sources={"geometry": f"URDF {path.name}"},
        source_file=str(path),
        key=path.stem,
        convention="urdf",
    )
