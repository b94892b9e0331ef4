"""Kinetostatics, stiffness model, identification and reports.

Everything inside is in SI units: metres, radians, newtons, newton-metres.
Degrees and millimetres appear only at the edges (files and command line),
always labelled.
"""

from analysis.errors import InputError, SingularPoseError

__all__ = ["InputError", "SingularPoseError"]
