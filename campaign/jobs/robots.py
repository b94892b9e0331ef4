"""The ``robots`` job: the built-in robot models, or one model's joints, limits and sources."""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

#: how messages name the robot asked for (the positional argument of ``campaign robots NAME``)
NAME_WHERE = "NAME (argument of campaign robots)"


@dataclass(frozen=True)
class RobotsOptions:
    """name: a built-in name, robot file or URDF (None: list the built-in models);
    tip: the tool frame of a URDF."""

    name: str | None = None
    tip: str | None = None


@dataclass
class RobotsResult:
    """robots: one record per model (:func:`robot_dict`: SI units, radians), each listed
    model with its built-in ``key``; ``single``: a model was asked for by name."""

    robots: list[dict] = field(default_factory=list)
    single: bool = False

    def to_json(self) -> dict:
        """The document ``campaign robots --json`` prints."""
        return self.robots[0] if self.single else {"robots": self.robots}


def robot_dict(r) -> dict:
    """A robot model as JSON (SI units, radians; the keys' suffixes say so)."""
    return {
        "name": r.name, "source_file": str(r.source_file) if r.source_file else None,
        "convention": r.convention, "joints": r.n,
        "lower_rad": r.lower.tolist(), "upper_rad": r.upper.tolist(),
        "controller_sign": [int(v) for v in r.controller_sign],
        "controller_offset_rad": r.controller_offset.tolist(),
        "controller_coupling": np.asarray(r.controller_coupling).tolist(),
        "nominal_stiffness_Nm_per_rad": None if r.nominal_stiffness is None
        else np.asarray(r.nominal_stiffness, float).tolist(),
        "characteristic_length_m": r.characteristic_length,
        "zones": [{"name": z.name, "ranges_rad": {f"q{j + 1}": [float(a), float(b)]
                                                  for j, (a, b) in z.ranges.items()}}
                  for z in r.zones],
        "notes": r.notes or None, "sources": dict(r.sources),
    }


def run(options: RobotsOptions) -> RobotsResult:
    """Load the model asked for, or every built-in model."""
    from analysis.model.robots import builtin_names, load_robot  # pinocchio: lazily

    if options.name is None:
        return RobotsResult([{"key": key, **robot_dict(load_robot(key))}
                             for key in builtin_names()])
    return RobotsResult([robot_dict(load_robot(options.name, options.tip, where=NAME_WHERE))],
                        single=True)
