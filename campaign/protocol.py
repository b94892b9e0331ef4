"""Campaign protocol files (TOML or YAML): schema, loading and validation.

A protocol says which robot and tool are used, how to reach the instruments,
which loads are applied and how, how many tests to plan, where to sample the
poses (zones), which poses to reject (thresholds, safety) and how the fake lab
behaves. ``protocols/README.md`` documents every key with its unit.

Units at the edge are in the key names (``xyz_mm``, ``rpy_deg``,
``max_v_r_deg``...); the accessors of :class:`Protocol` return SI values (m,
rad, N, N m). Every problem found in a file is reported as
``file:line: key: message`` (see :mod:`analysis.file_errors`).
"""

from __future__ import annotations

import math
from datetime import date
from pathlib import Path
from typing import Annotated, Literal

import numpy as np
from pydantic import (
    AfterValidator,
    BaseModel,
    ConfigDict,
    Field,
    PrivateAttr,
    ValidationError,
    field_validator,
    model_validator,
)

from analysis.errors import InputError
from analysis.file_errors import (
    input_error_from_validation,
    read_mapping_file,
    toml_line,
    yaml_line,
)
from campaign.planning.separation import DEFAULT_MIN_SEPARATION_DEG

DEG = math.pi / 180.0


def _within(limit: float, unit: str, why: str):
    """A float type refusing ``|value| > limit`` (a plausible range, not a safety limit):
    a value beyond it is a unit slip or a typo (``-1e300``), and would overflow the
    sums and norms made of it."""

    def check(value: float) -> float:
        if abs(value) > limit:
            raise ValueError(f"{value:g} {unit} is implausible: expected |value| <= "
                             f"{limit:g} {unit} ({why}); check the value and its unit")
        return value

    return Annotated[float, AfterValidator(check)]


#: Plausible ranges of the protocol's numbers (protocols/README.md lists them).
ForceN = _within(1e5, "N", "100 kN: far above any test load of an industrial arm")
MomentNm = _within(1e5, "N m", "100 kN m")
LengthMm = _within(1e5, "mm", "100 m")
AngleDeg = _within(3600.0, "deg", "ten turns")
Stiffness = _within(1e10, "N m/rad", "far above any industrial joint")
Ratio = _within(1e6, "", "a direction's components are scaled to a unit vector")
Force3 = tuple[ForceN, ForceN, ForceN]
Moment3 = tuple[MomentNm, MomentNm, MomentNm]
Length3 = tuple[LengthMm, LengthMm, LengthMm]
Angle3 = tuple[AngleDeg, AngleDeg, AngleDeg]
Angle6 = tuple[AngleDeg, AngleDeg, AngleDeg, AngleDeg, AngleDeg, AngleDeg]
Stiffness6 = tuple[Stiffness, Stiffness, Stiffness, Stiffness, Stiffness, Stiffness]
LoadMethod = Literal["hanging-mass", "cable-pulley", "push"]


class _Strict(BaseModel):
    model_config = ConfigDict(extra="forbid", allow_inf_nan=False)


def _joint_keys(value: dict, what: str) -> dict:
    for key in value:
        if not (key.startswith("q") and key[1:].isdigit() and 1 <= int(key[1:]) <= 6):
            raise ValueError(f"{what} key {key!r}: expected q1..q6")
    return value


def _ordered_ranges(value: dict) -> dict:
    for key, (lo, hi) in value.items():
        if lo >= hi:
            raise ValueError(f"range {key} = [{lo}, {hi}]: expected low < high")
    return value


class CampaignSpec(_Strict):
    """``[campaign]``: what is identified and how many tests."""

    name: str
    robot: str
    tests: int = Field(ge=1, le=200)
    repeats: int = Field(default=1, ge=1, le=100)
    prior_stiffness: Stiffness6 | None = None
    characteristic_length_mm: LengthMm | None = Field(default=None, gt=0)
    #: the model class the planner designs for (campaign.planning.model_class)
    model: str = "joints"

    @field_validator("model")
    @classmethod
    def _model_class(cls, value):
        from analysis.identification.models.names import parse_model

        try:
            parse_model(value)
        except InputError as err:
            raise ValueError(str(err).split(":", 1)[-1].strip() if ":" in str(err)
                             else str(err)) from None
        return value

    @field_validator("prior_stiffness")
    @classmethod
    def _positive(cls, value):
        if value is not None and min(value) <= 0:
            raise ValueError("prior stiffness values must be positive (N m/rad)")
        return value


