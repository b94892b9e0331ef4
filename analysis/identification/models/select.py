"""Choose the model class by evidence (``campaign analyze --model auto``).

Backward elimination over the extras (:data:`~analysis.identification.models.names.EXTRAS`):
from the class with every extra the data allow, each extra is removed in turn
(:func:`~analysis.identification.models.fit.fit_class`); an extra stays only if the
evidence for it is strong, and the weakest goes first, until every remaining one is
supported (at most 1 + 4 + 3 + 2 + 1 fits). Backward, not forward: effects that only
fit together (gravity and the compensator's spring both change the effective k2) would
each fail a forward step alone. The rule, stated in results.json:

* criterion: the Bayesian information criterion with the noise as declared,
  ``BIC = chi2 + p ln n`` (p parameters, n equations);
* an extra is kept only if the class with it has a BIC lower by more than
  :data:`BIC_MARGIN` than the class without it (Kass and Raftery's "very strong"
  evidence, 2 ln B > 10) AND a lower held-out (leave-pose-out) chi2/nu. So the joint
  springs are kept unless the evidence says otherwise;
* a class the design cannot test (no more distinct equations than its parameters, or
  not more with a pose held out: :mod:`~analysis.identification.models.design_size`)
  is never supported over a smaller one: its chi-square and held-out check are no
  evidence. It is fitted and listed, marked ``untestable`` with the reason, and the
  elimination steps to a testable class first where one of the trials is.

A class is accepted when its chi-square passes the misfit test
(P(chi2 >= observed) >= :data:`MISFIT_P`, as the joint fit's refusal).
"""

from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np

from analysis.identification.models.design_size import DesignSize, design_size
from analysis.identification.models.fit import ClassData, ClassFit, fit_class
from analysis.identification.models.names import EXTRAS, JOINTS, ModelChoice

#: BIC lead a class needs over the joint springs to replace them
BIC_MARGIN = 10.0
#: the misfit test's level (as analysis.identification.checks.plausibility.MISFIT_P)
MISFIT_P = 1e-6

RULE = (f"backward elimination from every effect the data allow; criterion BIC = chi2 + "
        f"p ln n (noise as declared); an effect stays only if the class with it has a BIC "
        f"lower by more than {BIC_MARGIN:g} and a lower held-out (leave-pose-out) chi2/nu "
        f"than the class without it, and the design can test it (more distinct equations "
        f"than parameters, also with a pose held out); the weakest goes first")


@dataclass(frozen=True)
class Selection:
    """The classes fitted (joints first) and the one chosen, with the rule applied."""

    candidates: tuple[ClassFit, ...]
    chosen: ClassFit
    auto: bool
    design: DesignSize | None = None

    @property
    def accepted(self) -> bool:
        p = self.chosen.p_value
        return bool(np.isfinite(p) and p >= MISFIT_P)

    def describe(self) -> dict:
        return {"asked": "auto" if self.auto else self.chosen.name, "chosen": self.chosen.name,
                "rule": RULE if self.auto else "as asked (--model)",
                "accepted": self.accepted, "misfit_level": MISFIT_P,
                **({"design": self.design.describe()} if self.design is not None else {}),
                "candidates": [c.describe() for c in self.candidates]}

    def untestable(self) -> tuple[ClassFit, ...]:
        """The candidates the design cannot test."""
        return tuple(c for c in self.candidates if c.untestable)


def supported(with_it: ClassFit, without: ClassFit) -> bool:
    """Does the evidence support the extra that ``with_it`` has and ``without`` lacks?"""
    if with_it.error or with_it.untestable:
        return False
    if without.error:
        return True
    return bool(with_it.bic < without.bic - BIC_MARGIN
                and with_it.heldout_chi2_nu < without.heldout_chi2_nu)


def available(data: ClassData) -> tuple[str, ...]:
    """The extras these data allow: gravity and lost motion need the robot's mass model,
    the compensator joint 2 identified."""
    mass = getattr(data.robot, "inertials", None) is not None
    return tuple(e for e in EXTRAS if not (e == "gravity" and not mass)
                 and not (e == "lost-motion" and data.gear_torques is None)
                 and not (e == "compensator" and 1 not in data.joints))


def select_model(data: ClassData, choice: ModelChoice) -> Selection:
    """Fit the classes ``choice`` asks for (auto: backward elimination; else joints and
    the one asked) and choose (auto) or take the one asked."""
    size = design_size(data.group, data.tests.w, data.tests.measured)

    def fit(extras: tuple[str, ...]) -> ClassFit:
        f = fit_class(data, extras)
        why = "" if f.error else size.untestable(f.n_params)
        return replace(f, untestable=why) if why else f

    if choice.auto:
        current = fit(available(data))
        fits = [current]
        while current.extras:
            trials = [fit(tuple(e for e in current.extras if e != drop))
                      for drop in current.extras]
            fits += trials
            weak = [t for t in trials if not supported(current, t)]
            if not weak:
                break
            # a testable class before any untestable one: the path must not run through
            # classes whose exact fits of the means only look good
            current = min(weak, key=lambda f: (bool(f.error), bool(f.untestable),
                                               f.bic if not f.error else np.inf))
            if current.error:
                break
        if () not in [f.extras for f in fits]:
            fits.append(fit(()))  # side by side with the papers' model
        fits.sort(key=lambda f: (len(f.extras), [EXTRAS.index(e) for e in f.extras]))
        return Selection(tuple(fits), current, True, size)
    joints = fit(())
    if not choice.extras:
        return Selection((joints,), joints, False, size)
    asked = fit(choice.extras)
    return Selection((joints, asked), asked, False, size)


__all__ = ["JOINTS", "RULE", "Selection", "supported", "select_model"]
