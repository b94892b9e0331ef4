"""Seeded Monte-Carlo of interval coverage, on the test-written 6R arm (5 poses x 3 loads)."""

from __future__ import annotations

import json
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from analysis.errors import InputError
from analysis.identification.estimate import identify
from analysis.identification.io.measurements import TestArrays
from analysis.identification.noise import NoiseModel
from analysis.kinetostatics.equilibrium import displacement_screw
from campaign.planning.candidates import evaluate, sample
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


@dataclass(frozen=True)
class Glitches:
    """Gross errors added to a campaign: each test, independently with probability
    ``fraction``, gets one; a share ``tracker`` of them (half by default, at random) on the
    tracker, one displacement
    component (drawn uniformly of the 6) off by ``size`` of its sigma (30 um / 40 urad), the
    others on the F/T sensor, one wrench component off by ``size`` of that component's
    sigma at the reading (0.5 N + 0.5 %, 0.05 N m + 0.5 %); the sign at random. Drawn from
    a generator of its own, so a glitched campaign is the clean one plus its glitches."""

    fraction: float = 0.1
    size: float = 20.0
    tracker: float = 0.5

    def add(self, rng, dm, wm, ww, noise):
        """(dm, wm) with the glitches added (copies); ``ww`` the true wrenches."""
        dm, wm = dm.copy(), wm.copy()
        m = dm.shape[0]
        hit = rng.random(m) < self.fraction
        tracker = rng.random(m) < self.tracker
        comp = rng.integers(0, 6, m)
        sign = np.where(rng.random(m) < 0.5, -1.0, 1.0)
        rows = np.arange(m)
        d_sig = np.broadcast_to(noise.displacement_sigma, dm.shape)
        w_sig = noise.wrench_sigma_at(ww)
        t, f = hit & tracker, hit & ~tracker
        dm[rows[t], comp[t]] += sign[t] * self.size * d_sig[rows[t], comp[t]]
        wm[rows[f], comp[f]] += sign[f] * self.size * w_sig[rows[f], comp[f]]
        return dm, wm


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


def coverage(robot, q, wrenches, k_true, method, scale, trials, seed, noise=NOISE,
             robust="none", glitches: Glitches | None = None, checkpoint: Path | None = None,
             every: int = 50):
    """(coverage (6,) over the results given, results given) of 95 % intervals of k.

    ``robust``: "none", "huber" or "tukey" (``identify(..., robust=)``); ``glitches``:
    gross errors added to every campaign (:class:`Glitches`), none by default.
    ``checkpoint``: a JSON file the counts and the generators' states are saved to every
    ``every`` campaigns and read back from, so that an interrupted cell resumes (and a
    cell of fewer campaigns extends) where it stopped with the same campaigns as one
    uninterrupted run; a file of another cell (method, scale, seed, robust, glitches) or
    of more campaigns than ``trials`` is not used.
    """
    qq = np.repeat(q, len(wrenches), axis=0)
    ww = np.tile(wrenches * scale, (len(q), 1))
    d = displacement_screw(robot, qq, k_true, ww)
    rng = np.random.default_rng(seed)
    glitch_rng = np.random.default_rng([seed, 1])
    hits = np.zeros(6)
    given = done = 0
    cell = {"method": method, "scale": float(scale), "seed": seed, "robust": robust,
            "glitches": None if glitches is None else repr(glitches)}
    if checkpoint is not None and Path(checkpoint).exists():
        saved = json.loads(Path(checkpoint).read_text())
        if saved["cell"] == cell and saved["done"] <= trials:
            done, given, hits = saved["done"], saved["given"], np.array(saved["hits"])
            rng.bit_generator.state = saved["rng"]
            glitch_rng.bit_generator.state = saved["glitch_rng"]

    def save():
        if checkpoint is not None:
            Path(checkpoint).write_text(json.dumps(
                {"cell": cell, "done": done, "given": given, "hits": hits.tolist(),
                 "rng": rng.bit_generator.state, "glitch_rng": glitch_rng.bit_generator.state}))

    labels = np.repeat([f"P{i}" for i in range(len(q))], len(wrenches))
    while done < trials:
        wm = ww + rng.normal(size=ww.shape) * noise.wrench_sigma_at(ww)
        dm = d + rng.normal(size=d.shape) * noise.displacement_sigma
        qm = qq + rng.normal(size=qq.shape) * noise.joint_sigma
        if glitches is not None:
            dm, wm = glitches.add(glitch_rng, dm, wm, ww, noise)
        done += 1
        tests = TestArrays(pose=labels, q=qm, w=wm, d=dm, measured=np.ones(d.shape, bool),
                           line=np.arange(len(qq)) + 2)
        try:
            res = identify(robot, tests, method=method, noise=noise, validate=False,
                           robust=robust)
        except InputError:
            res = None
        # refused by identify, or by the plausibility checks (campaign analyze)
        if res is not None and (res.linear_bias is None or res.linear_bias["reliable"]):
            ci = res.ci
            given += 1
            hits += (ci[:, 0] <= k_true) & (k_true <= ci[:, 1])
        if done % every == 0 or done == trials:
            save()
    return hits / max(given, 1), given
