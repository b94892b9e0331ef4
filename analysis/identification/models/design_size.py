"""How many distinct equations a campaign's tests give, for the model-class choice.

Repeats of a test (the same pose and load case, read again) add rows but no distinct
equation: a class with as many parameters as the distinct equations fits the tests'
means exactly, its chi-square is the scatter between repeats alone, and no evidence
can then tell it from a smaller class. With a pose group held out (the held-out
check), a class with at least as many parameters as the distinct equations left is
underdetermined there. :func:`design_size` counts both from the data, so that
``--model auto`` does not choose a class this design cannot test
(:mod:`analysis.identification.models.select`); ``campaign plan --model`` applies the
same count before the campaign (:mod:`campaign.planning.model_class`).

Two rows are the same test when they share a pose group and their wrenches agree within
:data:`SAME_LOAD` of the larger one, forces and moments each (the load cases of a
protocol differ in direction or size by far more; the repeats' differences are the load
system's scatter). A test gives as many equations as its rows measure components.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

#: relative wrench difference (forces and moments each) within which two rows of one
#: pose group are repeats of one test
SAME_LOAD = 0.05
#: force (N) and moment (N m) below which a wrench part counts as zero
ZERO_LOAD = (1e-6, 1e-6)


@dataclass(frozen=True)
class DesignSize:
    """A campaign's distinct ``tests`` and ``equations`` (6 per fully measured test), and
    ``equations_held_out``: the fewest left when one pose group is held out (0 with a
    single group)."""

    tests: int
    equations: int
    equations_held_out: int

    def untestable(self, parameters: int) -> str:
        """Why a class with ``parameters`` cannot be tested on this design ("" if it can)."""
        if self.equations <= parameters:
            return (f"{self.tests} distinct tests give {self.equations} equations for its "
                    f"{parameters} parameters: it fits the tests' means exactly (its "
                    "chi-square is the repeats' scatter alone) and cannot be told from a "
                    "smaller class")
        if self.equations_held_out <= parameters:
            return (f"with a pose held out {self.equations_held_out} distinct equations "
                    f"remain for its {parameters} parameters: the held-out check is "
                    "underdetermined")
        return ""

    def describe(self) -> dict:
        return {"distinct_tests": self.tests, "distinct_equations": self.equations,
                "equations_with_a_pose_held_out": self.equations_held_out,
                "same_test": f"same pose group, wrench within {SAME_LOAD:.0%} (forces and "
                             "moments each): repeats add no distinct equation"}


def distinct_tests(group: np.ndarray, w: np.ndarray) -> np.ndarray:
    """Distinct-test label (m,) of each row: rows of one pose ``group`` (m,) whose wrenches
    ``w`` (m, 6) [N; N m] agree within :data:`SAME_LOAD` are one test (greedy, in row
    order: a row joins the first test of its group it matches)."""
    group = np.asarray(group)
    w = np.asarray(w, dtype=float)
    label = np.empty(group.size, dtype=int)
    firsts: dict = {}  # pose group -> [(test label, first row)]
    n = 0
    for i in range(group.size):
        tests = firsts.setdefault(group[i], [])
        for t, r in tests:
            if _same_load(w[r], w[i]):
                label[i] = t
                break
        else:
            label[i] = n
            tests.append((n, i))
            n += 1
    return label


def _same_load(a: np.ndarray, b: np.ndarray) -> bool:
    for part, zero in ((slice(0, 3), ZERO_LOAD[0]), (slice(3, 6), ZERO_LOAD[1])):
        size = max(float(np.linalg.norm(a[part])), float(np.linalg.norm(b[part])))
        if size > zero and float(np.linalg.norm(a[part] - b[part])) > SAME_LOAD * size:
            return False
    return True


def design_size(group: np.ndarray, w: np.ndarray, measured: np.ndarray) -> DesignSize:
    """:class:`DesignSize` of rows with pose ``group`` (m,), wrench ``w`` (m, 6) and
    ``measured`` (m, 6) components."""
    group = np.asarray(group)
    label = distinct_tests(group, w)
    n_tests = int(label.max()) + 1 if label.size else 0
    eq = np.zeros(n_tests, dtype=int)
    np.maximum.at(eq, label, np.asarray(measured, dtype=bool).sum(axis=1))
    grp = np.zeros(n_tests, dtype=group.dtype if group.size else int)
    grp[label] = group
    total = int(eq.sum())
    held = [total - int(eq[grp == g].sum()) for g in np.unique(grp)]
    return DesignSize(n_tests, total, min(held) if len(held) > 1 else 0)


__all__ = ["DesignSize", "SAME_LOAD", "design_size", "distinct_tests"]