class ToolSpec(_Strict):
    """``[tool]``: the tool point P in the flange frame, and the tool mass."""

    xyz_mm: Length3 = (0.0, 0.0, 0.0)
    rpy_deg: Angle3 = (0.0, 0.0, 0.0)
    mass_kg: float = Field(default=0.0, ge=0, le=1e4)


class NoiseSpec(_Strict):
    """Standard deviations of an instrument's readings (one sigma, per component)."""

    # upper bounds: plausible ranges (0.1 m, 0.1 rad, 10 kN, 10 kN m, 100 %)
    translation_um: float | None = Field(default=None, ge=0, le=1e5)
    rotation_urad: float | None = Field(default=None, ge=0, le=1e5)
    force_N: float | None = Field(default=None, ge=0, le=1e4)
    torque_N_m: float | None = Field(default=None, ge=0, le=1e4)
    joint_urad: float | None = Field(default=None, ge=0, le=1e5)
    # F/T noise proportional to the reading: % of |f| (of |m|), in quadrature with force_N
    force_pct: float | None = Field(default=None, ge=0, le=100)
    torque_pct: float | None = Field(default=None, ge=0, le=100)


class InstrumentSpec(_Strict):
    """``[instruments.<role>]``: a driver name and its address string.

    ``model``, ``serial``, ``calibration_date``, ``calibration_due`` (dates,
    TOML ``2026-03-14`` or a ``"2026-03-14"`` string) and ``certificate`` (its
    number) are optional and only reported (docs/report.md).
    """

    driver: str = Field(min_length=1)
    address: str = Field(min_length=1)
    model: str | None = Field(default=None, min_length=1)
    serial: str | None = Field(default=None, min_length=1)
    calibration_date: date | None = None
    calibration_due: date | None = None
    certificate: str | None = Field(default=None, min_length=1)
    # driver options; nested tables (e.g. reflectors_mm) are checked by their consumer
    options: dict[str, str | int | float | bool | dict[str, list[float]]] = {}
    mount_xyz_mm: Length3 | None = None
    mount_rpy_deg: Angle3 | None = None
    noise: NoiseSpec = NoiseSpec()


class LoadCaseSpec(_Strict):
    """``[[load_cases]]``: a wrench at P (base-frame components) and how it is applied."""

    name: str = Field(min_length=1)
    method: LoadMethod
    force_N: Force3 | None = None
    moment_N_m: Moment3 | None = None
    direction: tuple[Ratio, Ratio, Ratio] | None = None
    magnitude_N: ForceN | None = Field(default=None, gt=0)
    #: the reference reading is taken under this fraction of the test wrench (same
    #: direction), so every gear stays on the flank the test load puts it on; the measured
    #: displacement is then loaded minus preloaded, for the wrench difference
    preload_fraction: float = Field(default=0.0, ge=0, lt=1)

    @model_validator(mode="after")
    def _one_form(self) -> LoadCaseSpec:
        vector = self.force_N is not None or self.moment_N_m is not None
        directed = self.direction is not None or self.magnitude_N is not None
        if vector == directed:
            raise ValueError("give either force_N/moment_N_m, or direction and magnitude_N")
        if directed and (self.direction is None or self.magnitude_N is None):
            raise ValueError("direction and magnitude_N go together")
        if directed and math.hypot(*self.direction) == 0.0:
            raise ValueError("direction must not be the zero vector")
        w = self.wrench()
        if not np.any(w):
            raise ValueError("the wrench is zero")
        if self.method == "hanging-mass":
            f = w[:3]
            if np.any(w[3:]) or abs(f[0]) + abs(f[1]) > 1e-9 * abs(f[2]) or f[2] >= 0:
                raise ValueError(
                    "a hanging mass pulls straight down: expected a pure force along -z0"
                )
        return self

    def wrench(self) -> np.ndarray:
        """Wrench [f (N); m (N m)] (6,), components in the robot base frame F0."""
        if self.direction is not None and self.magnitude_N is not None:
            d = np.asarray(self.direction, dtype=float)
            return np.concatenate([d / np.linalg.norm(d) * self.magnitude_N, np.zeros(3)])
        f = np.zeros(3) if self.force_N is None else np.asarray(self.force_N, dtype=float)
        m = np.zeros(3) if self.moment_N_m is None else np.asarray(self.moment_N_m, dtype=float)
        return np.concatenate([f, m])

    def reference_wrench(self) -> np.ndarray:
        """Wrench (6,) [N; N m] of the reference reading: ``preload_fraction`` x the test
        wrench (zero without a preload), base frame."""
        return self.preload_fraction * self.wrench()


