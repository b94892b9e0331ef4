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
             noise: NoiseModel, seed: int) -> tuple[TestArrays, np.ndarray]:
    """(tests as measured, true displacements (m, 6)) of one seeded campaign."""
    rng = np.random.default_rng(seed)
    poses = sample_poses(robot, n_poses, rng, min_inverse_condition=0.3)
    q = np.repeat(poses, len(loads), axis=0)
    w = np.tile(loads, (n_poses, 1))
    d_true = displacement(robot, lab, k, q, np.zeros(6), w)
    d = d_true + rng.normal(size=d_true.shape) * noise.displacement_sigma
    wm = w + rng.normal(size=w.shape) * noise.wrench_sigma
    m = q.shape[0]
    tests = TestArrays(pose=np.array([f"P{i // len(loads) + 1}" for i in range(m)]), q=q,
                       w=wm, d=d, measured=np.ones((m, 6), bool), line=np.arange(m) + 2)
    return tests, d_true


def one_campaign(robot, lab: RealisticLab, k, loads, n_poses, noise, seed) -> Outcome:
    """Simulate, fit every class, choose, and score against the projected truth."""
    tests, d_true = simulate(robot, lab, k, loads, n_poses, noise, seed)
    res = identify(robot, tests, "exact", noise=noise, validate=False)
    taus = (gear_torques(robot, tests.q, np.zeros(6)), gear_torques(robot, tests.q, tests.w))
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
