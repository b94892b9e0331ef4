"""Study of the model classes on a simulated realistic arm (issue 32).

Each seeded campaign: poses sampled in the robot's zones (1/kappa_F >= 0.3), every pose
with every load case of a protocol; the true displacement from the realistic-arm physics
(:func:`analysis.kinetostatics.realistic.displacement`, no simulated instrument: the
pure physics the fakes speak for), instrument noise as declared; the joint-only exact
fit, then ``--model auto`` (:func:`~analysis.identification.models.select.select_model`).

The truth of a class's parameters is its projection of the true arm: the same class,
with the parameterisation of the noisy fit (the same parameters kept, the same joint-2
flank pattern), fitted to the noise-free true displacements of the same tests (the
joint compliances then include the link bending the tests cannot tell from them, see
:mod:`analysis.identification.models.fit`). Coverage counts the 95 % intervals of the
chosen class's joint stiffness and extra parameters that contain that projection.
"""

from __future__ import annotations

from dataclasses import dataclass, replace
from pathlib import Path

import numpy as np

from analysis.identification.estimate import identify
from analysis.identification.io.measurements import TestArrays
from analysis.identification.models.fit import Z95, fit_class, prepare
from analysis.identification.models.names import ModelChoice
from analysis.identification.models.select import select_model
from analysis.identification.noise import NoiseModel
from analysis.identification.poses import pose_groups
from analysis.identification.studies.robustness import sample_poses
from analysis.kinetostatics.realistic import RealisticLab, displacement
from analysis.model.gravity import gear_torques

#: held-out pose radius (rad): the planner's default minimum pose separation (5 deg)
HOLDOUT_RADIUS = np.radians(5.0)


@dataclass(frozen=True)
class Outcome:
    """One campaign: the class chosen and the true one, acceptance, the counts of 95 %
    intervals that contain the projected truth (covered of total), the held-out chi2/nu of
    the chosen class and its k relative error to the lab's k (6,)."""

    chosen: str
    true_class: str
    accepted: bool
    covered: int
    total: int
    heldout_chi2_nu: float
    k_error: np.ndarray


@dataclass(frozen=True)
class Design:
    """A fixed test design, the same for every seed: m test rows (a planned test's repeats
    are rows of their own, each with its own noise, as a campaign run measures them).

    Attributes: pose (m,) labels; q (m, n) commanded joint angles (rad, model convention);
    w (m, 6) loaded reading's wrench [N; N m] at P, base frame; w_ref (m, 6) reference
    reading's wrench (the load case's preload; zeros without one); label, what the table
    says of it."""

    pose: np.ndarray
    q: np.ndarray
    w: np.ndarray
    w_ref: np.ndarray
    label: str


def plan_design(directory: Path | str) -> Design:
    """The design of a plan directory written by ``campaign plan``: each plan.csv test at
    its model-convention angles, with its load case's wrench and reference (preload)
    wrench from the plan's protocol copy (as the planner takes them), ``repeats`` rows."""
    from campaign.planning.plan_output import read_plan

    prot, df = read_plan(directory)
    names = [c.name for c in prot.load_cases]
    case = np.array([names.index(str(c)) for c in df["load_case"]])
    w = np.asarray(prot.wrenches(), float)[case]
    # plan.csv's wrench columns are the same load cases, to its 3 decimals
    cols = ["fx_N", "fy_N", "fz_N", "mx_N_m", "my_N_m", "mz_N_m"]
    if not np.allclose(df[cols].to_numpy(float), w, atol=1e-3):
        raise ValueError(f"{directory}: plan.csv's wrenches are not its load cases'")
    q = np.radians(df[[f"q{j}_model_deg" for j in range(1, 7)]].to_numpy(float))
    reps = df["repeats"].to_numpy(int)
    rows = np.repeat(np.arange(len(df)), reps)
    label = (f"planner's design ({len(df)} tests x {reps.max()} repeats"
             if np.all(reps == reps[0]) else f"planner's design ({len(df)} tests, "
             f"{reps.sum()} rows") + ")"
    return Design(pose=np.array([f"P{p}" for p in df["pose"]])[rows], q=q[rows], w=w[rows],
                  w_ref=np.asarray(prot.reference_wrenches(), float)[case][rows],
                  label=label)


def true_class(lab: RealisticLab) -> str:
    """The class name of the effects a lab has (``joints`` for none)."""
    from analysis.identification.models.names import class_name

    extras = []
    if lab.gravity == "on":
        extras.append("gravity")
    if lab.links:
        extras.append("links")
    if lab.compensator is not None:
        extras.append("compensator")
    if lab.lost_motion is not None and np.any(lab.lost_motion):
        extras.append("lost-motion")
    return class_name(tuple(extras))


