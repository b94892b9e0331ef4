"""Fit of one model class: the joint compliances plus the class's extra parameters.

The displacement of P is modelled as ``f(x) + B beta``: f the joint-spring model of the
estimator (``exact``: the equilibrium model, ``ols``/``wls``: the linear one), x the
joint compliances (rad/(N m)), B the class's extra columns (the regressors of
:mod:`analysis.identification.checks.cause_columns`, reused):

* ``links``: 21 entries of the symmetric 6 x 6 compliance C_l of each link of
  :data:`LINKS` at its distal frame (:func:`analysis.kinetostatics.realistic.distal_frames`,
  the simulated lab's frame): ``J_l C_l J_l^T w``;
* ``lost-motion``: the dead band 2b_j (rad) of each joint whose gear torque changes sign
  between the reference and the loaded reading (from the robot's mass model and the
  measured wrench). The torque is known to the wrench noise only (sigma_tau, the noise
  model's wrench sigma through J^T at the reading, :func:`torque_sigmas`; the mass model
  taken as exact): where it is within :data:`~analysis.model.gravity.FLANK_DECIDED_SIGMAS`
  sigma_tau of zero the flank is a coin with p = Phi(tau / sigma_tau), so the column is
  the expected step ``J_j E[(s_load - s_ref)/2]`` and the test's residual covariance
  gains ``(2b_j)^2 Var[(s_load - s_ref)/2] J_j J_j^T`` at the fitted 2b_j (refitted, at
  most :data:`FLANK_REWEIGHT` times, until the bands settle: the weights depend on
  them). Chosen over a hard rule with a wider mid-band (which would throw away a band
  the data do show) and over a mixture likelihood (exact but not Gaussian: the fit's
  covariance and chi-square would no longer be (M^T W M)^-1 and a chi-square): the first
  two moments keep the Gaussian machinery, and the row's chi-square stays about 1-2
  where the wrong hard flank gave hundreds (study seed 178). Beyond 8.5 sigma_tau the
  flank is the hard rule's bit for bit (probability 1 in double precision), so a campaign
  without near-zero torques keeps its numbers. Which bands are candidates (identifiable)
  is still decided by the hard rule; joint 2's flank pattern search under a compensator
  too (its spring's torque is searched, not noisy);
* ``compensator``: with the spring's geometry known (attachment points), its preload
  (N) and rate (N/m) inside the realistic-arm equilibrium
  (:func:`analysis.kinetostatics.realistic.displacement`: the effective k2 is
  k2 - dtau_c/dq2); else the stated law ``x2(q2) = x2 + c1 t + c2 t^2``, t = q2 - q2ref
  (q2ref the tests' mean);
* ``gravity``: no parameter: the robot's mass model loads the springs at both readings
  (the realistic-arm equilibrium), which changes the effective stiffness by dg/dq.

Identifiable combinations: each class's whitened columns are projected off the joint
springs' (and the classes reduced before it, in :data:`~.names.EXTRAS` order), scaled to
unit norm and reduced by a QR factorisation with column pivoting; a column whose
|R_ii| is below :data:`RANK_TOL` (the largest is 1) is fixed at 0 and named, so the
kept ones are original parameters. The fixed ones' effect is absorbed by the joint
springs and the kept ones (their gauge): the joint compliances of a class with links are
the joint springs plus the link bending the tests cannot tell from them.

Gauss-Newton on (x, beta) from the joint-only fit, whitened by the joint fit's residual
covariance (:func:`~analysis.identification.noise.residual_covariance`), Gaussian
covariance ``(M^T W M)^-1`` (noise as declared). Held-out: each pose group left out in
turn, the class refitted (one linear step from the full fit, exact for a linear model)
and the left-out tests predicted; ``heldout_chi2_nu`` is the sum of the left-out
residuals' Mahalanobis norms (measurement plus prediction covariance) over the
left-out equations (1 when the class is right). All SI.
"""

from __future__ import annotations

from dataclasses import dataclass, field, replace

import numpy as np

from analysis.identification.checks import cause_columns as cc
from analysis.identification.io.measurements import TestArrays
from analysis.identification.linalg.lsq import whitening
from analysis.identification.models.names import EXTRAS, class_name
from analysis.identification.noise import NoiseModel, residual_covariance
from analysis.identification.uncertainty import stiffness_interval
from analysis.kinetostatics.equilibrium import EquilibriumError
from analysis.kinetostatics.realistic import distal_frames, virtual_jacobian
from analysis.model.kinematics import chain_state, jacobian