class LoadsSpec(_Strict):
    """``[loads]``: how load cases are combined with poses."""

    selection: Literal["per-pose", "all"] = "all"


class ZoneSpec(_Strict):
    """``[[zones]]``: a box in joint space, model convention, degrees."""

    name: str = Field(min_length=1)
    ranges_deg: dict[str, tuple[AngleDeg, AngleDeg]]

    @field_validator("ranges_deg")
    @classmethod
    def _keys(cls, value: dict) -> dict:
        return _ordered_ranges(_joint_keys(value, "zone range"))


class SamplingSpec(_Strict):
    """``[sampling]``: values of the joints that zones leave free (model convention, deg)."""

    use_robot_zones: bool = True
    fixed_deg: dict[str, AngleDeg] = {}
    ranges_deg: dict[str, tuple[AngleDeg, AngleDeg]] = {}

    @field_validator("fixed_deg")
    @classmethod
    def _fixed_keys(cls, value: dict) -> dict:
        return _joint_keys(value, "fixed_deg")

    @field_validator("ranges_deg")
    @classmethod
    def _range_keys(cls, value: dict) -> dict:
        return _ordered_ranges(_joint_keys(value, "ranges_deg"))


class ThresholdSpec(_Strict):
    """``[thresholds]``: rejection of candidate poses."""

    min_inv_kappa_F: float = Field(default=0.0, ge=0, le=1)
    max_v_p: float = Field(default=1.0, gt=0)
    max_v_r_deg: float = Field(default=180.0, gt=0)
    #: smallest joint-space distance between two planned poses (campaign.planning.separation)
    min_pose_separation_deg: float = Field(default=DEFAULT_MIN_SEPARATION_DEG, ge=0, le=360)


class SafetySpec(_Strict):
    """``[safety]``: limits the planner and the runner respect."""

    joint_margin_deg: float = Field(default=2.0, ge=0, le=90)
    max_joint_speed_deg_s: float = Field(default=10.0, gt=0, le=1e3)
    max_joint_acceleration_deg_s2: float = Field(default=20.0, gt=0, le=1e5)
    approach_offset_mm: float = Field(default=50.0, ge=0, le=1e4)
    max_force_N: ForceN = Field(default=1000.0, gt=0)
    max_moment_N_m: MomentNm = Field(default=200.0, gt=0)


class ReportSpec(_Strict):
    """``[report]``: what ``campaign analyze`` shows besides the identification.

    ``poses_deg``: name -> six joint angles (model convention, deg) where the
    report gives K_X; ``wrench``: [fx, fy, fz (N), mx, my, mz (N m)] at P, base
    frame, for the predicted deflection (default: the first load case).
    """

    poses_deg: dict[str, Angle6] = {}
    wrench: tuple[ForceN, ForceN, ForceN, MomentNm, MomentNm, MomentNm] | None = None


