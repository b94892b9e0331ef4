"""The campaign planner: candidate poses in the zones -> an optimal set of tests.

:func:`make_plan` returns a :class:`Plan`; :func:`write_plan` saves it as a
directory (``plan.csv``, the protocol copy, ``plan_map.png``, ``summary.txt``,
``summary.json``); :func:`read_plan` reads that directory back for the
acquisition runner.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
import pandas as pd

from analysis.errors import InputError
from analysis.identification.noise import NoiseModel
from analysis.model.robot_model import RobotModel
from campaign.planning.candidates import Candidates, check_enough, evaluate, sample
from campaign.planning.criteria import (
    candidate_information,
    choose,
    pose_compliance,
    random_reference,
    relative_se,
    tests_information,
)
from campaign.planning.design import criterion, greedy_exchange, random_design
from campaign.planning.plan_output import COLUMNS, read_plan, write_plan
from campaign.planning.separation import Separation
from campaign.protocol import DEG, Protocol
from campaign.protocol_robot import (
    SamplingBox,
    characteristic_length,
    prior_stiffness,
    protocol_robot,
    sampling_boxes,
)
from campaign.run_noise import noise_from_protocol

__all__ = ["COLUMNS", "STRATEGIES", "Design", "Plan", "make_plan", "read_plan", "write_plan"]

STRATEGIES = ("worst-joint", "weighted", "d-optimal", "e-optimal", "zones-random")


@dataclass
class Design:
    """A chosen set of tests. Arrays have one entry per test (pose, load case)."""

    pose: np.ndarray  # (t,) candidate pose index
    case: np.ndarray  # (t,) load case index
    se: np.ndarray  # (n,) predicted standard error of k (N m/rad)
    log_det: float  # log det of the information matrix of relative compliances
    min_eig: float  # its smallest eigenvalue
    picks: np.ndarray | None = None  # (p,) indices of the chosen candidate tests
    #: the prediction under the plan's model class (se above: its marginal se of k), None
    #: for the joint springs (campaign.planning.model_class)
    model: object = None
    joint_se: np.ndarray | None = None  # (n,) se of k of the joint springs only (N m/rad)


@dataclass(frozen=True)
class TestsRaised:
    """The protocol's ``tests`` (``was``) raised ``to`` the least a design for ``model``
    needs: its fit estimates ``parameters`` over the candidates, and with fewer distinct
    tests it fits them exactly or its held-out check is underdetermined."""

    __test__ = False  # not a pytest test class

    was: int
    to: int
    parameters: int
    model: str

    def describe(self) -> dict:
        return {"from": self.was, "to": self.to, "parameters_over_candidates": self.parameters,
                "why": self.sentence()}

    def sentence(self) -> str:
        return (f"tests raised from the protocol's {self.was} to {self.to}: class "
                f"{self.model} has {self.parameters} parameters over the candidates, and a "
                f"design for it needs at least {self.to} distinct tests (twice as many "
                "equations as parameters, more than them with one test held out); "
                "--tests sets the count")


@dataclass
class Plan:
    """A planned campaign: the chosen design, the random zone design, the evidence.

    Attributes
    ----------
    protocol, robot : the inputs (robot with the protocol's tool).
    strategy, seed : how it was planned.
    candidates : the evaluated candidate poses.
    boxes : sampling box of each zone (rad).
    chosen, random : the chosen design and the random zone design (same seed).
    k_prior : (n,) prior joint stiffness (N m/rad). sigma : (6,) displacement sigma
        of one averaged test [m x3; rad x3]. length : characteristic length L (m).
    noise : noise model of one test row (the identification's, see
        :mod:`campaign.run_noise`); the predictions include every source.
    random_median_se : (n,) median predicted standard error of k (N m/rad) over
        201 seeded random zone designs (the reference of the worst-joint criterion).
    case_contributions : per load case, its tests and the relative se of every
        joint without them (see :func:`case_contributions`).
    """

    protocol: Protocol
    robot: RobotModel
    strategy: str
    seed: int
    candidates: Candidates
    boxes: list[SamplingBox]
    chosen: Design
    random: Design
    k_prior: np.ndarray
    sigma: np.ndarray
    length: float
    noise: NoiseModel | None = None
    random_median_se: np.ndarray | None = None
    case_contributions: list[dict] | None = None
    weights: np.ndarray | None = None
    #: the model class the plan designs for (``joints``: today's planner)
    model: str = "joints"
    #: the protocol's test count raised for the class (None: kept)
    tests_raised: TestsRaised | None = None

    def to_frame(self) -> pd.DataFrame:
        """One row per test, columns :data:`COLUMNS` (degrees, N, N m; v_r in deg)."""
        return design_frame(self, self.chosen)


def design_frame(plan: Plan, design: Design) -> pd.DataFrame:
    """Table of a design (see :data:`COLUMNS`)."""
    cand, protocol, robot = plan.candidates, plan.protocol, plan.robot
    q = cand.q[design.pose]
    ctrl = robot.to_controller(q)
    w = plan.protocol.wrenches()[design.case]
    _, pose_id = np.unique(design.pose, return_inverse=True)
    data: dict[str, object] = {
        "test": np.arange(1, len(design.pose) + 1),
        "pose": pose_id + 1,
        "zone": [plan.boxes[z].name for z in cand.zone[design.pose]],
        "load_case": [protocol.load_cases[c].name for c in design.case],
        "method": [protocol.load_cases[c].method for c in design.case],
        "repeats": protocol.campaign.repeats,
    }
    for j in range(robot.n):
        data[f"q{j + 1}_model_deg"] = q[:, j] / DEG
    for j in range(robot.n):
        data[f"q{j + 1}_ctrl_deg"] = ctrl[:, j] / DEG
    for i, name in enumerate(["fx_N", "fy_N", "fz_N", "mx_N_m", "my_N_m", "mz_N_m"]):
        data[name] = w[:, i]
    data["inv_kappa_F"] = cand.inv_kappa[design.pose]
    data["v_p"] = cand.v_p[design.pose, design.case]
    data["v_r_deg"] = cand.v_r[design.pose, design.case] / DEG
    return pd.DataFrame(data, columns=COLUMNS)


#: when some flank changes cannot be avoided, a design with fewer is preferred while its
#: worst relative standard error of k stays within this factor of the flank-blind design's
FLANK_SE_TOLERANCE = 1.25


def _flank_counts(protocol: Protocol, robot: RobotModel, cand: Candidates) -> np.ndarray | None:
    """(N, cases) the number of joints each candidate test moves from one flank to the
    other between its reference reading (under the load case's preload) and its loaded one
    (:mod:`campaign.planning.flanks`), or None when the plan does not look at flanks: a
    robot without a mass model, or a protocol that neither preloads its load cases nor
    simulates lost motion (those plans are unchanged)."""
    from campaign.planning.flanks import flank_changes

    lost = protocol.fake_lab is not None and protocol.fake_lab.lost_motion_rad is not None
    if robot.inertials is None or not (protocol.preloaded or lost):
        return None
    w, w_ref = protocol.wrenches(), protocol.reference_wrenches()
    return np.stack([flank_changes(robot, cand.q, np.broadcast_to(w[c], (len(cand.q), 6)),
                                   np.broadcast_to(w_ref[c], (len(cand.q), 6))).sum(axis=1)
                     for c in range(len(w))], axis=1)


def _flank_limited(protocol: Protocol, cand: Candidates, counts: np.ndarray) -> list:
    """[(limit, candidates)]: for each limit from the fewest flank changes any valid
    candidate test has up to the most, the candidates whose tests change at most that
    many flanks, when enough remain for the protocol's thresholds (the tests over the
    limit counted as rejected ``gear_flank_change``)."""
    valid = cand.valid
    if not valid.any():
        return []
    out = []
    for limit in range(int(counts[valid].min()), int(counts[valid].max()) + 1):
        over = valid & (counts > limit)
        kept = dataclasses.replace(cand, valid=valid & ~over,
                                   rejected={**cand.rejected,
                                             "gear_flank_change": int(np.sum(over))})
        try:
            check_enough(protocol, kept)
        except InputError:
            continue
        out.append((limit, kept))
        if not over.any():
            break
    return out


def _flips(counts: np.ndarray | None, design: Design) -> int:
    """Flank changes of a design's tests (0 without counts)."""
    return 0 if counts is None else int(np.sum(counts[design.pose, design.case]))


def _tests(cand: Candidates, selection: str):
    """Candidate tests: (pose index, case index or -1 for all cases) and the pose group."""
    if selection == "all":
        poses = np.flatnonzero(np.all(cand.valid, axis=1))
        return poses, np.full(poses.size, -1), poses
    poses, cases = np.nonzero(cand.valid)
    return poses, cases, poses


def _expand(pose: np.ndarray, case: np.ndarray, m: int) -> tuple[np.ndarray, np.ndarray]:
    """Rows of a design: a case of -1 stands for every load case in turn."""
    rows_p, rows_c = [], []
    for p, c in zip(pose, case, strict=True):
        for cc in range(m) if c < 0 else [c]:
            rows_p.append(p)
            rows_c.append(cc)
    return np.array(rows_p, dtype=int), np.array(rows_c, dtype=int)


def _design(plan_in: dict, picks: np.ndarray) -> Design:
    pose, case = _expand(plan_in["pose"][picks], plan_in["case"][picks], plan_in["m"])
    M = plan_in["F"][picks].sum(axis=0)
    se = plan_in["k"] * relative_se(_full_information(plan_in, pose, case))
    spec = plan_in.get("spec")
    if spec is None:
        return Design(pose=pose, case=case, se=se, log_det=float(criterion(M, "d")),
                      min_eig=float(criterion(M, "e")), picks=np.asarray(picks, dtype=int))
    from campaign.planning.model_class import predict

    pred = predict(plan_in["robot"], plan_in["cand"], pose, case, plan_in["wrenches"],
                   plan_in["noise"], plan_in["k"], plan_in["rows"], spec)
    return Design(pose=pose, case=case, se=pred.k_se, log_det=float(criterion(M, "d")),
                  min_eig=float(criterion(M, "e")), picks=np.asarray(picks, dtype=int),
                  model=pred, joint_se=se)


def _full_information(plan_in: dict, pose: np.ndarray, case: np.ndarray) -> np.ndarray:
    """Information of the design's tests with every noise source, encoders included."""
    from analysis.identification.studies.robustness import jacobian_derivative

    cand = plan_in["cand"]
    dJ = jacobian_derivative(plan_in["robot"], cand.q[pose])
    F = candidate_information(cand.J[pose], plan_in["wrenches"][case], plan_in["noise"],
                              plan_in["k"], plan_in["rows"], dJ)
    return F.sum(axis=0)


def case_contributions(plan_in: dict, design: Design, names: list[str]) -> list[dict]:
    """What each load case brings: its tests, and each joint's relative se without them."""
    out = []
    for c, name in enumerate(names):
        keep = design.case != c
        used = int(np.sum(~keep))
        without = (relative_se(_full_information(plan_in, design.pose[keep], design.case[keep]))
                   if used and keep.any() else np.full(len(plan_in["k"]), np.inf))
        out.append({"load_case": name, "tests": used,
                    "relative_se_without": [float(v) for v in without] if used else None})
    return out


def _choose(protocol: Protocol, robot: RobotModel, cand: Candidates, strategy: str, seed: int,
            weights, noise: NoiseModel, k_prior: np.ndarray, rows: int, spec=None,
            fixed_tests: bool = True):
    """(cand, inputs, chosen, random, reference): the design of ``strategy`` over the
    candidates, the random zone design, the median random relative se per joint.
    ``spec``: the model class designed for (:mod:`campaign.planning.model_class`; None:
    the joint springs): ``worst-joint`` then minimises its criterion, the other strategies
    keep theirs; the predictions and the reference are the class's. With a class and
    ``fixed_tests`` False (the count is the protocol's, not ``--tests``), fewer tests than
    :func:`~campaign.planning.model_class.minimum_tests` of the class's parameters over
    the candidates are raised to it (``inputs["tests_raised"]``)."""
    wrenches = protocol.wrenches()
    pose, case, group = _tests(cand, protocol.loads.selection)
    if case.size and case[0] < 0:
        C = pose_compliance(cand.J, k_prior)
        F = tests_information(cand.J, pose, wrenches[0], None, noise, k_prior, rows, C)
        for c in range(1, len(wrenches)):
            F += tests_information(cand.J, pose, wrenches[c], None, noise, k_prior, rows, C)
    else:
        F = tests_information(cand.J, pose, wrenches, case, noise, k_prior, rows)
    inputs = {"pose": pose, "case": case, "F": F, "k": k_prior, "m": len(wrenches),
              "cand": cand, "robot": robot, "wrenches": wrenches, "noise": noise, "rows": rows,
              "spec": spec}
    n = protocol.campaign.tests
    inp = None
    if spec is not None:
        from campaign.planning import model_class as mc

        inp = mc.pool_inputs(robot, cand, pose, case, wrenches, noise, k_prior, rows, spec)
        need = mc.minimum_tests(inp.B.shape[-1])
        if n < need and not fixed_tests:
            # fewer distinct tests than this leave the class's fit exact (or its held-out
            # check underdetermined): it could not be told from a smaller class
            inputs["tests_raised"] = TestsRaised(n, need, int(inp.B.shape[-1]), spec.name)
            n = need
    zone = cand.zone[pose]
    sep_deg = protocol.thresholds.min_pose_separation_deg
    sep = Separation(cand.q[pose], group, sep_deg * DEG)
    try:
        rand = random_design(group, zone, n, seed, sep)
        if strategy == "zones-random":
            picks = rand
        elif strategy in ("worst-joint", "weighted"):
            picks = choose(F, group, zone, n, seed,
                           kind="worst" if strategy == "worst-joint" else "weighted",
                           weights=weights, sep=sep)
        else:
            picks = greedy_exchange(F, group, n, kind="d" if strategy == "d-optimal" else "e",
                                    sep=sep)
        reference = random_reference(F, group, zone, n, seed, sep=sep)[1]
        if inp is not None:
            crit_median, reference = mc.random_reference(inp, group, zone, n, seed, sep)
            if strategy == "worst-joint":
                picks = mc.choose_for_class(inp, group, zone, n, seed, picks, crit_median, sep)
    except ValueError as err:
        raise InputError(
            f"cannot choose {n} poses at least {sep_deg:g} deg apart (joint space) from "
            f"{len(np.unique(group))} candidate poses ({err}); lower "
            "min_pose_separation_deg, widen the zones or draw more --candidates",
            where=protocol.where("thresholds", "min_pose_separation_deg")) from err
    chosen = _design(inputs, picks)
    return cand, inputs, chosen, _design(inputs, rand), reference


def _worst(design: Design, k: np.ndarray) -> float:
    return float(np.max(design.se / k))


def _fewer_flips(protocol: Protocol, robot: RobotModel, cand: Candidates, counts: np.ndarray,
                 blind, strategy: str, seed: int, weights, noise: NoiseModel,
                 k_prior: np.ndarray, rows: int, spec=None, fixed_tests: bool = True):
    """A design that changes no flank when the candidates allow one (its fit has no
    lost-motion error at all, whatever its se); else the design with the fewest changes among
    those over the candidates limited to at most 1, 2 ... changes per test
    (:func:`_flank_limited`), whose worst relative standard error of k is within
    :data:`FLANK_SE_TOLERANCE` of the flank-blind design's
    (``blind``, a :func:`_choose` tuple); among equal flank changes the one that separates
    link from joint compliance best (the smallest worst k bias its joint-only fit would
    take from the protocol's assumed link compliances, :mod:`.link_alias`; without
    assumed links, the smaller worst se). ``blind`` when none does better."""
    from campaign.planning.link_alias import design_alias, protocol_links

    links = protocol_links(protocol, robot)

    def key(c) -> tuple[int, float]:
        design = c[2]
        alias = design_alias(protocol, robot, c[0].q[design.pose], design.case, k_prior,
                             noise.displacement_sigma, links)
        second = (_worst(design, k_prior) if alias is None
                  else float(np.nanmax(np.abs(alias))))
        return _flips(counts, design), second

    best, best_key = blind, key(blind)
    bound = FLANK_SE_TOLERANCE * _worst(blind[2], k_prior)
    for _, limited in _flank_limited(protocol, cand, counts):
        try:
            c = _choose(protocol, robot, limited, strategy, seed, weights, noise, k_prior, rows,
                        spec, fixed_tests)
        except InputError:
            continue
        ck = key(c)
        if ck[0] == 0:
            return c  # no flank changes at all: no lost-motion error, whatever its se
        if _worst(c[2], k_prior) <= bound and ck < best_key:
            best, best_key = c, ck
        if best_key[0] == 0:
            break
    return best


def make_plan(
    protocol: Protocol,
    strategy: str = "worst-joint",
    seed: int = 0,
    candidates: int = 10000,
    tests: int | None = None,
    weights: Sequence[float] | None = None,
    model: str | None = None,
) -> Plan:
    """Plan the campaign of ``protocol``.

    Parameters
    ----------
    protocol : a loaded protocol (:func:`campaign.protocol.load_protocol`).
    strategy : ``worst-joint`` (min the largest relative standard error of k,
        guarded so that no joint is worse than the median random zone design;
        :mod:`campaign.planning.criteria`), ``weighted`` (min the ``weights``-weighted sum of
        the relative standard errors), ``d-optimal`` (max log det of the
        information matrix), ``e-optimal`` (max smallest eigenvalue) or
        ``zones-random`` (the paper's practice: random poses cycling through the
        zones). Every criterion uses the identification's noise model.
    seed : seed of the candidate draw and of the random design.
    candidates : number of candidate poses drawn over the zones.
    tests : number of test poses; default the protocol's ``campaign.tests`` (an
        override is recorded in the summary, not in the protocol copy).
    weights : (n,) weights of the joints' relative standard errors (``weighted``).
    model : the model class to design for (``campaign plan --model``), overriding the
        protocol's ``[campaign] model`` (default ``joints``: today's plans);
        :mod:`campaign.planning.model_class`.

    Raises
    ------
    InputError
        Zones or fixed joints outside the limits, thresholds leaving too few
        candidates, unknown strategy; each names the key and line.
    """
    if strategy not in STRATEGIES:
        raise InputError(f"unknown strategy {strategy!r}: expected one of "
                         f"{', '.join(STRATEGIES)}", where="--strategy")
    if candidates < 1:
        raise InputError("need at least one candidate", where="--candidates")
    if tests is not None:
        if tests < 1:
            raise InputError("need at least one test", where="--tests")
        protocol = protocol.model_copy(
            update={"campaign": protocol.campaign.model_copy(update={"tests": tests})}
        )
    robot = protocol_robot(protocol)
    if weights is not None and strategy != "weighted":
        raise InputError("weights are used by --strategy weighted only", where="--weights")
    if strategy == "weighted":
        if weights is None or len(weights) != robot.n or not all(
                np.isfinite(v) and v >= 0 for v in weights) or not any(weights):
            raise InputError(f"the weighted criterion needs {robot.n} weights >= 0, not all 0",
                             where="--weights")
        weights = np.asarray(weights, dtype=float)
    from campaign.planning.model_class import planner_class

    spec = planner_class(protocol, model)
    k_prior = prior_stiffness(protocol, robot)
    protocol.measurement_sigma()  # refuses a pose instrument without noise figures
    noise = noise_from_protocol(protocol)
    rows = protocol.campaign.repeats
    sigma = noise.displacement_sigma / np.sqrt(rows)
    length = characteristic_length(protocol, robot)
    boxes = sampling_boxes(protocol, robot)
    q, zone = sample(boxes, candidates, seed)
    cand = evaluate(protocol, robot, q, zone, k_prior, length)
    check_enough(protocol, cand)
    counts = _flank_counts(protocol, robot, cand)
    fixed = tests is not None
    choice = _choose(protocol, robot, cand, strategy, seed, weights, noise, k_prior, rows, spec,
                     fixed)
    if counts is not None:
        choice = _fewer_flips(protocol, robot, cand, counts, choice, strategy, seed, weights,
                              noise, k_prior, rows, spec, fixed)
    cand, inputs, chosen, rand, reference = choice
    raised = inputs.get("tests_raised")
    if raised is not None:
        protocol = protocol.model_copy(update={"campaign": protocol.campaign.model_copy(
            update={"tests": raised.to})})
    return Plan(
        protocol=protocol,
        robot=robot,
        strategy=strategy,
        seed=seed,
        candidates=cand,
        boxes=boxes,
        chosen=chosen,
        random=rand,
        k_prior=k_prior,
        sigma=sigma,
        length=length,
        noise=noise,
        random_median_se=k_prior * reference,
        case_contributions=case_contributions(
            inputs, chosen, [c.name for c in protocol.load_cases]),
        weights=weights,
        model="joints" if spec is None else spec.name,
        tests_raised=raised,
    )
