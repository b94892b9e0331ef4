"""A :class:`~analysis.kinetostatics.realistic.RealisticLab` from plain SI settings (the
simulated lab's ``[fake_lab]`` effects, :meth:`campaign.protocol.FakeLabSpec.effects`).

``realistic_lab(robot, effects)`` with ``effects`` a mapping of: ``gravity`` ("off",
"flanks", "on"), ``lost_motion`` ((n,) rad, full band 2b), ``links`` (mappings with
``link`` 1..n and ``compliance`` 6 x 6 SI or ``beam`` {E_Pa, G_Pa, width_m and wall_m or
I_m4, J_m4 and A_m2, optional length_m}), ``compensator`` {joint (1-based), base_point,
arm_point (m), rate (N/m), preload (N)}. Missing keys: the effect is off. Other keys (the
instruments' drifts) are ignored here.
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

import numpy as np

from analysis.errors import InputError
from analysis.kinetostatics.realistic import (
    LinkCompliance,
    RealisticLab,
    box_section,
    compensator_for,
    link_beam_compliance,
)
from analysis.model.gravity import inertials_of
from analysis.model.robot_model import RobotModel


def _link(robot: RobotModel, spec: Mapping[str, Any]) -> LinkCompliance:
    link = int(spec["link"])
    if not 1 <= link <= robot.n:
        raise InputError(f"link {link}: {robot.name} has links 1..{robot.n}",
                         where="fake_lab.links")
    if spec.get("compliance") is not None:
        return LinkCompliance(link, np.array(spec["compliance"], dtype=float))
    beam = spec["beam"]
    if beam.get("width_m") is not None:
        I, J, A = box_section(beam["width_m"], beam["wall_m"])
    else:
        I, J, A = beam["I_m4"], beam["J_m4"], beam["A_m2"]
    try:
        C = link_beam_compliance(robot, link, beam["E_Pa"], beam["G_Pa"], I, J, A,
                                 beam.get("length_m"))
    except ValueError as err:
        raise InputError(str(err), where="fake_lab.links") from None
    return LinkCompliance(link, C)


def realistic_lab(robot: RobotModel, effects: Mapping[str, Any]) -> RealisticLab:
    """The effects of ``effects`` (module docstring) on ``robot``; gravity and lost motion
    need the robot's mass model (a one-line error otherwise)."""
    gravity = str(effects.get("gravity", "off"))
    lost = effects.get("lost_motion")
    if lost is not None:
        lost = np.array(lost, dtype=float)
        if lost.shape != (robot.n,):
            raise InputError(f"lost motion: {robot.n} values expected, got {lost.size}",
                             where="fake_lab.lost_motion_rad")
        if gravity == "off" and np.any(lost):
            gravity = "flanks"  # the flanks need gravity's torque; the springs do not
    if gravity != "off":
        inertials_of(robot)
    comp = effects.get("compensator")
    compensator = None
    if comp is not None:
        j = int(comp["joint"]) - 1
        if not 0 <= j < robot.n:
            raise InputError(f"compensator joint {j + 1}: {robot.name} has joints "
                             f"1..{robot.n}", where="fake_lab.compensator")
        compensator = compensator_for(robot, j, comp["base_point"], comp["arm_point"],
                                      comp["rate"], comp["preload"])
    links = tuple(_link(robot, spec) for spec in effects.get("links", ()))
    return RealisticLab(links=links, lost_motion=lost, compensator=compensator,
                        gravity=gravity)