#: the simulated lab's fastest clock (times the wall clock): the protocol's
#: ``[fake_lab] time_scale``, ``--time-scale`` and the GUI's field share it
MAX_TIME_SCALE = 1e4

LostMotion = _within(0.1, "rad", "0.1 rad is 6 deg of play: mrad or arcmin typed as rad?")
LengthM = _within(100.0, "m", "100 m")
Modulus = _within(1e13, "Pa", "above any engineering material")
Drift = _within(1.0, "per s", "a metre or a newton per second is no drift")


class BeamSpec(_Strict):
    """``beam`` of a ``[[fake_lab.links]]``: the link as a cantilever of symmetric section,
    SI: ``E_Pa``, ``G_Pa`` and either ``width_m``/``wall_m`` of a square hollow box or
    ``I_m4``, ``J_m4``, ``A_m2``; ``length_m`` (default: the distance between the link's
    joints)."""

    E_Pa: Modulus = Field(gt=0)
    G_Pa: Modulus = Field(gt=0)
    width_m: LengthM | None = Field(default=None, gt=0)
    wall_m: LengthM | None = Field(default=None, gt=0)
    I_m4: float | None = Field(default=None, gt=0)
    J_m4: float | None = Field(default=None, gt=0)
    A_m2: float | None = Field(default=None, gt=0)
    length_m: LengthM | None = Field(default=None, gt=0)

    @model_validator(mode="after")
    def _one_section(self) -> BeamSpec:
        box = (self.width_m, self.wall_m)
        sec = (self.I_m4, self.J_m4, self.A_m2)
        if all(v is not None for v in box) == all(v is not None for v in sec) or (
                any(v is not None for v in box) and any(v is not None for v in sec)):
            raise ValueError("give either width_m and wall_m (square hollow box) or I_m4, "
                             "J_m4 and A_m2")
        if self.wall_m is not None and 2 * self.wall_m >= self.width_m:
            raise ValueError("wall_m must be less than half of width_m")
        return self


class LinkSpec(_Strict):
    """``[[fake_lab.links]]``: a flexible link of the simulated robot (virtual-joint model):
    ``link`` 1..6 (the body joint ``link`` moves), and its compliance at its distal frame,
    either ``compliance`` (6 x 6, SI: [m; rad] per [N; N m], the distal frame's axes) or
    ``beam`` (:class:`BeamSpec`)."""

    link: int = Field(ge=1, le=6)
    compliance: list[list[float]] | None = None
    beam: BeamSpec | None = None

    @model_validator(mode="after")
    def _one_form(self) -> LinkSpec:
        if (self.compliance is None) == (self.beam is None):
            raise ValueError("give either compliance (6 x 6) or beam")
        if self.compliance is not None:
            C = np.array(self.compliance, dtype=float)
            if C.shape != (6, 6) or not np.all(np.isfinite(C)):
                raise ValueError("compliance: expected 6 rows of 6 numbers (SI)")
            if not np.allclose(C, C.T, rtol=1e-9, atol=0.0):
                raise ValueError("compliance must be symmetric")
            if np.linalg.eigvalsh(C)[0] < -1e-9 * max(np.abs(C).max(), 1e-300):
                raise ValueError("compliance must be positive semi-definite")
        return self


class CompensatorSpec(_Strict):
    """``[fake_lab.compensator]``: a compression spring between the link before joint
    ``joint`` (base_point_m, in that joint's frame at q = 0) and the link it moves
    (arm_point_m, in that link's frame), rate_N_per_m, preload_N (its force at its longest
    over the joint's range)."""

    joint: int = Field(default=2, ge=1, le=6)
    base_point_m: tuple[LengthM, LengthM, LengthM]
    arm_point_m: tuple[LengthM, LengthM, LengthM]
    rate_N_per_m: float = Field(ge=0, le=1e9)
    preload_N: ForceN = Field(ge=0)


