"""``/api/sensitivity``: the sensitivity explorer over :mod:`campaign.jobs.sensitivity`.

The request is in the units the page's sliders show (um, urad, N, %, deg),
labelled in each field's name; it is converted to SI here and the job does the
rest. A robot file or a plan is a path inside the workspace.
"""

from __future__ import annotations

from typing import Annotated, Literal

import numpy as np
from fastapi import APIRouter, Request
from pydantic import BaseModel, ConfigDict, Field

from analysis.choices import DEFAULT_METHOD, METHODS
from analysis.errors import InputError

router = APIRouter(prefix="/api/sensitivity", tags=["sensitivity"])

#: most trials one request may ask for (a slider move must stay interactive)
API_MAX_TRIALS = 5000


#: a wrench component (N or N m) and a joint stiffness (N m/rad) within physical reach
WrenchValue = Annotated[float, Field(ge=-1e6, le=1e6)]
StiffnessValue = Annotated[float, Field(ge=1.0, le=1e12)]
AngleDeg = Annotated[float, Field(ge=-3600, le=3600)]


class SensitivityRequest(BaseModel):
    """Settings of the explorer (units in the field names; ``None``: the default)."""

    model_config = ConfigDict(extra="forbid", allow_inf_nan=False)

    robot: str = Field("kr240-2", max_length=200,
                       description="Built-in name, or a robot file (.toml/.yaml, e.g. an "
                       "identified model.toml) or a URDF with its tool frame "
                       "(robots/arm.urdf#tool0) inside the workspace (see /api/robots).")
    poses: Literal["zones", "plan", "typed"] = "zones"
    plan: str | None = Field(None, max_length=500,
                             description="Plan directory inside the workspace (poses=plan).")
    q_deg: list[Annotated[list[AngleDeg], Field(max_length=12)]] | None = Field(
        None, max_length=200,
                                            description="Typed poses, model convention (deg).")
    wrench_N_Nm: list[WrenchValue] | None = Field(None, min_length=6, max_length=6)
    joint_stiffness_Nm_per_rad: list[StiffnessValue] | None = Field(None, max_length=12)
    translation_sigma_um: float | None = Field(None, ge=0, le=10_000)
    rotation_sigma_urad: float | None = Field(None, ge=0, le=100_000)
    force_sigma_N: float | None = Field(None, ge=0, le=10_000)
    moment_sigma_Nm: float | None = Field(None, ge=0, le=10_000)
    force_percent: float | None = Field(None, ge=0, le=100)
    moment_percent: float | None = Field(None, ge=0, le=100)
    encoder_resolution_deg: float | None = Field(None, ge=0, le=1)
    reflector_radius_mm: float | None = Field(
        None, ge=10, le=2000, description="Reflector triangle circumradius (mm): the rotation "
        "sigma from the reflector fit, when rotation_sigma_urad is not given.")
    link_compliance_percent: float = Field(
        0.0, ge=0, le=50, description="Links 2 and 3 bend by this % of the tool point's "
        "deflection (median over the tests); 0: rigid links.")
    lost_motion_mrad: float = Field(
        0.0, ge=0, le=2, description="Full dead band of every gear (mrad), flanks decided "
        "by gravity (the robot file's masses); 0: none.")
    compensator_percent: float = Field(
        0.0, ge=0, le=30, description="Axis-2 gravity compensator whose stiffness reaches "
        "this % of k2 over the q2 range (gravity on); 0: none.")
    model: Literal["joints", "links", "compensator", "compensator+links"] = Field(
        "joints", description="Model class each trial is identified with (joints: the joint "
        "springs; links, compensator: the class's identifiable parameters as well).")
    n_tests: int = Field(10, ge=1, le=200)
    method: Literal[METHODS] = DEFAULT_METHOD  # robustness's and analyze's default
    trials: int = Field(1000, ge=2, le=API_MAX_TRIALS)
    seed: int = Field(0, ge=0, le=2**32 - 1)


class JointOut(BaseModel):
    joint: int
    k_true_Nm_per_rad: float
    median_Nm_per_rad: float | None
    q25_Nm_per_rad: float | None
    q75_Nm_per_rad: float | None
    predicted_se_Nm_per_rad: float | None
    std_Nm_per_rad: float | None
    rejected: int
    linear_bias_relative: float | None = None
    model_bias_relative: float | None = None


