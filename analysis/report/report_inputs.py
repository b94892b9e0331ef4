"""The report's policy: which wrench, which poses, which reference stiffness and which load
cases a report of an identification shows, and where each comes from.

``protocol`` is a campaign protocol (any object with its ``report``, ``campaign``,
``sampling``, ``load_cases``, ``thresholds`` and ``path``; None for imported tests): read,
never imported here. Values arrive checked and in SI (N, N m, rad).
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from pathlib import Path

import numpy as np

from analysis.errors import InputError
from analysis.identification.io.measurements import TestArrays
from analysis.identification.noise import NoiseModel
from analysis.report.build import ReportInputs, wrench_text
from analysis.report.quantities import load_cases as measured_load_cases
from analysis.report.summary import CampaignInfo
from analysis.report.test_table import LoadCase, match_load_cases


def report_inputs(*, robot, tests: TestArrays, info: CampaignInfo, protocol, noise: NoiseModel,
                  wrench: np.ndarray | None, poses: Sequence[np.ndarray],
                  true_k: np.ndarray | None, trials: int,
                  history: Callable[[], object] | None = None) -> ReportInputs:
    """The :class:`ReportInputs` of a report: ``wrench`` (6,) N, N m given by the user (None:
    the protocol's [report] wrench, else its first tested load case, else the imported
    tests' first load case), ``poses`` (each (n,) rad) given by the user after the
    protocol's [report] poses (neither: the first tested pose), ``true_k`` (N m/rad) of a
    simulated lab, ``history()`` the report's history section (None: none). For imported
    tests, ``info.wrenches`` gets the load cases measured."""
    labels = list(dict.fromkeys(tests.pose.tolist()))
    w, w_source = _wrench(protocol, wrench, tests.w, noise)
    if protocol is None:
        info.wrenches = [(wrench_text(c), n) for c, n in
                         measured_load_cases(tests.w, noise.force_sigma, noise.moment_sigma)]
    nominal, label, nominal_source = _nominal(robot, protocol)
    first_of_pose = [int(np.flatnonzero(tests.pose == lab)[0]) for lab in labels]
    return ReportInputs(
        robot=robot, tests=tests, info=info, noise=noise, wrench=w, wrench_source=w_source,
        poses=_poses(robot, protocol, poses, tests.q, labels),
        nominal=None if nominal is None else np.asarray(nominal, float),
        nominal_label=label, nominal_source=nominal_source, true_k=true_k,
        map_fixed=_map_fixed(protocol, robot.n, tests.q[first_of_pose]),
        trials=trials, load_cases=_load_cases(protocol, tests.w, noise),
        history=None if history is None else history())


def _nominal(robot, protocol):
    """(reference k (N m/rad) or None, its label, where its values come from): the robot
    model's, else the protocol's prior."""
    nominal, label = robot.nominal_stiffness, "nominal (robot model)"
    source = (robot.sources or {}).get(
        "stiffness", "the robot file's [stiffness] (its [sources] give no reference)")
    if nominal is None and protocol is not None and protocol.campaign.prior_stiffness:
        nominal, label = np.asarray(protocol.campaign.prior_stiffness), "prior (protocol)"
        source = f"protocol {Path(protocol.path).name} [campaign] prior_stiffness"
    return nominal, label, source


def _poses(robot, protocol, given: Sequence[np.ndarray], q_tests: np.ndarray,
           labels) -> list:
    """(label, q rad) where K_X is reported, each inside the joint limits."""
    poses = []
    if protocol is not None:
        for name, deg in protocol.report.poses_deg.items():
            poses.append((name, np.radians(np.asarray(deg, float))))
    for i, q in enumerate(given, start=1):
        poses.append((f"pose {i} (command line)", np.asarray(q, float)))
    if not poses:
        poses.append((f"{labels[0]} (first tested pose)", q_tests[0]))
    for label, q in poses:
        if np.any(q < robot.lower - 1e-9) or np.any(q > robot.upper + 1e-9):
            raise InputError(f"{np.round(np.degrees(q), 3).tolist()} deg is outside the joint "
                             f"limits of {robot.name}", where=f"pose {label}")
    return poses


def _wrench(protocol, given: np.ndarray | None, w_tests: np.ndarray,
            noise: NoiseModel) -> tuple[np.ndarray, str]:
    """(wrench (6,) N, N m at P, base frame, for the predicted deflection; its source)."""
    if given is not None:
        return np.asarray(given, float), "--wrench"
    if protocol is not None and protocol.report.wrench is not None:
        return np.asarray(protocol.report.wrench, float), "protocol [report] wrench"
    if protocol is not None:
        cases = _load_cases(protocol, w_tests, noise)
        used = sorted(set(match_load_cases(w_tests, cases, noise.force_sigma,
                                           noise.moment_sigma).tolist()) - {-1})
        i = used[0] if used else 0
        return protocol.wrenches()[i], (
            f"load case '{protocol.load_cases[i].name}', the first one tested" if used else
            f"first load case '{protocol.load_cases[0].name}' (no test matches a load case)")
    # not the first test's measured wrench: its noise would show as a load component
    w, n = measured_load_cases(w_tests, noise.force_sigma, noise.moment_sigma)[0]
    return w, (f"load case 1 of the imported tests: mean of its {n} measured wrench(es) "
               f"rounded to the noise sigmas ({noise.force_sigma:g} N, "
               f"{noise.moment_sigma:g} N m); --wrench to choose another")


def _load_cases(protocol, w_tests: np.ndarray, noise: NoiseModel) -> list[LoadCase]:
    """The planned load cases (protocol), or those of the imported tests (CSV)."""
    if protocol is not None:
        return [LoadCase(c.name, c.method, w) for c, w in zip(protocol.load_cases,
                                                              protocol.wrenches(), strict=True)]
    return [LoadCase(f"load case {i + 1}", "as measured", w) for i, (w, _) in
            enumerate(measured_load_cases(w_tests, noise.force_sigma, noise.moment_sigma))]


def _map_fixed(protocol, n: int, q_poses: np.ndarray):
    """The maps' fixed joints: the plan map's rule (protocol fixed_deg, else the poses' median)."""
    from analysis.kinetostatics.map_fixed import map_fixed_joints

    return map_fixed_joints(n, None if protocol is None else protocol.sampling.fixed_deg,
                            q_poses)