class FakeLabSpec(_Strict):
    """``[fake_lab]``: the simulated lab (truth and noise it simulates), and the effects of
    a real arm it can add (each off unless given; protocols/README.md)."""

    true_joint_stiffness: Stiffness6
    noise: NoiseSpec = NoiseSpec()
    seed: int = Field(default=0, ge=0)
    time_scale: float = Field(default=1.0, gt=0, le=MAX_TIME_SCALE)

    time_scale: float = Field(default=1.0, gt=0, le=1e4)
    gravity: Literal["off", "flanks", "on"] = "off"
    lost_motion_rad: tuple[LostMotion, LostMotion, LostMotion, LostMotion, LostMotion,
                           LostMotion] | None = None
    links: list[LinkSpec] = []
    compensator: CompensatorSpec | None = None
    tracker_drift_m_per_s: tuple[Drift, Drift, Drift] | None = None
    ft_drift_N_per_s: tuple[Drift, Drift, Drift] | None = None
    ft_drift_N_m_per_s: tuple[Drift, Drift, Drift] | None = None

    @field_validator("lost_motion_rad")
    @classmethod
    def _band(cls, value):
        if value is not None and min(value) < 0:
            raise ValueError("lost motion (the full dead band 2b, rad) must be >= 0")
        return value

    @field_validator("links")
    @classmethod
    def _distinct(cls, value):
        numbers = [link.link for link in value]
        if len(set(numbers)) != len(numbers):
            raise ValueError(f"each link at most once, got links {numbers}")
        return value

    def effects(self) -> dict[str, object]:
        """The real-arm effects that are on, SI, with the simulated lab's field names
        (empty for a joint-spring lab)."""
        out: dict[str, object] = {}
        if self.gravity != "off":
            out["gravity"] = self.gravity
        if self.lost_motion_rad is not None:
            out["lost_motion"] = tuple(self.lost_motion_rad)
        if self.links:
            out["links"] = tuple(link.model_dump(exclude_none=True) for link in self.links)
        if self.compensator is not None:
            c = self.compensator
            out["compensator"] = {"joint": c.joint, "base_point": tuple(c.base_point_m),
                                  "arm_point": tuple(c.arm_point_m), "rate": c.rate_N_per_m,
                                  "preload": c.preload_N}
        if self.tracker_drift_m_per_s is not None:
            out["tracker_drift"] = tuple(self.tracker_drift_m_per_s)
        if self.ft_drift_N_per_s is not None or self.ft_drift_N_m_per_s is not None:
            out["ft_drift"] = (*(self.ft_drift_N_per_s or (0.0,) * 3),
                               *(self.ft_drift_N_m_per_s or (0.0,) * 3))
        return out

    @field_validator("true_joint_stiffness")
    @classmethod
    def _positive(cls, value):
        if min(value) <= 0:
            raise ValueError("true joint stiffness values must be positive (N m/rad)")
        return value


