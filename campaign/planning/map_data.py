"""The numbers of a plan's zone map (``plan_map.png``) for the interactive plots.

The map is the planner's: theta_2 against theta_3 (model convention) over 1/kappa_F of
the normalized Jacobian, the zones as boxes, the candidate poses (those passing the
thresholds marked), the random zone design, and the chosen poses numbered as in
``plan.csv``'s ``pose`` column. One builder (:func:`zone_map`) serves both views: the
Plan view's from the plan in memory (:func:`map_points`), the Acquire view's from the
plan directory (:func:`plan_map_data`), which keeps the chosen poses only: there the
candidates are drawn again from the protocol with the seed and count ``summary.json``
recorded (:func:`campaign.planning.candidates.sample` is seeded, so the same draw), and
the chosen poses are checked to be among them. Angles are returned in deg (the edge).
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

    ``candidates_q_deg`` (N, n): joint angles of the candidates drawn (deg, model
    convention), ``passing`` (N,) those passing the thresholds for some load case; empty
    with ``note`` saying why when they cannot be drawn again. ``chosen``: one record per
    pose of the plan (``pose``, ``q_deg``, ``zone``, ``tests`` (test ids), ``candidate``
    (its index among the passing candidates or None)). ``random_q_deg`` (M, n): the
    random zone design's poses (deg), None when not known (a plan directory).
    """

    axes: tuple[int, int]
    zones: list[dict]
    candidates_q_deg: np.ndarray
    passing: np.ndarray
    chosen: list[dict]
    candidates_drawn: int | None = None
    note: str = ""
    grid: dict | None = None
    random_q_deg: np.ndarray | None = None
    strategy: str = ""

    def to_json(self) -> dict:
        """The Acquire view's map (plain types): the passing candidates as one list of
        angles per joint (deg, 3 decimals), the chosen poses as records."""
        q = np.round(self.candidates_q_deg[self.passing], 3)
        return {"axes": list(self.axes), "zones": self.zones,
                "candidates": {"count": int(q.shape[0]), "drawn": self.candidates_drawn,
                               "q_deg": [q[:, j].tolist() for j in range(q.shape[1])]},
                "chosen": self.chosen, "note": self.note, "grid": self.grid}

    def series_json(self) -> dict:
        """The Plan view's map (plain types), the map's axes only (deg, model convention).

        ``grid``: 1/kappa_F of J_N (``inv_kappa[i3][i2]``) and its axes; ``candidates``:
        every drawn pose, ``passing`` where it passes the thresholds; ``chosen``: the
        design's distinct poses in plan.csv's ``pose`` order, with the tests at each;
        ``random``: the random zone design's poses; ``zones``: the sampling boxes.
        """
        a, b = (j - 1 for j in self.axes)
        grid = dict(self.grid or {})
        texts = {k: grid.pop(k, "") for k in ("fixed_text", "rule_text")}
        rnd = (np.zeros((0, self.candidates_q_deg.shape[1])) if self.random_q_deg is None
               else self.random_q_deg)
        cand = self.candidates_q_deg
        return {
            "grid": grid, **texts,
            "candidates": {"q2_deg": cand[:, a].tolist(), "q3_deg": cand[:, b].tolist(),
                           "passing": [bool(v) for v in self.passing]},
            "chosen": {"q2_deg": [c["q_deg"][a] for c in self.chosen],
                       "q3_deg": [c["q_deg"][b] for c in self.chosen],
                       "tests": [c["tests"] for c in self.chosen]},
            "random": {"q2_deg": rnd[:, a].tolist(), "q3_deg": rnd[:, b].tolist()},
            "zones": [{"name": z["name"], "q2_deg": [z["lo_deg"][a], z["hi_deg"][a]],
                       "q3_deg": [z["lo_deg"][b], z["hi_deg"][b]]} for z in self.zones],
            "strategy": self.strategy,
        }


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


