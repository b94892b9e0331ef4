"""Errors raised for bad input: each names the file, field or argument at fault."""

from __future__ import annotations

from dataclasses import dataclass


class InputError(ValueError):
    """Bad user input (file, field, argument).

    The message names where the problem is and what was expected. The CLI
    prints it without a traceback and exits with status 2.
    """

    def __init__(self, message: str, *, where: str | None = None) -> None:
        self.where = where
        super().__init__(f"{where}: {message}" if where else message)


class SingularPoseError(InputError):
    """A quantity that needs J^-1 was asked for at a singular pose."""


@dataclass(frozen=True)
class Refusal:
    """One reason a result is refused: what the data contradict, as one sentence (its
    figures and the likely causes in the text)."""

    text: str


#: the opening of a refusal's message; the reasons follow, joined by " | "
REFUSED = "refused, the data do not support this stiffness: "
#: how a refusal's message ends: what keeps the result anyway (the command line's option)
KEEP_ANYWAY = ("; to keep the result anyway rerun with --accept-misfit (results.json and "
               "the report then say so)")


class Refused(InputError):
    """The data do not support the result: ``reasons``, one :class:`Refusal` each.

    Bad input as any :class:`InputError` (one line, exit status 2); a face that shows the
    reasons one by one reads :attr:`reasons`, never the message's text.
    """

    def __init__(self, reasons: tuple[Refusal, ...], *, where: str | None = None) -> None:
        self.reasons = tuple(reasons)
        super().__init__(REFUSED + " | ".join(r.text for r in self.reasons) + KEEP_ANYWAY,
                         where=where)

    def __reduce__(self):
        # pickled by its fields (a job's process sends it back to the server)
        return (_refused, (self.reasons, self.where))


def _refused(reasons: tuple[Refusal, ...], where: str | None) -> Refused:
    return Refused(reasons, where=where)
