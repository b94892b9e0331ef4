"""Noise model of one test row of a run, from its protocol's instrument figures."""

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
    return NoiseModel().with_overrides(**values)


def protocol_noise_source(protocol) -> str:
    """Where :func:`noise_from_protocol`'s figures come from, in words."""
    from pathlib import Path

    name = Path(str(protocol.path)).name
    return (f"protocol {name} [instruments] noise (pose reading x sqrt(1.5) for loaded - "
            "mean of two unloaded readings; defaults where the protocol gives none)")
