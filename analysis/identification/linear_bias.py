"""Linearisation bias of the linear estimators (OLS, WLS), and what to do about it.

The linear model ``A x`` (eqs. 14-18) is the first-order term of the finite
displacement ``f(x)`` of the equilibrium. A linear estimator ``x_hat = G d``
with ``G A = I`` therefore has the expectation ``G f(x)``, i.e. the bias
``b = G (f(x) - A x)``, evaluated at the estimate (the exact-minus-linear
prediction of every test, mapped through the estimator). Its error is of
relative order se/x, small wherever the result is usable.

Handling (:func:`bias_decision`): when every ``|b_j|`` is at most
:data:`BIAS_FRACTION` of its standard error, the interval of x is widened by
``|b_j|`` on both sides. With the bias known, a 95 % interval ``x_hat +-
(1.96 se + |b|)`` covers between 95 % (b = 0) and 97.5 % (b >> se) of the
time; the estimate of b is itself approximate, so beyond one standard error
(where a biased estimate is mostly bias and the interval mostly padding) the
linear method is refused with a message recommending ``exact``, which has no
such bias.
"""

from __future__ import annotations

import numpy as np

from analysis.errors import InputError
from analysis.identification.exact_fit import model_displacement_masked
from analysis.identification.gauss_newton import EVAL_BLOCK
from analysis.identification.lsq import stack_vector
from analysis.identification.measurements import TestArrays
from analysis.model.robot_model import RobotModel

#: refuse a linear method when some |bias| exceeds this fraction of its standard error
BIAS_FRACTION = 1.0


def linearisation_bias(
    robot: RobotModel,
    tests: TestArrays,
    joints: tuple[int, ...],
    x: np.ndarray,
    G: np.ndarray,
    predicted: np.ndarray,
) -> np.ndarray:
    """Bias (p,) of the linear estimate x (p,) (rad/(N m)): ``G (f(x) - A x)``.

    ``G`` (p, 6m): the estimator (x = G d, stacked measured components);
    ``predicted`` (m, 6): the linear model's A x. NaN where the equilibrium
    cannot be solved at x.
    """
    x_full = np.zeros(robot.n)
    x_full[list(joints)] = x
    # the equilibrium in blocks of tests: its chain states are ~2.6 kB per test at once
    diff = np.empty_like(predicted)
    for s in range(0, tests.m, EVAL_BLOCK):
        sl = slice(s, s + EVAL_BLOCK)
        f, _, ok = model_displacement_masked(robot, tests.q[sl], x_full, tests.w[sl],
                                             with_jacobian=False)
        if not np.all(ok):
            return np.full(len(joints), np.nan)
        diff[sl] = np.where(tests.measured[sl], f - predicted[sl], 0.0)
    return G @ stack_vector(diff)


def bias_decision(
    method: str,
    joints: tuple[int, ...],
    bias: np.ndarray,
    se_x: np.ndarray,
    fraction: float = BIAS_FRACTION,
) -> tuple[np.ndarray, str]:
    """Widened standard errors for the interval (p,) and a note; raises when the bias is too big.

    The interval ``x +- c se`` becomes ``x +- (c se + |b|)``: returned as the
    half-width's ``|b|`` part, to be added by the caller.

    Raises
    ------
    InputError
        Some ``|b_j| > fraction * se_j`` (or the equilibrium has no solution at the
        estimate): the linear model is too biased at these loads.
    """
    if not np.all(np.isfinite(bias)):
        raise InputError(f"{method}: the equilibrium cannot be solved at the linear estimate, "
                         "so its linearisation bias is unknown; use --method exact",
                         where="--method")
    ratio = np.abs(bias) / se_x
    worst = int(np.argmax(ratio))
    if ratio[worst] > fraction:
        raise InputError(
            f"{method} is biased by the linearisation at these loads: joint "
            f"{joints[worst] + 1}'s estimated bias is {ratio[worst]:.2f} of its standard error "
            f"(limit {fraction:g}); use --method exact (the nonlinear equilibrium fit)",
            where="--method")
    note = (f"{method}: linearisation bias estimated (exact minus linear at the estimate), at "
            f"most {ratio[worst]:.2f} of the standard error (joint {joints[worst] + 1}); "
            "intervals widened by it")
    return np.abs(bias), note
