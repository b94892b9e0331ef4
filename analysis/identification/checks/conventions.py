"""Would the data fit the joint springs in another pose convention? Refits, not nested.

A pose given in another convention than the robot model's (the controller's angles for
the model's, one joint's direction reversed) puts every test at a wrong pose. That
alternative is not nested in the fitted model, so it is not an F-test: the tests are
refitted (linear model, weighted by the declared noise at the fit's compliances, two
passes) at the poses of each convention, and a convention *explains* the misfit when the
fit at the given poses fails the misfit test while the refit passes it
(P(chi2 >= observed) >= :data:`MISFIT_P`). Variants: the controller's angles read as
the model's (when the robot file's controller convention differs from the model's), and
each joint's angle reversed.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from analysis.identification.estimators.linear_model import design_block
from analysis.identification.io.measurements import TestArrays
from analysis.identification.linalg.lsq import whitening
from analysis.identification.noise import NoiseModel, residual_covariance
from analysis.model.kinematics import jacobian

#: the misfit test's level (as plausibility.MISFIT_P)
MISFIT_P = 1e-6


@dataclass(frozen=True)
class ConventionCheck:
    """A refit at the poses of another convention.

    variant : what was changed ("the angles read as the controller's", "joint 3 reversed").
    chi2 : the linear refit's chi-square at the given poses; chi2_alt : at the variant's.
    dof : residual degrees of freedom of both. p_given, p_alt : P(chi2 >= observed) of each.
    """

    variant: str
    chi2: float
    chi2_alt: float
    dof: int
    p_given: float
    p_alt: float

    @property
    def explains(self) -> bool:
        """The misfit at the given poses, none at the variant's."""
        return bool(self.p_given < MISFIT_P <= self.p_alt)

    def text(self) -> str:
        return (f"the pose sign convention: with {self.variant} the joint springs fit "
                f"(chi-square {self.chi2:.4g} -> {self.chi2_alt:.4g} with {self.dof} dof, "
                f"P(chi2 >= observed) {self.p_given:.2g} -> {self.p_alt:.2g})")

    def describe(self) -> dict:
        return {"variant": self.variant, "chi2": self.chi2, "chi2_alt": self.chi2_alt,
                "dof": self.dof, "p_value_given": self.p_given, "p_value_alt": self.p_alt,
                "explains": self.explains}


def linear_chi2(robot, q: np.ndarray, tests: TestArrays, cols, x: np.ndarray,
                noise: NoiseModel, passes: int = 2) -> float:
    """Chi-square of the weighted linear fit of ``tests`` at poses ``q`` (rad), the weights
    from the declared noise at compliances ``x`` (rad/(N m)), refreshed once per pass."""
    J = jacobian(robot, q)
    A = design_block(J, tests.w)[..., list(cols)]
    e = np.where(tests.measured, tests.d, 0.0)
    xx = np.abs(np.asarray(x, dtype=float))
    chi2 = float("inf")
    for _ in range(passes):
        C = np.einsum("mrj,j,msj->mrs", J, xx, J)
        Linv = whitening(residual_covariance(noise, C, tests.w), tests.measured)
        WA = (Linv @ A).reshape(-1, len(cols))
        we = np.einsum("mij,mj->mi", Linv, e).reshape(-1)
        sol, *_ = np.linalg.lstsq(WA, we, rcond=None)
        chi2 = float(np.sum((we - WA @ sol) ** 2))
        xx = np.zeros(6)
        xx[list(cols)] = np.abs(sol)
    return chi2


def convention_checks(robot, tests: TestArrays, cols, x: np.ndarray,
                      noise: NoiseModel) -> tuple[ConventionCheck, ...]:
    """The refits of every variant (module docstring), best (smallest chi2_alt) first."""
    from scipy import special

    dof = int(tests.measured.sum()) - len(cols)
    if dof <= 0:
        return ()
    variants = []
    M = robot.controller_matrix
    if not (np.allclose(M, np.eye(robot.n)) and not np.any(robot.controller_offset)):
        variants.append(("the angles read as the controller's (teach pendant) angles",
                         robot.from_controller(tests.q)))
    for j in range(robot.n):
        q = tests.q.copy()
        q[:, j] = -q[:, j]
        variants.append((f"joint {j + 1}'s angle reversed", q))
    chi2 = linear_chi2(robot, tests.q, tests, cols, x, noise)
    p_given = float(special.chdtrc(dof, chi2))
    out = []
    for name, q in variants:
        alt = linear_chi2(robot, q, tests, cols, x, noise)
        out.append(ConventionCheck(name, chi2, alt, dof, p_given,
                                   float(special.chdtrc(dof, alt))))
    return tuple(sorted(out, key=lambda c: c.chi2_alt))
