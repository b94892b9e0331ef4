"""The model classes ``campaign analyze --model`` knows: the ONE list of their names.

``joints`` is the papers' model (joint springs only, today's results). The others add
to it and combine with ``+`` (``links+lost-motion``); ``auto`` fits every combination
and chooses by evidence (:mod:`analysis.identification.models.select`).
"""

from __future__ import annotations

from dataclasses import dataclass

from analysis.errors import InputError

#: the joint-spring model (the papers')
JOINTS = "joints"
#: what each class adds to the joint springs, in the order they are reduced and reported
EXTRAS = ("gravity", "compensator", "lost-motion", "links")
#: fit every combination and choose by evidence
AUTO = "auto"
#: every name the option takes
NAMES = (JOINTS, *EXTRAS, AUTO)

DESCRIPTIONS = {
    JOINTS: "joint springs only (the papers' model)",
    "gravity": "+ the arm's weight loads the joint springs at both readings (the robot "
               "file's mass model; no extra parameter)",
    "links": "+ compliance of links 2 and 3 (6 x 6 each at their distal frames, virtual-joint "
             "model): the identifiable combinations only",
    "compensator": "+ an axis-2 compensator: its spring's preload and rate when its "
                   "geometry is known, else joint 2's compliance x2(q2) = x2 + c1 (q2 - "
                   "q2ref) + c2 (q2 - q2ref)^2",
    "lost-motion": "+ lost motion per joint: a dead band 2b travelled where the gear torque "
                   "changes sign between the reference and the loaded reading",
}


@dataclass(frozen=True)
class ModelChoice:
    """What ``--model`` asked for: ``extras`` (a sub-tuple of :data:`EXTRAS`, in that
    order; empty: joints), or ``auto``."""

    extras: tuple[str, ...] = ()
    auto: bool = False

    @property
    def name(self) -> str:
        return AUTO if self.auto else class_name(self.extras)


def class_name(extras: tuple[str, ...]) -> str:
    """The label of a class: ``joints`` or its extras joined by ``+`` in :data:`EXTRAS`
    order."""
    return "+".join(e for e in EXTRAS if e in extras) or JOINTS


def parse_model(text: str | None) -> ModelChoice:
    """``joints``, ``auto`` or extras joined by ``+`` (``joints+`` may lead); a one-line
    error naming the known names otherwise."""
    raw = (text or JOINTS).strip().lower()
    if raw == AUTO:
        return ModelChoice(auto=True)
    parts = [p.strip() for p in raw.split("+") if p.strip()]
    bad = [p for p in parts if p not in (JOINTS, *EXTRAS)]
    if bad or not parts:
        raise InputError(f"unknown model class {bad[0] if bad else raw!r}: expected "
                         f"{', '.join(NAMES)}, extras combined with '+'", where="--model")
    return ModelChoice(tuple(e for e in EXTRAS if e in parts))
