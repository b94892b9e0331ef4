"""The planner for a model class of ``campaign analyze --model``: its information, its
design criterion and its predicted standard errors.

The class adds to the joint springs' columns ``A x`` (x = 1/k, rad/(N m)) the linear
columns of its extra parameters (:mod:`analysis.identification.models.fit`, the same
functions): ``links``, the entries of each link's 6 x 6 compliance at its distal frame
(:func:`~analysis.identification.models.fit.link_columns`; the links the protocol's
``[fake_lab]`` names, else links 2 and 3 as the fit); ``compensator``, the law
``x2(q2) = x2 + c1 t + c2 t^2``, t = q2 - q2ref (columns a2 t, a2 t^2, a2 joint 2's column
of A). Every test's rows are whitened by the noise model of today's planner
(:func:`campaign.planning.criteria.candidate_information`: displacement, F/T through the
Cartesian compliance, rows repeats), so its information is ``B^T B`` over (x / x0, extras).

Predicted standard errors (what a design's fit will report): the extra columns are reduced
by the fit's own rule (:func:`~analysis.identification.models.fit.identifiable_columns`,
class by class in the fit's order): the fixed ones are named, the kept ones' se and the
se of k are the square roots of the diagonal of ``(M^T W M)^-1`` of the joint and kept
columns: k's se is marginal over the extra parameters (what "separates links from joints"
means), the encoder term included as in today's prediction.

Design criterion (``worst-joint``): today's (worst relative se, the mean as tie-break,
guards at 0.95 of the median of 201 random zone designs), over the marginal relative se
of k and, for the compensator, the relative se of c1' = c1 h / x2 and c2' = c2 h^2 / x2
(the change of x2 over half the candidates' q2 range h: a design with a narrow q2 spread
leaves them poorly determined). The extra columns are first reduced over the whole
candidate pool (columns no design could separate are dropped); the rest carry a weak
Gaussian prior of unit precision in scaled units (each link entry scaled so that its
column's norm over the pool equals the mean joint column's, the compensator's as c1', c2'),
so that a design leaving one of them inseparable from the joints gets a large, finite,
marginal se of k instead of no criterion at all. Pure functions and records; SI.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from analysis.errors import InputError
from analysis.identification.estimators.linear_model import design_block
from analysis.identification.models import fit as class_fit
from analysis.identification.models.names import EXTRAS, class_name, parse_model
from analysis.identification.noise import NoiseModel, residual_covariance
from campaign.planning.criteria import (
    GUARD_FRACTION,
    SCREEN,
    cartesian_compliance,
    encoder_gradient,
    objective_of_se,
    relative_se,
)
from campaign.planning.design import random_design, zones_of
from campaign.planning.separation import Separation, blocked

#: the classes the planner designs for (their extra parameters are linear)
PLANNED = ("compensator", "links")
#: prior precision of the extra parameters in scaled units (see the module docstring)
PRIOR_PRECISION = 1.0
#: smallest half-range of q2 over the candidates used to scale c1, c2 (rad)
MIN_HALF_RANGE = 1e-3
#: compensator joint (0-based), as the fit's
COMP_JOINT = class_fit.COMP_JOINT
#: tests whitened at once (memory: tests x rows x parameters)
BLOCK = 4096


@dataclass(frozen=True)
class ClassSpec:
    """The class a plan designs for: ``extras`` (a sub-tuple of :data:`PLANNED` in
    :data:`~analysis.identification.models.names.EXTRAS` order), ``links`` (1-based)."""

    extras: tuple[str, ...]
    links: tuple[int, ...] = class_fit.LINKS

    @property
    def name(self) -> str:
        return class_name(self.extras)


@dataclass(frozen=True)
class ClassPrediction:
    """A design's predicted fit under the class: ``model`` its name; ``names``, ``units``
    and ``se`` (SI) of the extra parameters the fit keeps; ``fixed``: [(parameters, why)];
    ``k_se`` (n,) marginal standard error of k (N m/rad); ``q2ref`` the compensator law's
    reference (rad, NaN without), ``q2_std``/``q2_range`` the tests' q2 spread (rad)."""

    model: str
    names: tuple[str, ...]
    units: tuple[str, ...]
    se: np.ndarray
    fixed: tuple[tuple[str, str], ...]
    k_se: np.ndarray
    q2ref: float = float("nan")
    q2_std: float = float("nan")
    q2_range: float = float("nan")
    #: distinct equations of the design (6 per distinct (pose, load case) test) and those
    #: left when the pose with the most distinct tests is held out
    equations: int = 0
    equations_pose_held_out: int = 0

    @property
    def parameters(self) -> int:
        """Parameters the class's fit estimates: k and the kept extras."""
        return len(self.k_se) + len(self.names)

    def saturation(self) -> str | None:
        """Why the design cannot support this class, or None: with no more distinct
        equations than parameters the class fits the tests' means exactly (its chi-square
        is the scatter between repeats, so no larger class can beat a smaller one on the
        evidence); with a pose held out no more than the parameters, the held-out check
        is underdetermined. Repeats add no distinct equation."""
        p = self.parameters
        if self.equations <= p:
            return (f"the design's {self.equations // 6} distinct tests give "
                    f"{self.equations} equations for the {p} parameters of class "
                    f"{self.model}: it fits them exactly and cannot be told from a "
                    f"smaller class; use at least {minimum_tests(p)} distinct tests")
        if self.equations_pose_held_out <= p:
            return (f"with a pose held out the design leaves {self.equations_pose_held_out} "
                    f"equations for the {p} parameters of class {self.model}: the "
                    "held-out check cannot test it; use at least "
                    f"{minimum_tests(p)} distinct tests")
        return None