#: compliant links of the ``links`` class, 1-based (the upper arm and the forearm)
LINKS = (2, 3)
#: pivoted-QR tolerance: a column whose part independent of the joint springs and of the
#: columns kept before it is below this fraction of its norm is fixed (not identified)
RANK_TOL = 1e-2
#: Gauss-Newton steps at most, and the relative step that ends them
MAX_ITER = 10
STEP_TOL = 1e-7
#: two-sided normal quantile of the 95 % intervals
Z95 = 1.959963984540054
#: relative step of the forward differences of the gravity-loaded model
FD_STEP = 1e-6
#: forward-difference steps of the compensator spring's preload (N) and rate (N/m)
FD_PRELOAD = 1.0
FD_RATE = 10.0
#: joint of the compensator (0-based: axis 2)
COMP_JOINT = 1
#: joint 2's flank search: the half-width of the spring's range (standard errors), the
#: grid points per axis over it, and the number of distinct patterns fitted at most
FLANK_SEARCH_SE = 10.0
FLANK_GRID = 61
MAX_FLANK_PATTERNS = 2
#: refits at the best pattern's own spring when no candidate pattern is consistent
FLANK_FIXED_POINT = 2
#: a pattern is consistent when a spring within this many standard errors of the fitted
#: one (box, grid points per axis) produces it
FLANK_CONSISTENT_SE = 3.0
FLANK_CONSISTENT_GRID = 13
#: refits at most with the residual covariance widened by the fitted dead bands where a
#: flank is undecided, and the change of every band (relative) that ends them
FLANK_REWEIGHT = 5
FLANK_REWEIGHT_TOL = 1e-4


@dataclass(frozen=True)
class ClassData:
    """One campaign prepared for the class fits: the robot, the tests (SI), the fitted
    joints (0-based), the noise model, the estimator, the joint-only fit's compliances
    ``x0`` (6,) (rad/(N m)), the gear torques (tau_ref, tau_load) (m, 6) each (N m) or
    None (no mass model), the whitening ``Linv`` (m, 6, 6) and the pose group (m,) of
    each test for the held-out validation."""

    robot: object
    tests: TestArrays
    joints: tuple[int, ...]
    noise: NoiseModel
    method: str
    x0: np.ndarray
    gear_torques: tuple[np.ndarray, np.ndarray] | None
    Linv: np.ndarray
    group: np.ndarray
    links: tuple[int, ...] = LINKS
    w_ref: np.ndarray | None = None
    compensator: object = None
    #: the residual covariance (m, 6, 6) whose whitening is ``Linv`` (None: recomputed
    #: from x0 as :func:`prepare` does), widened where a gear's flank is undecided
    cov: np.ndarray | None = None


def prepare(robot, tests: TestArrays, joints, x0, noise: NoiseModel, method: str,
            gear_torques, group: np.ndarray, links=LINKS, w_ref: np.ndarray | None = None,
            compensator=None) -> ClassData:
    """:class:`ClassData` of a campaign, whitened at the joint-only fit's x0 (6,).

    ``w_ref`` (m, 6) the reference (preload) wrenches (None:
    unloaded references); ``compensator``: a
    :class:`~analysis.kinetostatics.realistic.Compensator` whose geometry is known (its
    rate and preload are then what the compensator class identifies) or None (the
    quadratic k2(q2) law)."""
    x0 = np.asarray(x0, dtype=float)
    J = jacobian(robot, tests.q)
    C = np.einsum("mrj,j,msj->mrs", J, x0, J)
    cov = residual_covariance(noise, C, tests.w)
    Linv = whitening(cov, tests.measured)
    return ClassData(robot, tests, tuple(joints), noise, method, x0, gear_torques, Linv,
                     np.asarray(group), tuple(links), w_ref, compensator, cov)


@dataclass(frozen=True)
class ClassFit:
    """One class fitted: ``name`` (``joints``, ``links+lost-motion``, ...); ``x`` (6,)
    joint compliances (rad/(N m), 0 for a rigid joint); ``k_ci`` (6, 2) their 95 %
    stiffness intervals (N m/rad); ``names``, ``values``, ``se``, ``units`` of the extra
    parameters kept; ``fixed``: (parameter or group, why) fixed at 0; ``cov`` the
    covariance of (x over joints, extras); chi2 over ``n_eq`` equations with ``n_params``
    parameters; ``bic`` = chi2 + n_params ln n_eq, ``aic`` = chi2 + 2 n_params (noise as
    declared); held-out chi2/nu and error (translation, %); ``q2ref`` (rad) of the
    compensator law; ``error``: why it could not be fitted ("" if fitted)."""

    name: str
    extras: tuple[str, ...]
    x: np.ndarray
    k_ci: np.ndarray
    names: tuple[str, ...]
    values: np.ndarray
    se: np.ndarray
    units: tuple[str, ...]
    fixed: tuple[tuple[str, str], ...]
    cov: np.ndarray
    chi2: float
    n_eq: int
    n_params: int
    bic: float
    aic: float
    heldout_chi2_nu: float
    heldout_error: float
    q2ref: float = float("nan")
    links: tuple[int, ...] = ()
    error: str = ""
    link_matrices: dict = field(default_factory=dict)
    #: (preload (N), rate (N/m)) whose spring torque decided joint 2's flanks (the flank
    #: pattern held), () when the flanks followed the fitted spring or no spring
    flank_spring: tuple[float, ...] = ()
    #: the fitted joints (0-based): the first rows of ``cov`` are their compliances
    joints: tuple[int, ...] = ()
    #: why the campaign's design cannot test this class ("" if it can;
    #: :mod:`analysis.identification.models.design_size`)
    untestable: str = ""

    @property
    def dof(self) -> int:
        return self.n_eq - self.n_params

    @property
    def chi2_nu(self) -> float:
        return self.chi2 / self.dof if self.dof > 0 else float("nan")

    @property
    def p_value(self) -> float:
        from scipy import special

        return float(special.chdtrc(self.dof, self.chi2)) if self.dof > 0 else float("nan")

    @property
    def k(self) -> np.ndarray:
        with np.errstate(divide="ignore"):
            return np.where(self.x > 0, 1.0 / np.where(self.x > 0, self.x, 1.0), np.nan)

    def describe(self) -> dict:
        """results.json's record of the class (SI; intervals 95 %, Gaussian)."""
        if self.error:
            return {"model": self.name, "error": self.error}
        return {
            "model": self.name, "chi2": self.chi2, "n_equations": self.n_eq,
            "n_parameters": self.n_params, "chi2_nu": self.chi2_nu, "p_value": self.p_value,
            "bic": self.bic, "aic": self.aic, "heldout_chi2_nu": self.heldout_chi2_nu,
            "heldout_error_pct": 100.0 * self.heldout_error,
            "k_N_m_per_rad": [None if not np.isfinite(v) else float(v) for v in self.k],
            "k_ci95": [[None if not np.isfinite(v) else float(v) for v in row]
                       for row in self.k_ci],
            "parameters": [{"name": n, "value": float(v), "se": float(s),
                            "ci95": [float(v - Z95 * s), float(v + Z95 * s)], "unit": u}
                           for n, v, s, u in zip(self.names, self.values, self.se,
                                                 self.units, strict=True)],
            "fixed": [{"parameter": n, "why": why} for n, why in self.fixed],
            **({"untestable": self.untestable} if self.untestable else {}),
            "covariance": {"parameters": [f"x{j + 1}" for j in self.joints] + list(self.names),
                           "unit": "products of the parameters' SI units (x = 1/k rad/(N m))",
                           "matrix": self.cov.tolist()},
            **({"compensator_q2ref_rad": self.q2ref} if np.isfinite(self.q2ref) else {}),
            **({"links": list(self.links),
                "link_compliance": {str(link): m.tolist()
                                    for link, m in self.link_matrices.items()}}
               if self.links else {}),
        }


