"""The one rule for the joints a (theta_2, theta_3) map holds fixed.

The dexterity and deflection maps vary theta_2 and theta_3; every other joint
takes the protocol's ``[sampling] fixed_deg`` value when it gives one, else the
median of the tested (or planned) poses. The plan map and the report use this
rule, so the same campaign shows the same map in both, and the captions state it.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

MAP_JOINTS = (1, 2)  # 0-based theta_2, theta_3: the maps' axes


@dataclass(frozen=True)
class MapFixed:
    """Joint values of a map (rad; entries 2 and 3 unused) and where each comes from.

    Attributes
    ----------
    q : (n,) joint angles (rad, model convention).
    from_protocol : 0-based joints taken from the protocol's fixed_deg.
    from_poses : 0-based joints taken as the median of the tested poses.
    """

    q: np.ndarray
    from_protocol: tuple[int, ...]
    from_poses: tuple[int, ...]

    def values_text(self) -> str:
        """'θ1 = 0, θ4 = 45, θ5 = 45, θ6 = 45 deg'."""
        deg = np.degrees(self.q)
        items = [f"\u03b8{j + 1} = {_deg(deg[j])}" for j in range(len(deg))
                 if j not in MAP_JOINTS]
        return ", ".join(items) + " deg"

    def rule_text(self) -> str:
        """Where the values come from, for a caption."""
        parts = []
        if self.from_protocol:
            parts.append(f"{_joints(self.from_protocol)} from the protocol's [sampling] "
                         "fixed_deg")
        if self.from_poses:
            parts.append(f"{_joints(self.from_poses)} the median of the tested poses")
        return "; ".join(parts)


def _deg(v: float) -> str:
    text = f"{v:.1f}".rstrip("0").rstrip(".")
    return "0" if text in ("-0", "") else text


def _joints(js: tuple[int, ...]) -> str:
    return ", ".join(f"\u03b8{j + 1}" for j in js)


def map_fixed_joints(n: int, fixed_deg: dict[str, float] | None,
                     q_poses: np.ndarray) -> MapFixed:
    """The fixed joints of a map (see the module docstring).

    Parameters
    ----------
    n : number of joints. fixed_deg : protocol ``[sampling] fixed_deg`` ({"q1": deg, ...})
        or None. q_poses : (m, n) tested or planned poses (rad), m >= 1.
    """
    q_poses = np.atleast_2d(np.asarray(q_poses, dtype=float))
    q = np.median(q_poses, axis=0)
    from_protocol = []
    for key, value in (fixed_deg or {}).items():
        j = int(str(key)[1:]) - 1
        if 0 <= j < n and j not in MAP_JOINTS:
            q[j] = np.radians(float(value))
            from_protocol.append(j)
    from_poses = [j for j in range(n) if j not in MAP_JOINTS and j not in from_protocol]
    return MapFixed(q, tuple(sorted(from_protocol)), tuple(from_poses))
