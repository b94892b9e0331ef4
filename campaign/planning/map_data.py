"""The numbers of a plan's zone map (``plan_map.png``) for an interactive plot.

The map is the planner's: theta_2 against theta_3 (model convention) over 1/kappa_F of
the normalized Jacobian, the zones as boxes, the candidate poses passing the thresholds,
and the chosen poses numbered as in ``plan.csv``'s ``pose`` column. The plan directory
keeps the chosen poses only; the candidates are drawn again from the protocol with the
seed and count ``summary.json`` recorded (:func:`campaign.planning.candidates.sample` is
seeded, so the same draw), and the chosen poses are checked to be among them. Angles are
returned in deg (the edge).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import pandas as pd

from campaign.protocol import DEG, Protocol

#: points per axis of the 1/kappa_F background (the Plan view's interactive map's too)
GRID = 61
#: a chosen pose is "the candidate" when every joint agrees to this (deg; plan.csv has 3
#: decimals and candidates are rounded to 1e-3 deg when drawn)
MATCH_DEG = 6e-4


@dataclass
class MapData:
    """A zone map: axes (joint numbers, 1-based), zones, candidates, chosen poses.

    ``candidates_q_deg`` (N, n): joint angles of the candidates passing the thresholds
    (deg, model convention), empty with ``note`` saying why when they cannot be drawn
    again. ``chosen``: one record per pose of the plan (``pose``, ``q_deg``, ``zone``,
    ``tests`` (test ids), ``candidate`` (its index among the passing candidates or None).
    """

    axes: tuple[int, int]
    zones: list[dict]
    candidates_q_deg: np.ndarray
    chosen: list[dict]
    candidates_drawn: int | None = None
    note: str = ""
    grid: dict | None = None

    def to_json(self) -> dict:
        """Plain types; candidates as one list of angles per joint (deg, 3 decimals)."""
        q = np.round(self.candidates_q_deg, 3)
        return {"axes": list(self.axes), "zones": self.zones,
                "candidates": {"count": int(q.shape[0]), "drawn": self.candidates_drawn,
                               "q_deg": [q[:, j].tolist() for j in range(q.shape[1])]},
                "chosen": self.chosen, "note": self.note, "grid": self.grid}


def chosen_poses(plan: pd.DataFrame, n: int) -> list[dict]:
    """One record per ``pose`` of a plan table (first row of the pose gives its angles)."""
    out = []
    for pose, rows in plan.groupby("pose", sort=True):
        first = rows.iloc[0]
        out.append({"pose": str(pose),
                    "q_deg": [float(first[f"q{j + 1}_model_deg"]) for j in range(n)],
                    "zone": str(first["zone"]),
                    "tests": [int(t) for t in rows["test"]]})
    return out


def plan_map_data(protocol: Protocol, plan: pd.DataFrame, seed: int | None,
                  drawn: int | None) -> MapData:
    """The zone map of ``plan`` (a plan table) planned from ``protocol``.

    ``seed`` and ``drawn``: the candidate draw of the plan (summary.json ``seed`` and
    ``candidates.drawn``); None when unknown: the map then has no candidates.
    """
    from campaign.protocol_robot import protocol_robot, sampling_boxes

    robot = protocol_robot(protocol)
    boxes = sampling_boxes(protocol, robot)
    zones = [{"name": b.name, "lo_deg": [float(v) for v in b.lo / DEG],
              "hi_deg": [float(v) for v in b.hi / DEG]} for b in boxes]
    chosen = chosen_poses(plan, robot.n)
    cand = np.zeros((0, robot.n))
    note = ""
    if seed is None or drawn is None:
        note = "candidates not shown: the plan's summary.json (seed, count) was not found"
    else:
        cand = _passing_candidates(protocol, robot, boxes, seed, drawn)
    for c in chosen:
        c["candidate"] = None
        if len(cand):
            err = np.max(np.abs(cand - np.asarray(c["q_deg"])), axis=1)
            i = int(np.argmin(err))
            c["candidate"] = i if err[i] <= MATCH_DEG else None
    if len(cand) and any(c["candidate"] is None for c in chosen):
        note = ("some chosen poses are not among the candidates drawn again (the plan was "
                "edited, or planned by another version): they are shown, not matched")
    return MapData(axes=(2, 3), zones=zones, candidates_q_deg=cand, chosen=chosen,
                   candidates_drawn=drawn, note=note,
                   grid=kappa_grid(protocol, robot, [c["q_deg"] for c in chosen]))


def kappa_grid(protocol: Protocol, robot, chosen_deg: list[list[float]],
               size: int = GRID) -> dict:
    """The map's background, as ``plan_map.png`` draws it: 1/kappa_F of J_N over
    (theta_2, theta_3) (``inv_kappa[i3][i2]``, axes in deg) at the other joints' values
    of the report's rule (the protocol's ``fixed_deg``, else the chosen poses' median)."""
    from analysis.kinetostatics.map_fixed import map_fixed_joints
    from campaign.planning.plan_map import kappa_map
    from campaign.protocol_robot import characteristic_length

    fixed = map_fixed_joints(robot.n, protocol.sampling.fixed_deg,
                             np.radians(np.asarray(chosen_deg, dtype=float)))
    t2, t3, inv_k = kappa_map(robot, fixed.q, characteristic_length(protocol, robot), size)
    return {"theta2_deg": (t2 / DEG).tolist(), "theta3_deg": (t3 / DEG).tolist(),
            "inv_kappa": np.round(inv_k, 6).tolist(), "fixed_text": fixed.values_text(),
            "rule_text": fixed.rule_text()}


def _passing_candidates(protocol: Protocol, robot, boxes, seed: int, drawn: int
                        ) -> np.ndarray:
    """The candidate draw of :func:`campaign.planning.planner.make_plan`, those passing (deg)."""
    from campaign.planning.candidates import evaluate, sample
    from campaign.protocol_robot import characteristic_length, prior_stiffness

    q, zone = sample(boxes, drawn, seed)
    cand = evaluate(protocol, robot, q, zone, prior_stiffness(protocol, robot),
                    characteristic_length(protocol, robot))
    return cand.q[np.any(cand.valid, axis=1)] / DEG