def _unit(a: int, b: int) -> str:
    if a < 3 and b < 3:
        return "m/N"
    if a >= 3 and b >= 3:
        return "rad/(N m)"
    return "rad/N"


def link_columns(robot, q: np.ndarray, w: np.ndarray, links) -> tuple[np.ndarray, list]:
    """(B (m, 6, 21 len(links)), names): the regressor of the links' compliances at
    their distal frames (:func:`cause_columns.symmetric_columns` on the Jacobian of the
    simulated lab's frame), names ``C2[a,b]`` (rows/columns 1..6: translations, rotations)."""
    tip = chain_state(robot, q).tip[:, :3, 3]
    blocks, names = [], []
    for link in links:
        Jl = virtual_jacobian(distal_frames(robot, q, link), tip)
        blocks.append(cc.symmetric_columns(Jl, w))
        names += [(f"C{link}[{a + 1},{b + 1}]", _unit(a, b)) for a in range(6)
                  for b in range(a, 6)]
    return np.concatenate(blocks, axis=-1), names


def _model(data: ClassData, x_full: np.ndarray, spring=None, gravity: bool = False):
    """(prediction (m, 6), A (m, 6, 6), G (m, 6, 2) or None) of the joint-spring model at
    x_full: the estimator's (``exact``: the equilibrium, else the linear model), or, with
    ``gravity`` (the class ``gravity``) or a ``spring`` = (preload (N), rate (N/m)) of
    the compensator of ``data.compensator``'s geometry, the realistic-arm physics
    (:func:`analysis.kinetostatics.realistic.displacement`: the arm's weight loads the
    springs at both readings; the spring's torque and stiffness enter the equilibrium),
    derivatives then by forward differences (x: relative :data:`FD_STEP`; preload
    :data:`FD_PRELOAD`, rate :data:`FD_RATE`); G the derivative in (preload, rate)."""
    t = data.tests
    if gravity or spring is not None:
        return _physics_model(data, x_full, spring, gravity)
    if data.method == "exact":
        from analysis.identification.estimators.exact_model import model_displacement

        return (*model_displacement(data.robot, t.q, x_full, t.w, w_ref=_w_ref(data)), None)
    from analysis.identification.estimators.linear_model import design_block

    A = design_block(jacobian(data.robot, t.q), t.w)
    return np.einsum("mrj,j->mr", A, x_full), A, None


def _w_ref(data: ClassData) -> np.ndarray | None:
    """The reference (preload) wrenches (m, 6): ``data.w_ref``, else the tests' own
    (``TestArrays.w_ref``; ``TestArrays.w`` is then loaded minus reference), or None."""
    w_ref = data.w_ref if data.w_ref is not None else getattr(data.tests, "w_ref", None)
    return None if w_ref is None else np.nan_to_num(np.asarray(w_ref, dtype=float))