def zone_map(protocol: Protocol, robot, boxes, length: float, chosen: list[dict],
             chosen_q: np.ndarray, candidates_q: np.ndarray, passing: np.ndarray, *,
             drawn: int | None = None, random_q: np.ndarray | None = None,
             strategy: str = "", note: str = "", size: int = GRID) -> MapData:
    """The zone map: the one builder of both views.

    ``robot``: the protocol's (with its tool); ``boxes``: the zones' sampling boxes (rad);
    ``length``: the characteristic length L (m); ``chosen``: the records of
    :func:`chosen_poses`, ``chosen_q`` (P, n) their joints (rad: the background's other
    joints follow them); ``candidates_q`` (N, n) the candidates drawn (rad) and
    ``passing`` (N,) those passing the thresholds; ``random_q`` (M, n) the random zone
    design's poses (rad) or None; ``note``: why the candidates are missing, if they are.
    Each chosen pose gets the index of the passing candidate it is (every joint within
    :data:`MATCH_DEG`), or None.
    """
    zones = [{"name": b.name, "lo_deg": [float(v) for v in b.lo / DEG],
              "hi_deg": [float(v) for v in b.hi / DEG]} for b in boxes]
    cand = np.asarray(candidates_q, dtype=float) / DEG
    passing = np.asarray(passing, dtype=bool)
    ok = cand[passing]
    for c in chosen:
        c["candidate"] = None
        if len(ok):
            err = np.max(np.abs(ok - np.asarray(c["q_deg"])), axis=1)
            i = int(np.argmin(err))
            c["candidate"] = i if err[i] <= MATCH_DEG else None
    if len(ok) and any(c["candidate"] is None for c in chosen):
        note = ("some chosen poses are not among the candidates drawn again (the plan was "
                "edited, or planned by another version): they are shown, not matched")
    return MapData(axes=(2, 3), zones=zones, candidates_q_deg=cand, passing=passing,
                   chosen=chosen, candidates_drawn=drawn, note=note,
                   grid=kappa_grid(protocol, robot, length, chosen_q, size),
                   random_q_deg=None if random_q is None else np.asarray(random_q) / DEG,
                   strategy=strategy)


def map_points(plan, size: int = GRID) -> dict:
    """The Plan view's zone map of ``plan`` (a :class:`campaign.planning.planner.Plan` in
    memory): :meth:`MapData.series_json` of its :func:`zone_map`, every candidate drawn."""
    cand = plan.candidates
    chosen = np.unique(plan.chosen.pose)
    return zone_map(plan.protocol, plan.robot, plan.boxes, plan.length,
                    chosen_poses(plan.to_frame(), plan.robot.n), cand.q[chosen], cand.q,
                    np.any(cand.valid, axis=1), drawn=len(cand.q),
                    random_q=cand.q[np.unique(plan.random.pose)], strategy=plan.strategy,
                    size=size).series_json()


def plan_map_data(protocol: Protocol, plan: pd.DataFrame, seed: int | None,
                  drawn: int | None) -> MapData:
    """The zone map of ``plan`` (a plan table) planned from ``protocol``.

    ``seed`` and ``drawn``: the candidate draw of the plan (summary.json ``seed`` and
    ``candidates.drawn``); None when unknown: the map then has no candidates.
    """
    from campaign.protocol_robot import characteristic_length, protocol_robot, sampling_boxes

    robot = protocol_robot(protocol)
    boxes = sampling_boxes(protocol, robot)
    chosen = chosen_poses(plan, robot.n)
    cand, passing = np.zeros((0, robot.n)), np.zeros(0, bool)
    note = ""
    if seed is None or drawn is None:
        note = "candidates not shown: the plan's summary.json (seed, count) was not found"
    else:
        cand, passing = _candidates(protocol, robot, boxes, seed, drawn)
    return zone_map(protocol, robot, boxes, characteristic_length(protocol, robot), chosen,
                    np.radians(np.asarray([c["q_deg"] for c in chosen], dtype=float)),
                    cand, passing, drawn=drawn, note=note)


def kappa_grid(protocol: Protocol, robot, length: float, chosen_q: np.ndarray,
               size: int = GRID) -> dict:
    """The map's background, as ``plan_map.png`` draws it: 1/kappa_F of J_N over
    (theta_2, theta_3) (``inv_kappa[i3][i2]``, axes in deg) at the other joints' values
    of the report's rule (the protocol's ``fixed_deg``, else the median of the chosen
    poses ``chosen_q`` (P, n), rad); ``length``: L (m)."""
    from analysis.kinetostatics.map_fixed import map_fixed_joints
    from campaign.planning.plan_map import kappa_map

    fixed = map_fixed_joints(robot.n, protocol.sampling.fixed_deg, chosen_q)
    t2, t3, inv_k = kappa_map(robot, fixed.q, length, size)
    return {"theta2_deg": (t2 / DEG).tolist(), "theta3_deg": (t3 / DEG).tolist(),
            "inv_kappa": np.round(inv_k, 6).tolist(), "fixed_text": fixed.values_text(),
            "rule_text": fixed.rule_text()}


def _candidates(protocol: Protocol, robot, boxes, seed: int, drawn: int
                ) -> tuple[np.ndarray, np.ndarray]:
    """The candidate draw of :func:`campaign.planning.planner.make_plan`: joints (N, n)
    (rad) and which pass the thresholds (N,)."""
    from campaign.planning.candidates import evaluate, sample
    from campaign.protocol_robot import characteristic_length, prior_stiffness

    q, zone = sample(boxes, drawn, seed)
    cand = evaluate(protocol, robot, q, zone, prior_stiffness(protocol, robot),
                    characteristic_length(protocol, robot))
    return cand.q, np.any(cand.valid, axis=1)