class Protocol(_Strict):
    """A validated campaign protocol. Load it with :func:`load_protocol`."""

    campaign: CampaignSpec
    tool: ToolSpec = ToolSpec()
    instruments: dict[str, InstrumentSpec]
    loads: LoadsSpec = LoadsSpec()
    load_cases: list[LoadCaseSpec] = Field(min_length=1)
    sampling: SamplingSpec = SamplingSpec()
    zones: list[ZoneSpec] = []
    thresholds: ThresholdSpec = ThresholdSpec()
    safety: SafetySpec = SafetySpec()
    fake_lab: FakeLabSpec | None = None
    report: ReportSpec = ReportSpec()

    _path: str = PrivateAttr(default="<protocol>")
    _text: str = PrivateAttr(default="")

    @model_validator(mode="after")
    def _cross_checks(self) -> Protocol:
        names = [c.name for c in self.load_cases]
        if len(set(names)) != len(names):
            raise ValueError(f"load case names must be unique, got {names}")
        if "pose" not in self.instruments:
            raise ValueError("instruments: a 'pose' instrument (tracker) is required")
        return self

    # -- provenance ---------------------------------------------------------------
    @property
    def path(self) -> str:
        """File the protocol was read from."""
        return self._path

    @property
    def text(self) -> str:
        """Exact text of the protocol file."""
        return self._text

    def where(self, *loc: str | int) -> str:
        """``file:line: key`` for a key path such as ``("thresholds", "max_v_p")``."""
        finder = yaml_line if self._path.endswith((".yaml", ".yml")) else toml_line
        line = finder(self._text, loc) if self._text else None
        key = ""
        for part in loc:
            key += f"[{part}]" if isinstance(part, int) else ("." if key else "") + str(part)
        return f"{self._path}:{line}: {key}" if line else f"{self._path}: {key}"

    # -- SI accessors -------------------------------------------------------------
    def wrenches(self) -> np.ndarray:
        """(m, 6) wrenches of the load cases, [N, N, N, N m, N m, N m], base frame."""
        return np.array([c.wrench() for c in self.load_cases])

    def reference_wrenches(self) -> np.ndarray:
        """(m, 6) wrenches of the load cases' reference readings (their preloads; zeros
        where none), [N; N m], base frame."""
        return np.array([c.reference_wrench() for c in self.load_cases])

    @property
    def preloaded(self) -> bool:
        """Some load case takes its reference reading under a preload."""
        return any(c.preload_fraction > 0 for c in self.load_cases)

    def reflectors(self) -> dict[str, tuple[float, float, float]] | None:
        """Reflector positions (m, tool frame) from the pose instrument's ``reflectors_mm``.

        ``options = { reflectors_mm = { NAME = [x, y, z], ... } }`` (mm): three or
        more reflectors measured in turn, the tool pose being their rigid fit.
        None when the instrument is a 6-DoF probe (no such option).
        """
        spec = self.instruments.get("pose")
        if spec is None:
            return None
        where = self.where("instruments", "pose", "options")
        if "reflectors" in spec.options:
            raise InputError("give reflector positions as reflectors_mm = { NAME = [x, y, z], "
                             "... } (mm, tool frame)", where=where)
        raw = spec.options.get("reflectors_mm")
        if raw is None:
            return None
        if not isinstance(raw, dict) or len(raw) < 3:
            raise InputError("reflectors_mm: expected at least three NAME = [x, y, z] "
                             "entries (mm, tool frame)", where=where)
        out = {}
        for name, xyz in raw.items():
            vec = np.array(xyz, dtype=float) if isinstance(xyz, list | tuple) else np.array([])
            if vec.shape != (3,) or not np.all(np.isfinite(vec)):
                raise InputError(f"reflectors_mm.{name}: expected [x, y, z] in mm, got {xyz!r}",
                                 where=where)
            out[str(name)] = tuple(float(v) * 1e-3 for v in vec)
        return out

    def pose_reading_sigma(self) -> tuple[float, float]:
        """Standard deviation of one pose reading of the tool point: (m, rad) per axis.

        A 6-DoF probe: the pose instrument's ``translation_um`` and
        ``rotation_urad``. Reflectors (``reflectors_mm``): ``translation_um`` is the
        noise of each point, and the rotation (and P's position) follow from the
        geometry of the rigid fit (:func:`analysis.identification.noise.rigid_fit_sigma`);
        ``rotation_urad`` is then not needed.
        """
        from analysis.identification.noise import rigid_fit_sigma

        noise = self.instruments["pose"].noise
        where = self.where("instruments", "pose", "noise")
        reflectors = self.reflectors()
        if noise.translation_um is None or (noise.rotation_urad is None and reflectors is None):
            raise InputError("the pose instrument needs translation_um and rotation_urad "
                             "(rotation_urad may be left out with reflectors_mm)", where=where)
        if reflectors is None:
            return noise.translation_um * 1e-6, noise.rotation_urad * 1e-6
        try:
            return rigid_fit_sigma(np.array(list(reflectors.values())),
                                   noise.translation_um * 1e-6)
        except ValueError as err:
            raise InputError(str(err), where=self.where("instruments", "pose", "options")
                             ) from None

    def measurement_sigma(self) -> np.ndarray:
        """(6,) standard deviation of one measured displacement component [m x3, rad x3].

        From :meth:`pose_reading_sigma`, divided by sqrt(repeats) (each test is
        measured ``repeats`` times).
        """
        s_t, s_r = self.pose_reading_sigma()
        sigma = np.array([s_t] * 3 + [s_r] * 3)
        if np.any(sigma <= 0):
            raise InputError("instrument noise must be positive for the planner",
                             where=self.where("instruments", "pose", "noise"))
        return sigma / math.sqrt(self.campaign.repeats)

    @property
    def lab(self) -> dict[str, object] | None:
        """Fake-lab settings in SI with the simulated lab's field names (None if absent)."""
        if self.fake_lab is None:
            return None
        lab = self.fake_lab
        robot = self.campaign.robot
        from analysis.model.robot_spec import is_robot_file

        is_file = is_robot_file(robot)
        if is_file and not Path(robot).is_absolute():
            # robot files are named relative to the protocol file
            robot = str(Path(self._path).parent / robot)
        out: dict[str, object] = {
            "robot": robot,
            "true_joint_stiffness": tuple(lab.true_joint_stiffness),
            "seed": lab.seed,
            "time_scale": lab.time_scale,
        }
        n = lab.noise
        for name, value, scale in (
            ("force_noise", n.force_N, 1.0),
            ("torque_noise", n.torque_N_m, 1.0),
            ("tracker_noise", n.translation_um, 1e-6),
            ("tracker_angle_noise", n.rotation_urad, 1e-6),
            ("encoder_noise", n.joint_urad, 1e-6),
        ):
            if value is not None:
                out[name] = value * scale
        out.update(lab.effects())
        return out


