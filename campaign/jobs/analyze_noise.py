"""The analyze job's noise overrides: a record of the seven noise figures an analysis may
override (SI), each field naming the :class:`NoiseModel` field it sets and the command-line
option that gives it (named in messages, and the unit it is typed in)."""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass

import numpy as np

from analysis.errors import InputError
from analysis.identification.noise import NoiseModel


def _override(noise_field: str, option: str, to_si: float):
    """A field of :class:`NoiseOverrides`: None (not given) or an SI value; ``to_si``: the
    option's unit in SI (um -> m: 1e-6; % -> 0.01)."""
    return dataclasses.field(default=None, metadata={
        "noise_field": noise_field, "option": option, "to_si": to_si})


@dataclass(frozen=True)
class NoiseOverrides:
    """Noise figures that replace those of the protocol, the sidecar or the defaults, per
    measured component of one test row (m, rad, N, N m, rad, and fractions of |f| and |m|);
    None: not given."""

    translation_sigma_m: float | None = _override("translation_sigma_override",
                                                  "--translation-sigma-um", 1e-6)
    rotation_sigma_rad: float | None = _override("rotation_sigma_override",
                                                 "--rotation-sigma-urad", 1e-6)
    force_sigma_N: float | None = _override("force_sigma", "--force-sigma-N", 1.0)
    moment_sigma_Nm: float | None = _override("moment_sigma", "--moment-sigma-Nm", 1.0)
    joint_sigma_rad: float | None = _override("joint_sigma_override", "--joint-sigma-urad",
                                              1e-6)
    force_relative: float | None = _override("force_relative", "--force-pct", 0.01)
    moment_relative: float | None = _override("moment_relative", "--moment-pct", 0.01)

    @classmethod
    def typed(cls, **values: float | None) -> NoiseOverrides:
        """The overrides from the values typed in the command line's units, each by its
        option's name (``force_sigma_N=2.0``, ``translation_sigma_um=30``, ``force_pct=0.5``);
        an unknown name is an error, never a shifted value."""
        by_option = {f.metadata["option"]: f for f in dataclasses.fields(cls)}
        given = {}
        for name, value in values.items():
            f = by_option.get("--" + name.replace("_", "-"))
            if f is None:
                raise ValueError(f"not a noise option: --{name.replace('_', '-')}")
            given[f.name] = None if value is None else value * f.metadata["to_si"]
        return cls(**given)

    def applied(self, noise: NoiseModel) -> tuple[NoiseModel, list[str]]:
        """(``noise`` with the overrides given, the options that changed it as the command
        line names them); a negative or non-finite value is refused naming its option (a
        zero only for the relative figures)."""
        changed, used = {}, []
        for f in dataclasses.fields(self):
            value, option = getattr(self, f.name), f.metadata["option"]
            if value is None:
                continue
            if not (np.isfinite(value) and (value > 0 or (value == 0 and option.endswith("pct")))):
                raise InputError("expected a positive number", where=option)
            changed[f.metadata["noise_field"]] = value
            used.append(option)
        return (noise.with_overrides(**changed) if changed else noise), used
