"""Noise model of one test row of a run, from its protocol's instrument figures.

One module for the planner (predicted standard errors, design criteria) and
the analysis (weights, intervals), so that the plan predicts what the
identification will see. Sources: the pose instrument (a 6-DoF probe's
figures, or the rigid fit over the reflectors), the F/T sensor (absolute and
% of reading) and the robot's encoders; a source the protocol leaves out
keeps the default of :class:`analysis.identification.noise.NoiseModel`.
"""

from __future__ import annotations

import numpy as np

from analysis.identification.noise import NoiseModel

#: sigma of a run's displacement / sigma of one pose reading: the runner takes
#: d = loaded - mean(unloaded before, unloaded after) (campaign/acquire/runner.py),
#: so var(d) = sigma^2 + sigma^2 / 2.
DISPLACEMENT_FROM_READING = float(np.sqrt(1.5))


def noise_from_protocol(protocol) -> NoiseModel:
    """Noise model of one test row from the protocol's instrument sigmas, defaults elsewhere.

    One pose reading's sigma comes from :meth:`Protocol.pose_reading_sigma` (a
    6-DoF probe's figures, or the rigid fit over the reflectors); a row's
    displacement has :data:`DISPLACEMENT_FROM_READING` times that.
    """
    values: dict = {}
    s_t, s_r = protocol.pose_reading_sigma()
    values["translation_sigma_override"] = s_t * DISPLACEMENT_FROM_READING
    values["rotation_sigma_override"] = s_r * DISPLACEMENT_FROM_READING
    ft = protocol.instruments.get("force_torque")
    if ft is not None:
        values["force_sigma"] = ft.noise.force_N
        values["moment_sigma"] = ft.noise.torque_N_m
        if ft.noise.force_pct is not None:
            values["force_relative"] = ft.noise.force_pct / 100.0
        if ft.noise.torque_pct is not None:
            values["moment_relative"] = ft.noise.torque_pct / 100.0
    rob = protocol.instruments.get("robot")
    if rob is not None and rob.noise.joint_urad is not None:
        values["joint_sigma_override"] = rob.noise.joint_urad * 1e-6
    return NoiseModel().with_overrides(**values)


def undeclared_sources(protocol) -> list[str]:
    """Noise sources the protocol does not declare (their defaults are used), with the default."""
    d = NoiseModel()
    out = []
    ft = protocol.instruments.get("force_torque")
    if ft is None or ft.noise.force_N is None:
        out.append(f"F/T force noise (default {d.force_sigma:.3g} N)")
    if ft is None or ft.noise.torque_N_m is None:
        out.append(f"F/T moment noise (default {d.moment_sigma:.3g} N m)")
    rob = protocol.instruments.get("robot")
    if rob is None or rob.noise.joint_urad is None:
        out.append(f"encoder noise (default {d.joint_sigma * 1e6:.3g} urad)")
    return out


def protocol_noise_source(protocol) -> str:
    """Where :func:`noise_from_protocol`'s figures come from, in words."""
    from pathlib import Path

    name = Path(str(protocol.path)).name
    return (f"protocol {name} [instruments] noise (pose reading x sqrt(1.5) for loaded - "
            "mean of two unloaded readings; defaults where the protocol gives none)")