def _physics_model(data: ClassData, x_full: np.ndarray, spring, gravity: bool):
    from analysis.kinetostatics.realistic import RealisticLab, displacement_cases

    t = data.tests
    w_ref = _w_ref(data)
    w_ref = np.zeros(6) if w_ref is None else w_ref
    # the point and its forward-difference neighbours, one Newton loop for all (cases:
    # x_full, then x_full + h_j e_j per fitted joint, then the spring's two steps)
    xs, springs, steps = [x_full], [spring], []
    for j in data.joints:
        h = FD_STEP * abs(x_full[j]) if x_full[j] != 0 else FD_STEP * 1e-6
        xh = x_full.copy()
        xh[j] += h
        xs.append(xh)
        springs.append(spring)
        steps.append(h)
    if spring is not None:
        for i, h in enumerate((FD_PRELOAD, FD_RATE)):
            sh = np.array(spring, dtype=float)
            sh[i] += h
            xs.append(x_full)
            springs.append(sh)
            steps.append(h)
    xs = np.array(xs)
    with np.errstate(divide="ignore"):
        k = np.where(xs > 0, 1.0 / np.where(xs > 0, xs, 1.0), np.inf)
    lab = RealisticLab(gravity="on" if gravity else "off",
                       compensator=None if spring is None else data.compensator)
    disp = displacement_cases(data.robot, lab, k, t.q, w_ref, w_ref + t.w,
                              None if spring is None else np.array(springs, dtype=float))
    pred = disp[0]
    A = np.zeros((*pred.shape, x_full.size))
    for c, j in enumerate(data.joints, start=1):
        A[..., j] = (disp[c] - pred) / steps[c - 1]
    if spring is None:
        return pred, A, None
    G = np.zeros((*pred.shape, 2))
    for i in range(2):
        c = len(data.joints) + 1 + i
        G[..., i] = (disp[c] - pred) / steps[c - 1]
    return pred, A, G


