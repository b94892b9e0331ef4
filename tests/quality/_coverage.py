"""Seeded Monte-Carlo of interval coverage, on the test-written 6R arm (5 poses x 3 loads)."""

from __future__ import annotations

import numpy as np

from analysis.errors import InputError
from analysis.identification.estimate import identify
from analysis.identification.measurements import TestArrays
from analysis.identification.noise import NoiseModel
from analysis.kinetostatics.equilibrium import displacement_screw
from campaign.candidates import evaluate, sample
from campaign.protocol import load_protocol
from campaign.protocol_robot import (
    characteristic_length,
    prior_stiffness,
    protocol_robot,
    sampling_boxes,
)

#: realistic instruments: 30 um and 40 urad per displacement component, F/T 0.5 % of reading
NOISE = NoiseModel(translation_sigma_override=30e-6, rotation_sigma_override=40e-6,
                   force_sigma=0.5, moment_sigma=0.05, force_relative=0.005,
                   moment_relative=0.005)


def campaign_setup(protocol_path, poses: int = 5, seed: int = 0):
    """(robot, q (poses, 6) rad, wrenches (3, 6), k_true (6,)) of the protocol's zones."""
    protocol = load_protocol(protocol_path)
    robot = protocol_robot(protocol)
    k = prior_stiffness(protocol, robot)
    q, zone = sample(sampling_boxes(protocol, robot), 400, seed)
    cand = evaluate(protocol, robot, q, zone, k, characteristic_length(protocol, robot))
    good = np.flatnonzero(np.all(cand.valid, axis=1))
    rng = np.random.default_rng(seed)
    pick = rng.choice(good, poses, replace=False)
    # the truth differs from the prior by up to 20 %
    k_true = k * rng.uniform(0.8, 1.2, k.size)
    return robot, cand.q[pick], protocol.wrenches(), k_true


def coverage(robot, q, wrenches, k_true, method, scale, trials, seed, noise=NOISE):
    """(coverage (6,) over the results given, results given) of 95 % intervals of k."""
    qq = np.repeat(q, len(wrenches), axis=0)
    ww = np.tile(wrenches * scale, (len(q), 1))
    d = displacement_screw(robot, qq, k_true, ww)
    rng = np.random.default_rng(seed)
    hits = np.zeros(6)
    given = 0
    labels = np.repeat([f"P{i}" for i in range(len(q))], len(wrenches))
    for _ in range(trials):
        wm = ww + rng.normal(size=ww.shape) * noise.wrench_sigma_at(ww)
        dm = d + rng.normal(size=d.shape) * noise.displacement_sigma
        qm = qq + rng.normal(size=qq.shape) * noise.joint_sigma
        tests = TestArrays(pose=labels, q=qm, w=wm, d=dm, measured=np.ones(d.shape, bool),
                           line=np.arange(len(qq)) + 2)
        try:
            res = identify(robot, tests, method=method, noise=noise, validate=False)
        except InputError:
            continue
        if res.linear_bias is not None and not res.linear_bias["reliable"]:
            continue  # refused by the plausibility checks (campaign analyze)
        ci = res.ci
        given += 1
        hits += (ci[:, 0] <= k_true) & (k_true <= ci[:, 1])
    return hits / max(given, 1), given