def simulate(robot, lab: RealisticLab, k: np.ndarray, loads: np.ndarray, n_poses: int,
             noise: NoiseModel, seed: int,
             design: Design | None = None) -> tuple[TestArrays, np.ndarray]:
    """(tests as measured, true displacements (m, 6)) of one seeded campaign: n_poses
    sampled zone poses x every row of ``loads``, or, given a ``design``, its tests (the
    seed then draws the noise only; ``loads`` and ``n_poses`` are not used)."""
    rng = np.random.default_rng(seed)
    if design is None:
        poses = sample_poses(robot, n_poses, rng, min_inverse_condition=0.3)
        q = np.repeat(poses, len(loads), axis=0)
        w = np.tile(loads, (n_poses, 1))
        w_ref = np.zeros(6)
        label = np.array([f"P{i // len(loads) + 1}" for i in range(q.shape[0])])
    else:
        q, w, w_ref, label = design.q, design.w, design.w_ref, design.pose
    d_true = displacement(robot, lab, k, q, w_ref, w)
    d = d_true + rng.normal(size=d_true.shape) * noise.displacement_sigma
    # the measured wrench: the loaded minus the reference reading (TestArrays.w)
    wm = w - w_ref + rng.normal(size=w.shape) * noise.wrench_sigma
    m = q.shape[0]
    preload = design is not None and bool(np.any(design.w_ref))
    tests = TestArrays(pose=label, q=q, w=wm, d=d, measured=np.ones((m, 6), bool),
                       line=np.arange(m) + 2,
                       w_ref=np.array(design.w_ref, float) if preload else None)
    return tests, d_true


def one_campaign(robot, lab: RealisticLab, k, loads, n_poses, noise, seed,
                 design: Design | None = None) -> Outcome:
    """Simulate (sampled poses, or the fixed ``design``), fit every class, choose, and
    score against the projected truth."""
    tests, d_true = simulate(robot, lab, k, loads, n_poses, noise, seed, design)
    res = identify(robot, tests, "exact", noise=noise, validate=False)
    w_ref = np.zeros(6) if tests.w_ref is None else tests.w_ref
    taus = (gear_torques(robot, tests.q, w_ref), gear_torques(robot, tests.q, tests.w + w_ref))
    group = pose_groups(tests.q, HOLDOUT_RADIUS)
    data = prepare(robot, tests, res.joints, res.x, noise, "exact", taus, group,
                   compensator=lab.compensator)
    sel = select_model(data, ModelChoice(auto=True))
    c = sel.chosen
    # the truth projected on the chosen class: the class fitted to the true displacements
    clean = replace(data, tests=replace(tests, d=d_true))
    ref = fit_class(clean, c.extras, like=c)
    covered = total = 0
    if not c.error and not ref.error:
        cols = list(res.joints)
        lo, hi = c.k_ci[cols, 0], c.k_ci[cols, 1]
        kt = ref.k[cols]
        covered += int(np.sum((kt >= lo) & (kt <= hi)))
        total += len(cols)
        # the parameters both fits kept (the lost-motion joints and the link entries kept
        # can differ when the spring's start moves joint 2's flanks)
        truth = dict(zip(ref.names, ref.values, strict=True))
        for n, v, s in zip(c.names, c.values, c.se, strict=True):
            if n in truth:
                covered += int(abs(v - truth[n]) <= Z95 * s)
                total += 1
    return Outcome(c.name, true_class(lab), sel.accepted, covered, total,
                   c.heldout_chi2_nu, c.k / np.asarray(k, float) - 1.0)


def shop_lab(protocol_path: Path | str | None = None):
    """(robot, lab, k, loads, noise) of the shipped shop protocol (kr240-2-shop.toml):
    every effect of its [fake_lab] but the instruments' drifts."""
    from analysis.kinetostatics.realistic_lab import realistic_lab
    from campaign.protocol import load_protocol
    from campaign.protocol_robot import protocol_robot
    from campaign.run_noise import noise_from_protocol

    if protocol_path is None:
        protocol_path = Path(__file__).resolve().parents[3] / "campaign" / "protocols" / \
            "kr240-2-shop.toml"
    prot = load_protocol(Path(protocol_path))
    robot = protocol_robot(prot)
    lab = realistic_lab(robot, prot.fake_lab.effects())
    k = np.asarray(prot.fake_lab.true_joint_stiffness, float)
    loads = np.asarray(prot.wrenches(), float)[:3]
    return robot, lab, k, loads, noise_from_protocol(prot)