def _reduce(WA: np.ndarray, WB: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(kept, tiny): indices of WB's columns kept by the pivoted QR of WB projected off
    WA's span and normalised, and the columns with no part independent of WA."""
    from scipy.linalg import qr

    Q, _ = np.linalg.qr(WA)
    P = WB - Q @ (Q.T @ WB)
    norm = np.linalg.norm(P, axis=0)
    ref = np.linalg.norm(WB, axis=0)
    tiny = norm <= RANK_TOL * np.where(ref > 0, ref, 1.0)
    live = np.flatnonzero(~tiny)
    if live.size == 0:
        return live, tiny
    _, R, piv = qr(P[:, live] / norm[live], mode="economic", pivoting=True)
    d = np.abs(np.diag(R))
    r = int(np.sum(d > RANK_TOL * d[0]))
    return np.sort(live[piv[:r]]), tiny


def identifiable_columns(WA: np.ndarray, WB: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(kept, tiny) of the fits' rule (module docstring): the columns of the whitened extra
    regressor WB (rows, r) kept beside the whitened joint columns WA (rows, n), and those
    with no part independent of WA (the planner predicts with the same rule,
    :mod:`campaign.planning.model_class`)."""
    return _reduce(WA, WB)


def parameter_covariance(WM: np.ndarray) -> np.ndarray:
    """``(M^T W M)^-1`` (p, p) of the whitened system WM (rows, p), the fits' covariance
    (columns scaled to unit norm first), products of the parameters' SI units."""
    return _solve(WM, np.zeros(WM.shape[0]))[1]


def _whiten(Linv: np.ndarray, M: np.ndarray) -> np.ndarray:
    return (Linv @ M).reshape(-1, M.shape[-1])


def _solve(WM: np.ndarray, Wr: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(least-squares solution, its covariance (M^T M)^-1) of the whitened system, the
    columns scaled to unit norm first (the parameters' units differ by up to 1e12:
    compliances, metres per newton, newtons)."""
    norm = np.linalg.norm(WM, axis=0)
    D = np.where(norm > 0, 1.0 / np.where(norm > 0, norm, 1.0), 0.0)
    S = WM * D
    sol = np.linalg.lstsq(S, Wr, rcond=None)[0] * D
    cov = np.linalg.pinv(S.T @ S) * D[:, None] * D[None, :]
    return sol, cov


def _extra_columns(data: ClassData, extras, A: np.ndarray, q2ref: float, Gc=None,
                   spring=None, flank_spring=None):
    """[(class, B (m, 6, r), names [(name, unit)], fixed [(name, why)])] per extra, in
    :data:`EXTRAS` order; ``Gc`` the physics model's derivative in the spring's (preload,
    rate) when the compensator's geometry is known, ``spring`` their current values (the
    spring's torque then joins joint 2's gear torque that decides its flank)."""
    t = data.tests
    out = []
    for e in EXTRAS:
        if e not in extras or e == "gravity":  # gravity is in the model, no extra column
            continue
        if e == "links":
            B, names = link_columns(data.robot, t.q, t.w, data.links)
            out.append((e, B, names, []))
        elif e == "lost-motion":
            if data.gear_torques is None:
                raise ValueError("lost motion needs the gear torques: the robot file gives no "
                                 "mass model (link masses and centres of mass)")
            J = jacobian(data.robot, t.q)
            taus = _lost_motion_torques(data, extras, spring, flank_spring)
            # which bands are candidates: the hard flank rule (a joint some test flips by
            # the sign of its torque, analysis.model.gravity.gear_flanks); the column: the
            # expected step, the torques known to the wrench noise (torque_sigmas)
            _, flips = cc.lost_motion_columns(J, *taus)
            B, _ = cc.lost_motion_moments(J, *taus, *torque_sigmas(data))
            n_flip = flips.sum(axis=0)
            fixed = [(f"2b{j + 1}", "not identifiable: no test changes the sign of its gear "
                      "torque") for j in range(B.shape[-1]) if n_flip[j] == 0]
            out.append((e, B, [(f"2b{j + 1}", "rad") for j in range(B.shape[-1])], fixed))
        else:
            if COMP_JOINT not in data.joints:
                raise ValueError("the compensator law needs joint 2 identified")
            if data.compensator is not None:
                out.append((e, Gc, [("preload", "N"), ("rate", "N/m")], []))
                continue
            a2 = A[:, :, COMP_JOINT]
            tt = t.q[:, COMP_JOINT] - q2ref
            B = np.stack([a2 * tt[:, None], a2 * (tt**2)[:, None]], axis=-1)
            out.append((e, B, [("c1", "rad/(N m) per rad"), ("c2", "rad/(N m) per rad^2")],
                        []))
    return out


def _lost_motion_torques(data: ClassData, extras, spring=None,
                         flank_spring=None) -> list[np.ndarray]:
    """[tau_ref, tau_load] (m, 6) each (N m): the gear torques that decide the flanks,
    joint 2's with the compensator spring's torque at ``flank_spring`` (else ``spring``) =
    (preload (N), rate (N/m)) when the class has the compensator."""
    taus = [np.array(tau, dtype=float) for tau in data.gear_torques]
    spring = spring if flank_spring is None else flank_spring
    if spring is not None and "compensator" in extras:
        from analysis.kinetostatics.realistic import compensator_torque

        comp = replace(data.compensator, preload=float(spring[0]), rate=float(spring[1]))
        tc = compensator_torque(comp, data.tests.q[:, comp.joint])[0]
        for tau in taus:
            tau[:, comp.joint] += tc
    return taus


def torque_sigmas(data: ClassData) -> tuple[np.ndarray, np.ndarray]:
    """(sigma_ref, sigma_load) (m, 6) each (N m): the standard deviation of each gear
    torque from the noise model's wrench noise (the fit's :meth:`NoiseModel.wrench_sigma_at`)
    through J^T at the reading. The loaded reading: the wrench noise at ``tests.w`` (plus
    the reference wrench, when the tests carry one); the reference: zero when it is
    unloaded (the weight's torque alone, the mass model taken as exact), else the noise at
    the reference wrench. The spring's torque adds none (its flank pattern is searched)."""
    from analysis.model.gravity import gear_torque_sigmas

    t = data.tests
    w_ref = _w_ref(data)
    load = t.w if w_ref is None else t.w + w_ref
    sig_load = gear_torque_sigmas(data.robot, t.q, data.noise.wrench_sigma_at(load))
    if w_ref is None:
        return np.zeros_like(sig_load), sig_load
    return gear_torque_sigmas(data.robot, t.q, data.noise.wrench_sigma_at(w_ref)), sig_load


def _flank_whitening(data: ClassData, extras, bands: dict[int, float], spring=None,
                     flank_spring=None) -> np.ndarray | None:
    """``data.Linv`` with the tests where a band of ``bands`` ({joint 0-based: 2b_j (rad)})
    has an undecided flank re-whitened by the residual covariance plus
    ``sum_j (2b_j)^2 var_j J_j J_j^T`` (var the step's variance,
    :func:`cause_columns.lost_motion_moments`); None when no test has one (the whitening
    is then the joint fit's, unchanged)."""
    t = data.tests
    taus = _lost_motion_torques(data, extras, spring, flank_spring)
    _, var = cc.lost_motion_moments(np.zeros((t.q.shape[0], 6, 6)), *taus,
                                    *torque_sigmas(data))
    band = np.zeros(6)
    for j, b in bands.items():
        band[j] = b
    v = var * band**2  # (m, 6) rad^2 per joint
    amb = np.flatnonzero(np.any(v > 0, axis=1))
    if amb.size == 0:
        return None
    J = jacobian(data.robot, t.q[amb])
    extra = np.einsum("mrj,mj,msj->mrs", J, v[amb], J)
    cov = data.cov
    if cov is None:
        C = np.einsum("mrj,j,msj->mrs", J, data.x0, J)
        cov0 = residual_covariance(data.noise, C, t.w[amb])
    else:
        cov0 = cov[amb]
    Linv = data.Linv.copy()
    Linv[amb] = whitening(cov0 + extra, t.measured[amb])
    return Linv


def fit_class(data: ClassData, extras: tuple[str, ...], like: ClassFit | None = None) -> ClassFit:
    """Fit the class joint springs + ``extras`` (module docstring); a class that cannot be
    fitted (no mass model, no convergence) comes back with ``error`` saying why. ``like``:
    a fit of the same class whose parameterisation (the parameters kept, joint 2's flank
    pattern) is used instead of choosing one from these data (the studies' projection of
    the truth on the estimator's parameters)."""
    name = class_name(extras)
    try:
        ordered = tuple(e for e in EXTRAS if e in extras)
        if like is not None:
            fs = np.array(like.flank_spring) if like.flank_spring else None
            return _fit(data, ordered, name, fs, flank_spring=fs, keep_names=like.names)
        if data.compensator is not None and {"compensator", "lost-motion"} <= set(ordered):
            return _multistart(data, ordered, name)
        return _fit(data, ordered, name)
    except (ValueError, EquilibriumError, np.linalg.LinAlgError) as err:
        nan = np.full(6, np.nan)
        return ClassFit(name, tuple(extras), nan, np.full((6, 2), np.nan), (), np.zeros(0),
                        np.zeros(0), (), (), np.zeros((0, 0)), np.nan, 0, 0, np.inf, np.inf,
                        np.nan, np.nan, error=str(err).split("\n")[0])


def _flank_pattern(data: ClassData, spring) -> tuple:
    """Joint 2's flanks (reference, loaded) at every test with the compensator spring
    ``spring`` = (preload (N), rate (N/m)): the discrete part of the model."""
    ref, load = _flank_patterns(data, np.array([spring[0]], dtype=float),
                                np.array([spring[1]], dtype=float))
    return tuple(ref[0].tolist()), tuple(load[0].tolist())


def _flank_patterns(data: ClassData, preload: np.ndarray,
                    rate: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Joint 2's flanks (reference, loaded) (G, m) each at every test for G springs
    (preload (G,) N, rate (G,) N/m): :func:`_flank_pattern` of a grid at once (the spring
    enters the torque linearly; the geometry's terms are computed once)."""
    from analysis.kinetostatics.realistic import compensator_torque
    from analysis.model.gravity import gear_flanks

    comp = data.compensator
    tc = compensator_torque(comp, data.tests.q[:, comp.joint], preload[:, None],
                            rate[:, None])[0]
    return tuple(gear_flanks(tau[:, comp.joint] + tc) for tau in data.gear_torques)


def _flank_candidates(data: ClassData, first: ClassFit, WM: np.ndarray,
                      Wr: np.ndarray) -> list[np.ndarray]:
    """Springs (preload, rate) representing the distinct joint-2 flank patterns within
    :data:`FLANK_SEARCH_SE` standard errors (scaled by sqrt(max(1, chi2/nu))) of the
    first-stage spring, ranked by the chi-square of one linear step from the first stage
    (whitened system ``WM``, ``Wr``) with joint 2's dead-band column of that pattern
    added; the :data:`MAX_FLANK_PATTERNS` best."""
    got = dict(zip(first.names, zip(first.values, first.se, strict=True), strict=True))
    (p0, sp), (r0, sr) = got["preload"], got["rate"]
    scale = np.sqrt(max(1.0, first.chi2_nu)) if np.isfinite(first.chi2_nu) else 1.0
    sp, sr = max(sp * scale, FD_PRELOAD), max(sr * scale, FD_RATE)
    u = np.linspace(-FLANK_SEARCH_SE, FLANK_SEARCH_SE, FLANK_GRID)
    a, b = (g.ravel() for g in np.meshgrid(u, u, indexing="ij"))  # a-major, as a loop
    pp, rr = p0 + a * sp, r0 + b * sr
    ref, load = _flank_patterns(data, pp, rr)
    d2 = a * a + b * b
    # each distinct pattern (first seen in grid order) with its grid point nearest the
    # first-stage spring (the first of equals)
    best: dict[bytes, tuple[float, int]] = {}
    keys = np.concatenate([ref, load], axis=1)
    for i in range(keys.shape[0]):
        key = keys[i].tobytes()
        if key not in best or d2[i] < best[key][0]:
            best[key] = (d2[i], i)
    J2 = jacobian(data.robot, data.tests.q)[:, :, COMP_JOINT]
    ranked = []
    for _, i in best.values():
        p, r = pp[i], rr[i]
        step = (load[i] - ref[i]) / 2.0
        col = _whiten(data.Linv, (J2 * step[:, None])[..., None])
        S = np.concatenate([WM, col], axis=1) if np.any(col) else WM
        sol = _solve(S, Wr)[0]
        e = Wr - S @ sol
        ranked.append((float(e @ e), p, r))
    ranked.sort()
    return [np.array([p, r]) for _, p, r in ranked[:MAX_FLANK_PATTERNS]]


def _multistart(data: ClassData, extras: tuple[str, ...], name: str) -> ClassFit:
    """The spring's torque decides joint 2's flank, a discontinuous function of its
    preload and rate: a Gauss-Newton fit that lets the flanks follow the spring settles
    on wrong ones (shop lab seed 101, noise-free: chi2 150 instead of 2.5 over 216
    equations, 2b2 half its value). So the flank pattern is searched as the discrete
    parameter it is: a first fit with joint 2's dead band left out (the other joints'
    flanks come from the mass model) gives the spring; the distinct joint-2 flank
    patterns its plausible range produces, ranked by one linear step
    (:func:`_flank_candidates`), are each fitted with the pattern held; the lowest
    chi-square wins (named in ``fixed``)."""
    first, WM, Wr = _fit(data, extras, name, drop_flank_joint=True, with_system=True)
    fits = [_fit(data, extras, name, s0, flank_spring=s0)
            for s0 in _flank_candidates(data, first, WM, Wr)]
    # a pattern is consistent when the spring fitted with it gives it back (joint 2's
    # steps between the readings): the others fit noise with flanks their own spring
    # would not produce (shop lab seed 110: 16 of 48 intervals missed the projection)
    ok = [f for f in fits if _consistent(data, f)]
    how = "consistent with its fitted spring"
    if not ok:  # fixed-point steps from the best: the flanks of its own spring
        f = min(fits, key=lambda f: f.chi2)
        for _ in range(FLANK_FIXED_POINT):
            f = _fit(data, extras, name, _spring(f), flank_spring=_spring(f))
            if _consistent(data, f):
                break
        ok, how = [f], ("of its own fitted spring" if _consistent(data, f) else
                        "NOT consistent with its fitted spring (no pattern found that is)")
    best = min(ok, key=lambda f: f.chi2)
    return replace(best, fixed=best.fixed + (
        ("joint 2 flanks", f"the pattern of lowest chi-square {how}, among {len(fits)} of "
         f"those the spring's plausible range produces (within {FLANK_SEARCH_SE:g} standard "
         f"errors of a fit without joint 2's dead band)"),))


def _spring(f: ClassFit) -> np.ndarray:
    """The fitted (preload (N), rate (N/m)) of a compensator class."""
    got = dict(zip(f.names, f.values, strict=True))
    return np.array([got.get("preload", 0.0), got.get("rate", 0.0)])


def _consistent(data: ClassData, f: ClassFit) -> bool:
    """Is the pattern ``f`` was fitted with (joint 2's steps, loaded minus reference flank)
    produced by a spring within :data:`FLANK_CONSISTENT_SE` standard errors of the fitted
    one (a grid over that box)? The spring is known to its uncertainty only: a test whose
    joint-2 torque is near zero can take either step within it."""
    if f.error or not f.flank_spring:
        return False
    want = np.subtract(*_flank_pattern(data, f.flank_spring)[::-1])
    got = dict(zip(f.names, zip(f.values, f.se, strict=True), strict=True))
    (p, sp), (r, sr) = got["preload"], got["rate"]
    u = np.linspace(-FLANK_CONSISTENT_SE, FLANK_CONSISTENT_SE, FLANK_CONSISTENT_GRID)
    a, b = (g.ravel() for g in np.meshgrid(u, u, indexing="ij"))
    ref, load = _flank_patterns(data, p + a * sp, r + b * sr)
    return bool(np.any(np.all(load - ref == want, axis=1)))


def _fit(data: ClassData, extras: tuple[str, ...], name: str,
         spring0: np.ndarray | None = None, flank_spring=None,
         drop_flank_joint: bool = False, with_system: bool = False,
         keep_names: tuple[str, ...] | None = None):
    t = data.tests
    cols = list(data.joints)
    p = len(cols)
    q2ref = float(np.mean(t.q[:, COMP_JOINT])) if "compensator" in extras else float("nan")
    spring_law = data.compensator is not None and "compensator" in extras
    gravity = "gravity" in extras
    if gravity and getattr(data.robot, "inertials", None) is None:
        raise ValueError("the gravity class needs the robot's mass model (link masses and "
                         "centres of mass in the robot file)")
    x = data.x0.copy()
    _, A, Gc = _model(data, x, np.zeros(2) if spring_law else None, gravity)
    # which extra parameters are identified: decided once, at the joint-only fit
    base = _whiten(data.Linv, A[..., cols])
    kept, fixed, names, classes = [], [], [], []
    for cls, B, nm, fx in _extra_columns(data, extras, A, q2ref, Gc, spring0, flank_spring):
        if cls == "lost-motion" and drop_flank_joint and f"2b{COMP_JOINT + 1}" not in dict(fx):
            fx = [*fx, (f"2b{COMP_JOINT + 1}", "left out of the first stage (its flanks "
                        "follow the spring)")]
        fixed += fx
        # the columns named fixed above (a joint no test flips) are not candidates
        cand = np.array([i for i in range(B.shape[-1]) if nm[i][0] not in dict(fx)], int)
        keep, tiny = np.zeros(0, dtype=int), np.zeros(B.shape[-1], bool)
        if keep_names is not None:  # the parameterisation of another fit
            keep = np.array([i for i in cand.tolist() if nm[i][0] in keep_names], int)
        elif cand.size:
            k_c, t_c = _reduce(base, _whiten(data.Linv, B[..., cand]))
            keep, tiny[cand] = cand[k_c], t_c
        kept.append(keep)
        names += [nm[i] for i in keep]
        classes += [cls] * len(keep)
        drop = [i for i in cand.tolist() if i not in set(keep.tolist())]
        indist = [nm[i][0] for i in drop if tiny[i]]
        weak = [nm[i][0] for i in drop if not tiny[i]]
        if indist:
            fixed.append((", ".join(indist), "indistinguishable from the joint springs (and "
                          "the classes reduced before) at these tests: fixed at 0, absorbed "
                          "by them"))
        if weak:
            fixed.append((", ".join(weak), f"a combination of the kept ones within "
                          f"{RANK_TOL:g} of its norm (pivoted QR): fixed at 0"))
        base = np.concatenate([base, _whiten(data.Linv, B[..., keep])], axis=1)
    beta = np.zeros(len(names))
    in_spring = np.array([c == "compensator" for c in classes], bool)
    spring_idx = kept[[e for e in EXTRAS if e in extras and e != "gravity"]
                      .index("compensator")] if spring_law else None
    if spring_law and spring0 is not None:  # a start (and flanks) for the spring
        beta[in_spring] = np.asarray(spring0, dtype=float)[spring_idx]
    meas = t.measured
    nonlinear = data.method == "exact" or spring_law or gravity
    Linv = data.Linv  # the joint fit's whitening, widened below where a flank is undecided

    def current_spring():
        if not spring_law:
            return None
        spring = np.zeros(2)
        spring[spring_idx] = beta[in_spring]
        return spring

    def system():
        spring = current_spring()
        pred, A_, Gc_ = _model(data, x, spring, gravity)
        m = pred.shape[0]
        g, G = np.zeros((m, 6)), []
        at = 0
        for (cls, B, _, _), keep in zip(_extra_columns(data, extras, A_, q2ref, Gc_, spring,
                                                       flank_spring), kept, strict=True):
            B = B[..., keep]
            if not (cls == "compensator" and spring_law):  # the spring is in pred
                g += np.einsum("mrk,k->mr", B, beta[at:at + B.shape[-1]])
            at += B.shape[-1]
            G.append(B)
        M = np.concatenate([A_[..., cols], *G], axis=-1)
        r = np.where(meas, t.d - pred, 0.0) - g
        return M, r, _whiten(Linv, M), np.einsum("mij,mj->mi", Linv, r).reshape(-1)

    def gauss_newton():
        nonlocal beta
        for _ in range(MAX_ITER):
            M, r, WM, Wr = system()
            delta = _solve(WM, Wr)[0]
            x[cols] += delta[:p]
            beta = beta + delta[p:]
            if not nonlinear or np.all(np.abs(delta[:p]) <= STEP_TOL * np.abs(x[cols])):
                break

    def fitted_bands() -> dict[int, float]:
        return {int(n[2:]) - 1: float(v) for (n, _), v in zip(names, beta, strict=True)
                if n.startswith("2b")}

    gauss_newton()
    # a test whose gear torque is within a few sigma of zero has a flank the data cannot
    # decide: its column is the expected step, and its covariance gains the step's
    # variance times the fitted band squared; refitted until the bands settle (the
    # whitening depends on them)
    for _ in range(FLANK_REWEIGHT if "lost-motion" in extras else 0):
        before = fitted_bands()
        wider = _flank_whitening(data, extras, before, current_spring(), flank_spring)
        if wider is None:
            break
        Linv = wider
        gauss_newton()
        after = fitted_bands()
        if all(abs(after[j] - b) <= FLANK_REWEIGHT_TOL * max(abs(after[j]), abs(b))
               for j, b in before.items()):
            break
    M, r, WM, Wr = system()
    cov = _solve(WM, Wr)[1]
    se = np.sqrt(np.clip(np.diag(cov), 0.0, None))
    chi2 = float(Wr @ Wr)
    n_eq = int(meas.sum())
    n_par = p + len(names)
    k_ci = np.full((6, 2), np.nan)
    k_ci[cols] = stiffness_interval(x[cols], se[:p], Z95)
    ho_chi2, ho_err = _heldout(data, WM, Wr, M, r)
    links = data.links if "links" in extras else ()
    fit = ClassFit(
        name, extras, x.copy(), k_ci, tuple(n for n, _ in names), beta, se[p:],
        tuple(u for _, u in names), tuple(fixed), cov, chi2, n_eq, n_par,
        chi2 + n_par * float(np.log(n_eq)), chi2 + 2.0 * n_par, ho_chi2, ho_err, q2ref, links,
        link_matrices=_link_matrices(names, beta, links),
        flank_spring=() if flank_spring is None else tuple(float(v) for v in flank_spring),
        joints=tuple(cols))
    return (fit, WM, Wr) if with_system else fit


def _link_matrices(names, beta, links) -> dict[int, np.ndarray]:
    """{link: C (6, 6)} of the kept entries (fixed ones 0), SI, distal-frame axes."""
    out = {link: np.zeros((6, 6)) for link in links}
    for (n, _), v in zip(names, beta, strict=True):
        if n.startswith("C"):
            link = int(n[1:n.index("[")])
            a, b = (int(s) - 1 for s in n[n.index("[") + 1:-1].split(","))
            out[link][a, b] = out[link][b, a] = v
    return out


def _heldout(data: ClassData, WM, Wr, M, r) -> tuple[float, float]:
    """(held-out chi2/nu, held-out translation error (fraction)) over the pose groups."""
    groups = np.unique(data.group)
    if groups.size < 2:
        return float("nan"), float("nan")
    meas = data.tests.measured
    rows = np.repeat(data.group, 6)
    z = 0.0
    n_out = 0
    err2 = meas2 = 0.0
    for g in groups:
        out = rows == g
        fit_in = WM[~out]
        dtheta, cov_g = _solve(fit_in, Wr[~out])
        e = Wr[out] - WM[out] @ dtheta
        live = np.flatnonzero(np.any(WM[out] != 0, axis=1) | (e != 0))
        e, Wo = e[live], WM[out][live]
        S = np.eye(e.size) + Wo @ cov_g @ Wo.T
        z += float(e @ np.linalg.solve(S, e))
        n_out += int(meas[data.group == g].sum())
        tests = data.group == g
        pred_err = r[tests] - np.einsum("mrk,k->mr", M[tests], dtheta)
        dp = np.where(meas[tests, :3], pred_err[:, :3], 0.0)
        err2 += float(np.sum(dp**2))
        meas2 += float(np.sum(np.where(meas[tests, :3], data.tests.d[tests, :3], 0.0) ** 2))
    return z / max(n_out, 1), float(np.sqrt(err2 / meas2)) if meas2 > 0 else float("nan")