class SensitivityResponse(BaseModel):
    """Per joint spread of k over the trials, the first trial sets, the simulated tests."""

    robot: str
    method: str
    trials: int
    n_tests: int
    joints: list[JointOut]
    sets_Nm_per_rad: list[list[float | None]]
    q_deg: list[list[float]]
    wrench_N_Nm: list[list[float]]
    noise: dict
    curve_tests: list[int]
    curve_relative_se: list[list[float | None]]
    note: str = ""
    model: str = "joints"


class Defaults(BaseModel):
    """The noise model's default figures, in the request's units, and the built-in robots."""

    translation_sigma_um: float
    rotation_sigma_urad: float
    force_sigma_N: float
    moment_sigma_Nm: float
    force_percent: float
    moment_percent: float
    encoder_resolution_deg: float
    reflector_radius_mm: float
    link_compliance_percent: float = 0.0
    lost_motion_mrad: float = 0.0
    compensator_percent: float = 0.0
    robots: list[str]


def options_from_request(body: SensitivityRequest, workspace):
    """The job's options (SI) for ``body``; files resolved inside ``workspace``."""
    from analysis.model.robot_spec import is_robot_file
    from analysis.model.robots import builtin_files
    from campaign.jobs.sensitivity import ErrorSources, Realism, SensitivityOptions
    from campaign.web.robots_api import resolve_robot
    from campaign.web.security import inside_workspace

    def scaled(v, f):
        return None if v is None else v * f

    robot = body.robot.strip()
    if robot.lower() not in builtin_files():
        if not is_robot_file(robot):
            raise InputError("expected a built-in name, or a .toml/.yaml robot file or a URDF "
                             "with its tool frame (FILE.urdf#FRAME) in the workspace",
                             where="robot")
        robot = resolve_robot(workspace, robot, "robot")
    plan = None
    if body.poses == "plan":
        if not body.plan:
            raise InputError("poses 'plan' needs a plan directory", where="plan")
        plan = inside_workspace(workspace, body.plan, "plan")
    q = None
    if body.poses == "typed":
        if not body.q_deg or len({len(r) for r in body.q_deg}) != 1:
            raise InputError("typed poses need rows of the same length", where="q_deg")
        q = np.radians(np.array(body.q_deg, dtype=float))
    errors = ErrorSources(
        translation_sigma=scaled(body.translation_sigma_um, 1e-6),
        rotation_sigma=scaled(body.rotation_sigma_urad, 1e-6),
        force_sigma=body.force_sigma_N, moment_sigma=body.moment_sigma_Nm,
        force_relative=scaled(body.force_percent, 0.01),
        moment_relative=scaled(body.moment_percent, 0.01),
        encoder_resolution=scaled(body.encoder_resolution_deg, np.pi / 180),
        reflector_radius=scaled(body.reflector_radius_mm, 1e-3))
    return SensitivityOptions(
        robot=robot, poses=body.poses, plan_dir=plan, q=q,
        wrench=None if body.wrench_N_Nm is None else np.array(body.wrench_N_Nm),
        joint_stiffness=None if body.joint_stiffness_Nm_per_rad is None
        else np.array(body.joint_stiffness_Nm_per_rad),
        errors=errors, n_tests=body.n_tests, method=body.method, trials=body.trials,
        seed=body.seed, model=body.model,
        realism=Realism(link_fraction=body.link_compliance_percent / 100,
                        lost_motion=body.lost_motion_mrad * 1e-3,
                        compensator_fraction=body.compensator_percent / 100))


@router.post("", response_model=SensitivityResponse)
def sensitivity(body: SensitivityRequest, request: Request) -> dict:
    """Monte-Carlo spread of the identified k for these settings (Figs. 6 and 7)."""
    from campaign.jobs.sensitivity import run_sensitivity

    options = options_from_request(body, request.app.state.workspace)
    with request.app.state.compute_slots:
        return run_sensitivity(options).to_dict()


@router.get("/defaults", response_model=Defaults)
def defaults() -> Defaults:
    """Where the sliders start: the noise model's defaults."""
    from analysis.identification.noise import NoiseModel
    from analysis.model.robots import builtin_files

    n = NoiseModel()
    return Defaults(
        translation_sigma_um=n.translation_sigma * 1e6, rotation_sigma_urad=n.rotation_sigma * 1e6,
        force_sigma_N=n.force_sigma, moment_sigma_Nm=n.moment_sigma,
        force_percent=100 * n.force_relative, moment_percent=100 * n.moment_relative,
        encoder_resolution_deg=float(np.degrees(n.encoder_resolution)),
        reflector_radius_mm=1e3 * n.reflector_radius,
        robots=sorted({p.stem for p in builtin_files().values()}))
