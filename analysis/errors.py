"""Errors raised for bad input: each names the file, field or argument at fault."""

from __future__ import annotations


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
