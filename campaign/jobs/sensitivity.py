"""The sensitivity explorer's job (the paper's Figs. 6 and 7, live).

Given a robot, the poses of the tests, the wrench of each test and one
standard deviation per error source, it simulates ``trials`` noisy campaigns
and identifies each (the project's Monte-Carlo of a design,
:mod:`analysis.identification.studies.design_simulation`), then reports per joint
the spread of the identified k (median, quartiles, a few individual trial
sets: the paper's broken lines) beside the planner's predicted standard
error (:func:`campaign.planning.criteria.candidate_information`, the same noise model).

Poses: ``zones`` draws ``n_tests`` poses in the robot's zones (the paper's
Table 4 for the KR240-2) with 1/kappa_F >= 0.2, the first ``n_tests`` of a
seeded draw of :data:`ZONE_POOL`, so that moving the number of tests adds or
removes poses and keeps the others; ``plan`` and ``typed`` take the given
poses in order, cycling when ``n_tests`` exceeds them. SI throughout.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from analysis.choices import DEFAULT_METHOD, LINEARISED_METHODS, METHODS
from analysis.errors import InputError
from campaign.jobs.option_checks import six_joints

POSE_SOURCES = ("zones", "plan", "typed")
MAX_TESTS = 200
MAX_TRIALS = 20_000
ZONE_POOL = 200  # poses drawn once from the zones; the tests are its first n_tests
SETS_SHOWN = 5  # individual trial sets returned (the paper's broken lines)
CURVE_TESTS = 40  # the predicted spread is drawn for 1 .. max(this, n_tests) tests


@dataclass(frozen=True)
class ErrorSources:
    """One standard deviation per error source (SI; ``None``: the noise model's default).

    translation_sigma (m) and rotation_sigma (rad): one component of a measured
    displacement; force_sigma (N), moment_sigma (N m): one wrench component;
    force_relative, moment_relative: part proportional to the reading (0.01 = 1 %);
    encoder_resolution (rad): joint encoder resolution (sigma = resolution / sqrt 12).
    reflector_radius (m): circumradius of the three-reflector triangle the rotation is
    fitted from; used when rotation_sigma is None (the noise model's reflector fit).
    """

    translation_sigma: float | None = None
    rotation_sigma: float | None = None
    force_sigma: float | None = None
    moment_sigma: float | None = None
    force_relative: float | None = None
    moment_relative: float | None = None
    encoder_resolution: float | None = None
    reflector_radius: float | None = None

    def noise(self):
        """The :class:`NoiseModel` with these figures."""
        from analysis.identification.noise import NoiseModel

        return NoiseModel().with_overrides(
            translation_sigma_override=self.translation_sigma,
            rotation_sigma_override=self.rotation_sigma,
            force_sigma=self.force_sigma, moment_sigma=self.moment_sigma,
            force_relative=self.force_relative, moment_relative=self.moment_relative,
            encoder_resolution=self.encoder_resolution, reflector_radius=self.reflector_radius)


#: the compensator's attachment points (m) of the explorer's stress test, in joint 2's frame
#: at q2 = 0 and in link 2's frame: the shop protocol's (protocols/kr240-2-shop.toml)
COMPENSATOR_POINTS = ((0.24, 0.215, 0.0), (0.27, 0.26, 0.0))


@dataclass(frozen=True)
class Realism:
    """What the simulated robot has beyond joint springs (each 0: off, today's numbers).

    link_fraction: links 2 and 3 bend (square steel boxes, one common scale) by this
    fraction of P's deflection, median over the tests (0.1 = 10 %); lost_motion (rad): the
    full dead band of every gear, flanks decided by gravity (needs the robot's mass model);
    compensator_fraction: an axis-2 spring (:data:`COMPENSATOR_POINTS`, rate and preload in
    the shop protocol's ratio) scaled so that its stiffness -dtau_c/dq2 reaches this
    fraction of k2 over the q2 range, gravity loading the arm (needs the mass model). The
    campaigns' displacements gain each effect's deterministic part: the realistic
    displacement minus that of the same arm without the effects."""

    link_fraction: float = 0.0
    lost_motion: float = 0.0
    compensator_fraction: float = 0.0

    @property
    def active(self) -> bool:
        return bool(self.link_fraction or self.lost_motion or self.compensator_fraction)


def realism_bias(robot, q: np.ndarray, w: np.ndarray, k: np.ndarray,
                 realism: Realism) -> np.ndarray:
    """(t, 6) what ``realism`` adds to the tests' displacements (m, rad) at q (t, n), w (t, 6)."""
    from analysis.kinetostatics import realistic as R

    gravity = "on" if realism.compensator_fraction else (
        "flanks" if realism.lost_motion else "off")
    if gravity != "off" and robot.inertials is None:
        raise InputError(f"{robot.name} has no mass model (link masses in its robot file): "
                         "lost motion and the compensator need gravity's torques",
                         where="lost_motion_mrad" if realism.lost_motion
                         else "compensator_percent")
    base = R.RealisticLab(gravity=gravity)
    links: tuple = ()
    if realism.link_fraction:
        I, J, A = R.box_section(0.22, 0.008)
        unit = tuple(R.LinkCompliance(link, R.link_beam_compliance(robot, link, 2.1e11,
                                                                   8.1e10, I, J, A))
                     for link in (2, 3))
        tw = R.link_twist(robot, R.RealisticLab(links=unit), q, w)
        joints = R.displacement(robot, R.RealisticLab(), k, q, np.zeros(6), w)
        ratio = np.median(np.linalg.norm(tw[:, :3], axis=1)
                          / np.linalg.norm(joints[:, :3], axis=1))
        scale = realism.link_fraction / ratio
        links = tuple(R.LinkCompliance(c.link, c.matrix * scale) for c in unit)
    comp = None
    if realism.compensator_fraction:
        shape = R.compensator_for(robot, 1, *COMPENSATOR_POINTS, 43000.0, 2100.0)
        q2 = np.linspace(robot.lower[1], robot.upper[1], 721)
        peak = np.max(np.abs(R.compensator_torque(shape, q2)[1]))
        s = realism.compensator_fraction * k[1] / peak
        comp = R.compensator_for(robot, 1, *COMPENSATOR_POINTS, 43000.0 * s, 2100.0 * s)
    lab = R.RealisticLab(links=links, compensator=comp, gravity=gravity,
                         lost_motion=np.full(robot.n, realism.lost_motion)
                         if realism.lost_motion else None)
    return (R.displacement(robot, lab, k, q, np.zeros(6), w)
            - R.displacement(robot, base, k, q, np.zeros(6), w))


@dataclass(frozen=True)
class SensitivityOptions:
    """What the explorer simulates.

    robot : built-in name or a robot file path (the web face resolves it in the workspace).
    poses : ``zones``, ``plan`` (``plan_dir``) or ``typed`` (``q`` (t, n) rad, model convention).
    wrench : (6,) N, N m at P, base frame, every test; None: the plan's per test, else the
        paper's w_eff. joint_stiffness : (n,) true k (N m/rad); None: the model's nominal.
    """

    robot: str = "kr240-2"
    poses: str = "zones"
    plan_dir: Path | None = None
    q: np.ndarray | None = None
    wrench: np.ndarray | None = None
    joint_stiffness: np.ndarray | None = None
    errors: ErrorSources = field(default_factory=ErrorSources)
    n_tests: int = 10
    method: str = DEFAULT_METHOD
    trials: int = 1000
    seed: int = 0
    realism: Realism = field(default_factory=Realism)
    #: the model class each trial is identified with (``joints``: the joint springs, today's)
    model: str = "joints"


@dataclass(frozen=True)
class JointSpread:
    """One joint's identified k over the trials (N m/rad)."""

    joint: int
    k_true: float
    median: float
    q25: float
    q75: float
    predicted_se: float  # the planner's prediction (inf: not identifiable)
    std: float  # sample std over the accepted trials
    rejected: int  # trials with a compliance <= 0 or not finite; all when not identifiable
    #: ols/wls: k of the linearised fit of noise-free tests / k_true - 1, the linearisation
    #: bias corrected in every trial (as ``campaign analyze`` does); 0 for exact
    linear_bias: float = 0.0
    #: with realism: k of the noise-free realistic tests identified as the trials are (the
    #: model class, the linearisation correction) / k_true - 1: what the model leaves in k
    #: of the simulated effects (NaN without realism)
    model_bias: float = float("nan")


@dataclass(frozen=True)
class SensitivityResult:
    """Per joint spreads, the first trial sets (sets[s][j], N m/rad, NaN if rejected), the
    poses (q (n_tests, n) rad) and wrenches (n_tests, 6) simulated, the noise figures, and
    the planner's relative standard error of each k against the number of tests
    (curve_se[i, j] for curve_tests[i] tests, inf where not identifiable: Fig. 7)."""

    robot: str
    method: str
    trials: int
    n_tests: int
    joints: list[JointSpread]
    sets: list[list[float]]
    q: np.ndarray
    wrench: np.ndarray
    noise: dict
    curve_tests: np.ndarray
    curve_se: np.ndarray
    #: a sentence on the linearisation-bias correction applied (ols/wls), else ""
    note: str = ""
    #: the model class the trials were identified with
    model: str = "joints"

    def to_dict(self) -> dict:
        """JSON-ready (SI; NaN and inf as None)."""
        def num(v):
            return float(v) if np.isfinite(v) else None

        return {
            "robot": self.robot, "method": self.method, "trials": self.trials,
            "n_tests": self.n_tests,
            "joints": [{"joint": j.joint, "k_true_Nm_per_rad": j.k_true,
                        "median_Nm_per_rad": num(j.median), "q25_Nm_per_rad": num(j.q25),
                        "q75_Nm_per_rad": num(j.q75),
                        "predicted_se_Nm_per_rad": num(j.predicted_se),
                        "std_Nm_per_rad": num(j.std), "rejected": j.rejected,
                        "linear_bias_relative": num(j.linear_bias),
                        "model_bias_relative": num(j.model_bias)}
                       for j in self.joints],
            "sets_Nm_per_rad": [[num(v) for v in s] for s in self.sets],
            "q_deg": np.degrees(self.q).round(6).tolist(),
            "wrench_N_Nm": self.wrench.tolist(),
            "noise": self.noise,
            "curve_tests": self.curve_tests.tolist(),
            "curve_relative_se": [[num(v) for v in row] for row in self.curve_se],
            "note": self.note,
            "model": self.model,
        }


def _check(o: SensitivityOptions) -> None:
    if o.method not in METHODS:
        raise InputError(f"expected one of {', '.join(METHODS)}, got {o.method!r}",
                         where="method")
    if o.poses not in POSE_SOURCES:
        raise InputError(f"expected one of {', '.join(POSE_SOURCES)}, got {o.poses!r}",
                         where="poses")
    if not 1 <= o.n_tests <= MAX_TESTS:
        raise InputError(f"must be 1 to {MAX_TESTS}, got {o.n_tests}", where="n_tests")
    if not 2 <= o.trials <= MAX_TRIALS:
        raise InputError(f"must be 2 to {MAX_TRIALS}, got {o.trials}", where="trials")
    r = o.realism
    for name, value, hi in (("link_fraction", r.link_fraction, 1.0),
                            ("lost_motion", r.lost_motion, 0.01),
                            ("compensator_fraction", r.compensator_fraction, 1.0)):
        if not (np.isfinite(value) and 0 <= value <= hi):
            raise InputError(f"must be 0 to {hi:g}, got {value!r}", where=name)
    _class_spec(o.model)


def _class_spec(model: str):
    """The :class:`~campaign.planning.model_class.ClassSpec` of ``model`` (None: joints);
    the explorer identifies the classes whose parameters are linear columns."""
    from analysis.identification.models.names import parse_model
    from campaign.planning.model_class import PLANNED, ClassSpec

    choice = parse_model(model)
    bad = [e for e in choice.extras if e not in PLANNED]
    if choice.auto or bad:
        raise InputError(f"the explorer identifies with joints, {', '.join(PLANNED)} "
                         f"(combined with '+'), not {'auto' if choice.auto else bad[0]}",
                         where="model")
    return ClassSpec(choice.extras) if choice.extras else None


def class_kept(robot, q: np.ndarray, w: np.ndarray, noise, k: np.ndarray, spec) -> tuple:
    """Names of the class's parameters the fit's rule keeps at the tests (q (t, n) rad,
    w (t, 6)), whitened at the true k without the encoder term: decided once, for the
    trials and the prediction alike (near-dependent link entries are kept or fixed by
    rounding-level differences, which move k's gauge)."""
    from analysis.model.kinematics import jacobian
    from campaign.planning import model_class as mc

    n = len(k)
    q2ref = float(np.mean(q[:, mc.COMP_JOINT]))
    W, names = mc.whitened(robot, jacobian(robot, q), q, w, noise, k, spec, q2ref)
    kept, _ = mc.reduce_by_class(W[..., :n].reshape(-1, n), W[..., n:].reshape(
        -1, W.shape[-1] - n), names)
    return tuple(names[i][0] for i in kept)


def class_trials(robot, sim, noise, k: np.ndarray, spec, method: str,
                 keep: tuple) -> np.ndarray:
    """Compliances (T, n) (rad/(N m)) of the simulated campaigns ``sim`` identified with the
    class ``spec``: the linear model plus the class's columns
    (:func:`campaign.planning.model_class.extra_columns`, at the true angles and the
    measured wrenches), the extras ``keep`` (:func:`class_kept`); rows whitened
    by their residual covariance at 1/k (``ols``: unweighted); one least-squares solve
    per trial, columns scaled to unit norm (their units span 1e12)."""
    from analysis.identification.estimators.linear_model import design_block
    from analysis.model.kinematics import jacobian
    from campaign.planning import model_class as mc

    T, m, n = sim.q.shape
    q2ref = float(np.mean(sim.q_true[:, mc.COMP_JOINT]))
    J0 = jacobian(robot, sim.q_true)
    names = mc.extra_columns(robot, J0[:1], sim.q_true[:1], sim.w_true[:1], spec, q2ref)[1]
    kept = [i for i, nm in enumerate(names) if nm[0] in set(keep)]
    Linv = (np.linalg.inv(mc.noise_factor(J0, sim.w_true, noise, k)) if method != "ols"
            else np.broadcast_to(np.eye(6), (m, 6, 6)))
    x = np.empty((T, n))
    for t in range(T):
        E = mc.extra_columns(robot, sim.J[t], sim.q_true, sim.w[t], spec, q2ref)[0]
        M = np.concatenate([design_block(sim.J[t], sim.w[t]), E[..., kept]], axis=-1)
        WM = (Linv @ M).reshape(6 * m, -1)
        Wd = np.einsum("mij,mj->mi", Linv, sim.d[t]).reshape(-1)
        norm = np.linalg.norm(WM, axis=0)
        norm = np.where(norm > 0, norm, 1.0)
        x[t] = (np.linalg.lstsq(WM / norm, Wd, rcond=None)[0] / norm)[:n]
    return x


def class_predicted_se(robot, q: np.ndarray, w: np.ndarray, k: np.ndarray, noise,
                       spec, keep: tuple) -> np.ndarray:
    """(n,) the planner's standard error of k (N m/rad) of the class fit of the tests (q
    (t, n) rad, w (t, 6)): marginal over the class's parameters ``keep``, encoders
    included."""
    from types import SimpleNamespace

    from analysis.model.kinematics import jacobian
    from campaign.planning.model_class import predict

    tests = SimpleNamespace(q=q, J=jacobian(robot, q))
    idx = np.arange(len(q))
    return predict(robot, tests, idx, idx, w, noise, k, 1, spec, keep=keep).k_se


def _poses(o: SensitivityOptions, robot, count: int) -> tuple[np.ndarray, np.ndarray | None]:
    """(q (count, n) rad, the plan's wrenches (count, 6) or None): the tests in order."""
    if o.poses == "zones":
        from analysis.identification.studies.robustness import sample_poses

        q = sample_poses(robot, max(ZONE_POOL, count), np.random.default_rng(o.seed))
        return q[:count], None
    if o.poses == "plan":
        if o.plan_dir is None:
            raise InputError("poses 'plan' needs a plan directory", where="plan")
        from campaign.planning.plan_output import read_plan

        _, df = read_plan(o.plan_dir)
        q = np.radians(df[[f"q{j}_model_deg" for j in range(1, robot.n + 1)]].to_numpy(float))
        w = df[["fx_N", "fy_N", "fz_N", "mx_N_m", "my_N_m", "mz_N_m"]].to_numpy(float)
        idx = np.arange(count) % len(q)
        return q[idx], w[idx]
    q = None if o.q is None else np.asarray(o.q, dtype=float)
    if q is None or q.ndim != 2 or q.shape[0] < 1 or q.shape[1] != robot.n \
            or not np.all(np.isfinite(q)):
        raise InputError(f"typed poses need rows of {robot.n} finite joint angles", where="q")
    out = (q < robot.lower - 1e-9) | (q > robot.upper + 1e-9)
    if out.any():
        i, j = (int(v) for v in np.argwhere(out)[0])
        raise InputError(
            f"pose {i + 1}: q{j + 1} = {np.degrees(q[i, j]):.6g} deg is outside the joint "
            f"limits [{np.degrees(robot.lower[j]):.6g}, {np.degrees(robot.upper[j]):.6g}] deg",
            where="q")
    return q[np.arange(count) % len(q)], None


def predicted_relative_se(robot, q, w, k, noise) -> np.ndarray:
    """(t, n): the planner's relative standard error of each k for the first 1, 2, ..., t
    of the tests (q (t, n) rad, w (t, 6) N, N m), one row each; inf where not identified."""
    from analysis.identification.studies.robustness import jacobian_derivative
    from analysis.model.kinematics import jacobian
    from campaign.planning.criteria import candidate_information, relative_se

    F = candidate_information(jacobian(robot, q), w, noise, k, 1, jacobian_derivative(robot, q))
    return relative_se(np.cumsum(F, axis=0))


def run_sensitivity(o: SensitivityOptions, robot=None) -> SensitivityResult:
    """Simulate and identify ``o.trials`` campaigns; ``robot`` (a loaded model) skips loading."""
    from analysis.identification.studies.design_simulation import (
        identify_campaigns,
        noise_free_campaign,
        simulate_campaigns,
    )
    from analysis.identification.studies.robustness import W_EFF

    _check(o)
    if robot is None:
        from analysis.model.robots import load_robot

        robot = load_robot(o.robot, where="robot")
    # the simulated campaigns are six-component tests of a six-joint arm
    six_joints(robot, where="robot")
    if o.joint_stiffness is not None:
        k = np.asarray(o.joint_stiffness, dtype=float)
        if k.shape != (robot.n,) or not np.all(np.isfinite(k)) or np.any(k <= 0):
            raise InputError(f"expected {robot.n} positive values (N m/rad)",
                             where="joint_stiffness")
    elif robot.nominal_stiffness is None:
        raise InputError(f"{robot.name} has no published joint stiffness: give it",
                         where="joint_stiffness")
    else:
        k = np.asarray(robot.nominal_stiffness, dtype=float)
    noise = o.errors.noise()
    count = max(CURVE_TESTS, o.n_tests)
    q, plan_w = _poses(o, robot, count)
    if o.wrench is not None:
        w = np.asarray(o.wrench, dtype=float)
        if w.shape != (6,) or not np.all(np.isfinite(w)) or not np.any(w):
            raise InputError("expected 6 finite numbers, not all zero (N, N m)", where="wrench")
        w = np.broadcast_to(w, (len(q), 6)).copy()
    else:
        w = plan_w if plan_w is not None else np.broadcast_to(W_EFF, (len(q), 6)).copy()
    curve = predicted_relative_se(robot, q, w, k, noise)
    q, w = q[:o.n_tests], w[:o.n_tests]
    rng = np.random.default_rng(o.seed + 1)
    sim = simulate_campaigns(robot, q, w, k, noise, 1, o.trials, rng)
    real = noise_free_campaign(robot, q, w, k) if o.realism.active else None
    if real is not None:  # the robot is not joint springs: every campaign sees it
        bias_d = realism_bias(robot, q, w, k, o.realism)
        sim.d[...] += bias_d[None]
        real.d[...] += bias_d[None]
    spec = _class_spec(o.model)
    if spec is not None:  # the class: its linear fit, the linearisation bias corrected
        keep = class_kept(robot, q, w, noise, k, spec)
        with np.errstate(all="ignore"):
            x = class_trials(robot, sim, noise, k, spec, o.method, keep)
            bias = class_trials(robot, noise_free_campaign(robot, q, w, k), noise, k, spec,
                                o.method, keep)[0] - 1.0 / k
            x = x - bias[None, :]
            k_bias = 1.0 / (1.0 / k + bias) / k - 1.0
            model_bias = (None if real is None else 1.0 / (
                class_trials(robot, real, noise, k, spec, o.method, keep)[0] - bias) / k - 1.0)
        return _result(o, robot, k, q, w, noise, count, curve, x, k_bias,
                       class_predicted_se(robot, q, w, k, noise, spec, keep), spec.name,
                       model_bias)
    with np.errstate(all="ignore"):
        try:
            x = identify_campaigns(robot, sim, noise, 1.0 / k, o.method)  # (T, n)
        except np.linalg.LinAlgError:  # wls/exact whiten by the rows' noise covariance
            raise InputError(f"{o.method} weights each test by the inverse of its noise "
                             "covariance, which is singular at these settings (zero noise "
                             "on every source of a measured component); give a nonzero "
                             "tracker or F/T noise, or use ols", where="method") from None
        k_bias = np.zeros(robot.n)  # the uncorrected fit's relative bias of k
        if o.method in LINEARISED_METHODS:
            # Analyze's correction, to first order: every trial less the bias of the
            # linearised fit at the true compliances (the noise-free tests' estimate - 1/k)
            bias = identify_campaigns(robot, noise_free_campaign(robot, q, w, k), noise,
                                      1.0 / k, o.method)[0] - 1.0 / k
            x = x - bias[None, :]
            k_bias = 1.0 / (1.0 / k + bias) / k - 1.0
        else:
            bias = np.zeros(robot.n)
        model_bias = None if real is None else 1.0 / (identify_campaigns(
            robot, real, noise, 1.0 / k, o.method)[0] - bias) / k - 1.0
    return _result(o, robot, k, q, w, noise, count, curve, x, k_bias,
                   curve[o.n_tests - 1] * k, "joints", model_bias)


def _result(o: SensitivityOptions, robot, k, q, w, noise, count, curve, x, k_bias, se,
            model: str, model_bias: np.ndarray | None = None) -> SensitivityResult:
    """The spreads of the trials' compliances x (T, n), the predicted se (n,) N m/rad;
    ``model_bias`` (n,) relative, with realism (:attr:`JointSpread.model_bias`)."""
    with np.errstate(all="ignore"):
        ok = np.isfinite(x) & (x > 0)
    # a joint these tests do not identify (singular information: equal poses, a singular
    # pose): the least-squares k of each trial is an arbitrary number, never shown as one
    ok &= np.isfinite(se)[None, :]
    kk = np.where(ok, 1.0 / np.where(ok, x, 1.0), np.nan)
    joints = []
    for j in range(robot.n):
        v = kk[ok[:, j], j]
        q25, q50, q75 = np.percentile(v, [25, 50, 75]) if len(v) else (np.nan,) * 3
        joints.append(JointSpread(
            joint=j + 1, k_true=float(k[j]), median=float(q50), q25=float(q25),
            q75=float(q75), predicted_se=float(se[j]),
            std=float(np.std(v, ddof=1)) if len(v) > 1 else float("nan"),
            rejected=int((~ok[:, j]).sum()),
            linear_bias=float(k_bias[j]) if np.isfinite(se[j]) else float("nan"),
            model_bias=float("nan") if model_bias is None or not np.isfinite(se[j])
            else float(model_bias[j])))
    return SensitivityResult(
        robot=robot.name, method=o.method, trials=o.trials, n_tests=o.n_tests, joints=joints,
        sets=kk[:SETS_SHOWN].tolist(), q=q, wrench=w, noise=noise.describe(),
        curve_tests=np.arange(1, count + 1), curve_se=curve,
        note=_bias_note(o.method, k_bias, np.isfinite(se)) if model == "joints" else
        _class_note(model, k_bias, np.isfinite(se)), model=model)


def _class_note(model: str, k_bias: np.ndarray, identified: np.ndarray) -> str:
    """The sentence the page shows under the table of a model class."""
    shown = [f"k{j + 1} {100 * b:+.2f} %" for j, b in enumerate(k_bias) if identified[j]]
    return (f"identified with the model class {model}: the linear model plus its parameters "
            "(the identifiable ones at these tests), every trial corrected for its "
            f"linearisation bias ({', '.join(shown) or 'nothing identified'}); the predicted "
            "se is marginal over the class's parameters (the curve stays the joint springs').")


def _bias_note(method: str, k_bias: np.ndarray, identified: np.ndarray) -> str:
    """The sentence the page shows under the table of a linearised method."""
    if method not in LINEARISED_METHODS:
        return ""
    shown = [f"k{j + 1} {100 * b:+.2f} %" for j, b in enumerate(k_bias) if identified[j]]
    return (f"{method} fits the linearised model: every trial is corrected for its "
            "linearisation bias at these tests, as Analyze corrects it; uncorrected, the "
            f"median would be off by {', '.join(shown) or 'nothing identified'}.")