def load_protocol(path: str | Path) -> Protocol:
    """Read and validate a protocol file (schema, units, loads against safety limits).

    Checks that need the robot (zones inside joint limits, thresholds that
    leave candidates) are made by :func:`campaign.planning.planner.make_plan`, which
    reports them with the same ``file:line: key`` form.

    Raises
    ------
    InputError
        Naming the file, line and key of every problem.
    """
    path = Path(path)
    data, text = read_mapping_file(path, "protocol file")
    try:
        protocol = Protocol.model_validate(data)
    except ValidationError as err:
        raise input_error_from_validation(err, str(path), text) from None
    protocol._path = str(path)
    protocol._text = text
    _check_safety(protocol)
    _check_instruments(protocol)
    return protocol


def _check_instruments(protocol: Protocol) -> None:
    """Driver names known to the registry and addresses that parse (see :mod:`drivers`)."""
    try:
        from drivers.address import parse_address
        from drivers.errors import AddressError
        from drivers.registry import available_drivers
    except ImportError:  # the drivers package is optional for planning
        return
    known = available_drivers()
    for role, spec in protocol.instruments.items():
        if spec.driver not in known:
            raise InputError(
                f"unknown driver {spec.driver!r} for {role}: expected one of "
                f"{', '.join(sorted(known))}",
                where=protocol.where("instruments", role, "driver"),
            )
        try:
            parse_address(spec.address)
        except AddressError as err:
            raise InputError(f"bad address {spec.address!r}: {err}",
                             where=protocol.where("instruments", role, "address")) from None


def _check_safety(protocol: Protocol) -> None:
    safety = protocol.safety
    for i, case in enumerate(protocol.load_cases):
        w = case.wrench()
        f, m = float(np.linalg.norm(w[:3])), float(np.linalg.norm(w[3:]))
        if f > safety.max_force_N * (1 + 1e-12):
            raise InputError(
                f"load case {case.name!r}: force {f:.1f} N exceeds safety.max_force_N = "
                f"{safety.max_force_N:g} N",
                where=protocol.where("load_cases", i, "name"),
            )
        if m > safety.max_moment_N_m * (1 + 1e-12):
            raise InputError(
                f"load case {case.name!r}: moment {m:.1f} N m exceeds safety.max_moment_N_m = "
                f"{safety.max_moment_N_m:g} N m",
                where=protocol.where("load_cases", i, "name"),
            )