def minimum_tests(parameters: int) -> int:
    """Distinct tests (6 equations each) that leave more equations than ``parameters``
    with one test held out, and twice the parameters in all: the least a design for a
    class needs so that the class can be told from a smaller one."""
    return max(parameters // 6 + 2, -(-2 * parameters // 6))


@dataclass(frozen=True)
class ClassInputs:
    """The candidate tests under the class, for the design: ``B`` (T, rows, p) whitened,
    scaled columns (the n relative compliances x / x0, then the extras kept over the pool
    in scaled units); ``n`` joints; ``crit`` the indices of p in the criterion (k, the
    compensator's c1', c2'); ``names`` the extras kept; ``h`` the q2 half-range (rad)."""

    B: np.ndarray
    n: int
    crit: np.ndarray
    names: tuple[str, ...]
    q2ref: float
    h: float

    def information(self, idx) -> np.ndarray:
        """Information (len(idx), p, p) of the candidate tests ``idx``."""
        b = self.B[np.asarray(idx, dtype=int)]
        return np.einsum("tri,trj->tij", b, b)

    def prior(self) -> np.ndarray:
        """The prior's information (p, p): 0 on k, :data:`PRIOR_PRECISION` on the extras."""
        d = np.full(self.B.shape[-1], PRIOR_PRECISION)
        d[:self.n] = 0.0
        return np.diag(d)


def planner_class(protocol, override: str | None = None) -> ClassSpec | None:
    """The class to design for: ``override`` (``campaign plan --model``) or the protocol's
    ``[campaign] model``; None for ``joints`` (today's planner). Refuses the classes whose
    parameters are not linear columns (gravity, lost motion: the planner avoids gear-flank
    changes instead) and ``auto`` (a plan is made for one class)."""
    where = "--model" if override is not None else protocol.where("campaign", "model")
    text = override if override is not None else getattr(protocol.campaign, "model", None)
    choice = parse_model(text)
    if choice.auto:
        raise InputError("a plan is designed for one model class, not auto: name the class "
                         f"({', '.join(('joints', *PLANNED))}, combined with '+')", where=where)
    other = [e for e in choice.extras if e not in PLANNED]
    if other:
        raise InputError(f"the planner designs for {', '.join(('joints', *PLANNED))} (linear "
                         f"extra parameters), not {', '.join(other)}: lost motion and gravity "
                         "are handled by avoiding gear-flank changes", where=where)
    if not choice.extras:
        return None
    links = class_fit.LINKS
    if protocol.fake_lab is not None and protocol.fake_lab.links:
        links = tuple(sorted(link.link for link in protocol.fake_lab.links))
    return ClassSpec(choice.extras, links)


def extra_columns(robot, J: np.ndarray, q: np.ndarray, w: np.ndarray, spec: ClassSpec,
                  q2ref: float) -> tuple[np.ndarray, list[tuple[str, str, str]]]:
    """(E (m, 6, r), [(name, unit, class)]): the class's extra columns of tests at q (m, n)
    rad under w (m, 6) (N, N m), SI parameters, in the fit's order."""
    cols, names = [], []
    for e in EXTRAS:
        if e not in spec.extras:
            continue
        if e == "compensator":
            a2 = design_block(J, w)[..., COMP_JOINT]
            t = q[:, COMP_JOINT] - q2ref
            cols.append(np.stack([a2 * t[:, None], a2 * (t**2)[:, None]], axis=-1))
            names += [("c1", "rad/(N m) per rad", e), ("c2", "rad/(N m) per rad^2", e)]
        else:
            B, nm = class_fit.link_columns(robot, q, w, spec.links)
            cols.append(B)
            names += [(a, u, e) for a, u in nm]
    return np.concatenate(cols, axis=-1), names


def noise_factor(J: np.ndarray, w: np.ndarray, noise: NoiseModel, k_prior: np.ndarray,
                 dJ: np.ndarray | None = None) -> np.ndarray:
    """L (m, 6, 6), L L^T the residual covariance of one row of each test (today's
    planner's: displacement, F/T through C = J K^-1 J^T, encoders with dJ)."""
    x0 = 1.0 / np.asarray(k_prior, dtype=float)
    G = None if dJ is None else encoder_gradient(J, dJ, w, x0)
    return np.linalg.cholesky(residual_covariance(noise, cartesian_compliance(J, k_prior),
                                                  w, G))


def whitened(robot, J: np.ndarray, q: np.ndarray, w: np.ndarray, noise: NoiseModel,
             k_prior: np.ndarray, spec: ClassSpec, q2ref: float, rows: int = 1,
             dJ: np.ndarray | None = None) -> tuple[np.ndarray, list]:
    """(W (m, 6, n + r), names): ``sqrt(rows) L^-1 [A diag(x0), E]`` of m tests
    (:func:`noise_factor`)."""
    x0 = 1.0 / np.asarray(k_prior, dtype=float)
    E, names = extra_columns(robot, J, q, w, spec, q2ref)
    W = np.linalg.solve(noise_factor(J, w, noise, k_prior, dJ),
                        np.concatenate([design_block(J, w) * x0, E], axis=-1))
    return np.sqrt(rows) * W, names


def reduce_by_class(WA: np.ndarray, WB: np.ndarray, names: list) -> tuple[list, list]:
    """(kept indices, fixed [(names, why)]) of WB's columns by the fit's rule, class by
    class in the fit's order, each against the joints and the classes kept before it."""
    base, kept, fixed = WA, [], []
    for cls in EXTRAS:
        idx = np.array([i for i, nm in enumerate(names) if nm[2] == cls], dtype=int)
        if not idx.size:
            continue
        keep, tiny = class_fit.identifiable_columns(base, WB[:, idx])
        drop = [i for i in range(idx.size) if i not in set(keep.tolist())]
        indist = [names[idx[i]][0] for i in drop if tiny[i]]
        weak = [names[idx[i]][0] for i in drop if not tiny[i]]
        if indist:
            fixed.append((", ".join(indist), "indistinguishable from the joint springs at "
                          "these tests: fixed at 0, absorbed by them"))
        if weak:
            fixed.append((", ".join(weak), "a combination of the kept ones: fixed at 0"))
        kept += idx[keep].tolist()
        base = np.concatenate([base, WB[:, idx[keep]]], axis=1)
    return kept, fixed


def _rows(robot, cand, pose, case, wrenches, noise, k_prior, spec, q2ref, rows, dJ=None):
    """Whitened columns (T, R, n + r) of candidate tests (pose, case; a case of -1: every
    load case, their rows stacked), in blocks of :data:`BLOCK` tests."""
    pose, case = np.asarray(pose, dtype=int), np.asarray(case, dtype=int)
    cases = range(len(wrenches)) if case.size and case[0] < 0 else [None]
    out, names = [], None
    for lo in range(0, pose.size, BLOCK):
        p = pose[lo:lo + BLOCK]
        parts = []
        for c in cases:
            w = wrenches[case[lo:lo + BLOCK]] if c is None else np.broadcast_to(
                wrenches[c], (p.size, 6))
            W, names = whitened(robot, cand.J[p], cand.q[p], w, noise, k_prior, spec, q2ref,
                                rows, None if dJ is None else dJ[lo:lo + BLOCK])
            parts.append(W)
        out.append(np.concatenate(parts, axis=1))
    return np.concatenate(out, axis=0), names


def pool_inputs(robot, cand, pose, case, wrenches, noise: NoiseModel, k_prior: np.ndarray,
                rows: int, spec: ClassSpec) -> ClassInputs:
    """:class:`ClassInputs` of the candidate tests (the planner's ``_tests``)."""
    q2 = cand.q[pose, COMP_JOINT]
    q2ref = float(np.mean(q2))
    h = max(0.5 * float(np.ptp(q2)), MIN_HALF_RANGE)
    W, names = _rows(robot, cand, pose, case, wrenches, noise, k_prior, spec, q2ref, rows)
    n = len(k_prior)
    WA, WB = W[..., :n].reshape(-1, n), W[..., n:].reshape(-1, W.shape[-1] - n)
    kept, _ = reduce_by_class(WA, WB, names)
    x2 = 1.0 / float(k_prior[COMP_JOINT])
    joint_norm = float(np.mean(np.linalg.norm(WA, axis=0)))
    scale = []
    for i in kept:
        if names[i][0] == "c1":
            scale.append(x2 / h)
        elif names[i][0] == "c2":
            scale.append(x2 / h**2)
        else:
            scale.append(joint_norm / float(np.linalg.norm(WB[:, i])))
    B = np.concatenate([W[..., :n], W[..., n:][..., kept] * np.array(scale)], axis=-1)
    crit = np.array(list(range(n)) + [n + j for j, i in enumerate(kept)
                                      if names[i][2] == "compensator"], dtype=int)
    return ClassInputs(B, n, crit, tuple(names[i][0] for i in kept), q2ref, h)


def criterion_se(inp: ClassInputs, M: np.ndarray) -> np.ndarray:
    """Relative standard errors (..., len(crit)) of the criterion's parameters for
    information M (..., p, p) of a design (the prior added here)."""
    return relative_se(M + inp.prior())[..., inp.crit]


def class_objective(inp: ClassInputs, M: np.ndarray, guard: np.ndarray | None) -> np.ndarray:
    """The ``worst`` criterion (:func:`~campaign.planning.criteria.objective_of_se`) of
    information M (..., p, p) under the class; smaller is better."""
    return objective_of_se(criterion_se(inp, M), "worst", None, guard)


def _screen(inp: ClassInputs, base: np.ndarray, allowed: np.ndarray,
            guard: np.ndarray) -> np.ndarray:
    """Allowed candidates with the largest first-order decrease of the criterion's weighted
    variances (as :func:`campaign.planning.criteria._screen`, over the criterion's entries)."""
    idx = np.flatnonzero(allowed)
    if idx.size <= SCREEN:
        return idx
    Minv = np.linalg.pinv(base + inp.prior())
    r = np.sqrt(np.abs(np.diag(Minv)))[inp.crit]
    c = (r / r.max()) ** 8 + (r > guard)
    W = (Minv[:, inp.crit] * c) @ Minv[inp.crit, :]
    gain = np.empty(idx.size)
    for lo in range(0, idx.size, BLOCK):
        b = inp.B[idx[lo:lo + BLOCK]]
        gain[lo:lo + BLOCK] = np.einsum("tri,tri->t", b @ W, b)
    keep = np.argpartition(-gain, SCREEN - 1)[:SCREEN]
    return np.sort(idx[keep])


def class_exchange(inp: ClassInputs, group: np.ndarray, start, guard: np.ndarray,
                   sep: Separation | None = None, max_passes: int = 20,
                   rel_tol: float = 1e-6) -> tuple[np.ndarray, float]:
    """Exchange passes from ``start`` minimising :func:`class_objective` (one candidate per
    pose group), as :func:`campaign.planning.criteria.exchange`. (sorted picks, criterion)."""
    chosen = [int(c) for c in start]
    M = inp.information(chosen).sum(axis=0)
    current = float(class_objective(inp, M, guard))
    for _ in range(max_passes):
        improved = False
        for slot in range(len(chosen)):
            base = M - inp.information([chosen[slot]])[0]
            others = [c for j, c in enumerate(chosen) if j != slot]
            allowed = ~blocked(group, others, sep) if others else np.ones(len(group), bool)
            idx = _screen(inp, base, allowed, guard)
            if not idx.size:
                continue
            score = class_objective(inp, base + inp.information(idx), guard)
            j = int(np.argmin(score))
            if score[j] < current * (1 - rel_tol):
                chosen[slot] = int(idx[j])
                M = base + inp.information([chosen[slot]])[0]
                current = float(score[j])
                improved = True
        if not improved:
            break
    return np.sort(np.array(chosen, dtype=int)), current


def fit_rule_se(inp: ClassInputs, picks) -> np.ndarray:
    """Relative standard errors (n,) of k of the design ``picks`` by the fit's rule (the
    extras reduced class by class, no prior, no encoder term): what its fit reports."""
    b = inp.B[np.asarray(picks, dtype=int)]
    W = b.reshape(-1, b.shape[-1])
    names = [(nm, "", "compensator" if nm in ("c1", "c2") else "links") for nm in inp.names]
    kept, _ = reduce_by_class(W[:, :inp.n], W[:, inp.n:], names)
    cov = class_fit.parameter_covariance(np.concatenate([W[:, :inp.n], W[:, inp.n:][:, kept]],
                                                        axis=1))
    return np.sqrt(np.clip(np.diag(cov)[:inp.n], 0.0, None))


def random_reference(inp: ClassInputs, group, zone, n: int, seed: int, sep=None,
                     designs: int = 201) -> tuple[np.ndarray, np.ndarray]:
    """(median criterion se (len(crit),), median relative se of k by the fit's rule (n,))
    of the seeded random zone designs of :func:`campaign.planning.criteria.random_reference`
    (the same seeds): the guards' base and the summary's reference."""
    zones = zones_of(zone)
    picks = [random_design(group, zone, n, seed + 1000 + i, sep, zones) for i in range(designs)]
    crit = np.stack([criterion_se(inp, inp.information(p).sum(axis=0)) for p in picks])
    fit = np.stack([fit_rule_se(inp, p) for p in picks])
    return np.median(crit, axis=0), np.median(fit, axis=0)


def choose_for_class(inp: ClassInputs, group, zone, n: int, seed: int, joint_picks,
                     crit_median: np.ndarray, sep: Separation | None = None) -> np.ndarray:
    """Picks (n,) minimising :func:`class_objective` guarded by :data:`GUARD_FRACTION` of
    ``crit_median`` (:func:`random_reference`): exchange from the joint-only design and
    from one seeded random zone design."""
    guard = GUARD_FRACTION * crit_median
    inits = [np.asarray(joint_picks, dtype=int),
             random_design(group, zone, n, seed + 17, sep, zones_of(zone))]
    best, best_score = inits[0], np.inf
    for init in inits:
        picks, score = class_exchange(inp, group, init, guard, sep)
        if score < best_score:
            best, best_score = picks, score
    return best


def predict(robot, cand, pose, case, wrenches, noise: NoiseModel, k_prior: np.ndarray,
            rows: int, spec: ClassSpec, encoders: bool = True,
            keep: tuple[str, ...] | None = None) -> ClassPrediction:
    """The fit's standard errors under the class of a design's tests (rows of the design:
    pose (m,), case (m,) indices), by the fit's reduction rule (module docstring), or with
    the parameters ``keep`` (names) when given; the encoder term included unless
    ``encoders`` is False."""
    from analysis.identification.studies.robustness import jacobian_derivative

    pose, case = np.asarray(pose, dtype=int), np.asarray(case, dtype=int)
    q = cand.q[pose]
    q2ref = float(np.mean(q[:, COMP_JOINT])) if "compensator" in spec.extras else float("nan")
    dJ = jacobian_derivative(robot, q) if encoders else None
    ref = 0.0 if np.isnan(q2ref) else q2ref
    W, names = whitened(robot, cand.J[pose], q, wrenches[case], noise, k_prior, spec, ref,
                        rows, dJ)
    n = len(k_prior)
    WA, WB = W[..., :n].reshape(-1, n), W[..., n:].reshape(-1, W.shape[-1] - n)
    if keep is None:
        # chosen as the fit chooses: whitened without the encoder term (near-dependent
        # link entries are kept or fixed by rounding-level differences)
        W0 = W if dJ is None else whitened(robot, cand.J[pose], q, wrenches[case], noise,
                                           k_prior, spec, ref, rows)[0]
        kept, fixed = reduce_by_class(W0[..., :n].reshape(-1, n),
                                      W0[..., n:].reshape(-1, W.shape[-1] - n), names)
    else:
        kept = [i for i, nm in enumerate(names) if nm[0] in set(keep)]
        out = [nm[0] for i, nm in enumerate(names) if i not in set(kept)]
        fixed = [(", ".join(out), "fixed at 0 (not kept by the fit)")] if out else []
    cov = class_fit.parameter_covariance(np.concatenate([WA, WB[:, kept]], axis=1))
    se = np.sqrt(np.clip(np.diag(cov), 0.0, None))
    q2 = q[:, COMP_JOINT]
    tests = np.unique(np.stack([pose, case], axis=1), axis=0)
    per_pose = np.unique(tests[:, 0], return_counts=True)[1]
    return ClassPrediction(spec.name, tuple(names[i][0] for i in kept),
                           tuple(names[i][1] for i in kept), se[n:], tuple(fixed),
                           np.asarray(k_prior, dtype=float) * se[:n], q2ref,
                           float(np.std(q2)), float(np.ptp(q2)),
                           equations=6 * len(tests),
                           equations_pose_held_out=6 * (len(tests) - int(per_pose.max())))


def describe(pred: ClassPrediction, random: ClassPrediction | None,
             joint_only_se: np.ndarray, k_prior: np.ndarray) -> dict:
    """summary.json's ``model_class`` record (SI)."""
    rnd = {} if random is None else dict(zip(random.names, random.se, strict=True))
    return {
        "model": pred.model,
        "parameters": [{"name": nm, "unit": u, "se_design": float(s),
                        "se_random": None if nm not in rnd else float(rnd[nm])}
                       for nm, u, s in zip(pred.names, pred.units, pred.se, strict=True)],
        "fixed": [{"parameters": nm, "why": why} for nm, why in pred.fixed],
        "k_se_joints_only_N_m_per_rad": [float(v) for v in joint_only_se],
        "k_se_joints_only_percent": [float(100 * v / k) for v, k in
                                     zip(joint_only_se, k_prior, strict=True)],
        **({"compensator_q2ref_rad": pred.q2ref} if np.isfinite(pred.q2ref) else {}),
        "q2_std_rad": pred.q2_std, "q2_range_rad": pred.q2_range,
        "distinct_equations": pred.equations, "parameters_estimated": pred.parameters,
        "equations_with_a_pose_held_out": pred.equations_pose_held_out,
        "warning": pred.saturation(),
        "what": "predicted standard errors of the class's fit (first order, noise model of "
                "the plan): k marginal over the class's parameters (predicted_standard_errors),"
                " the kept parameters' se here; the fixed ones as the fit would fix them",
    }
