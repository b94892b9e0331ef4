"""The choices of the jobs' options (enums) and the JSON form of their results.

Shared by the faces: the command line offers these choices (``campaign.cli.terminal``
re-exports them for the commands), the web API reads them from the options records.
Only the standard library at import time: every command module imports them at start-up.
"""

from __future__ import annotations

import math
from enum import StrEnum
from pathlib import Path

from analysis.choices import DEFAULT_METHOD as DEFAULT_METHOD  # the faces read it from here
from analysis.choices import METHODS, ROBUST_MODES


def _choices(name: str, values: tuple[str, ...], doc: str) -> type[StrEnum]:
    """A StrEnum whose members are ``values`` (member name = value, ``-`` as ``_``)."""
    enum = StrEnum(name, [(v.replace("-", "_"), v) for v in values], module=__name__)
    enum.__doc__ = doc
    return enum


#: Estimator of the joint compliances (the names of :data:`analysis.choices.METHODS`).
Method = _choices("Method", METHODS, "Estimator of the joint compliances "
                  "(analysis.choices.METHODS).")

#: the estimator of ``campaign analyze`` and ``robustness`` when none is given, and the
#: Monte-Carlo trials per point; standard library only, so that ``--help`` shows them cheaply
DEFAULT_TRIALS = 200


class Covariance(StrEnum):
    """Covariance of the estimate: the noise figures taken as known, or scaled by chi-square."""

    model = "model"
    residual = "residual"


#: Robust fitting of ``campaign analyze`` (the names of :data:`analysis.choices.ROBUST_MODES`).
Robust = _choices("Robust", ROBUST_MODES, "Robust fitting of ``campaign analyze`` "
                  "(analysis.choices.ROBUST_MODES).")


class Strategy(StrEnum):
    """Test selection of ``campaign plan`` (campaign.planning.planner.STRATEGIES)."""

    worst_joint = "worst-joint"
    weighted = "weighted"
    d_optimal = "d-optimal"
    e_optimal = "e-optimal"
    zones_random = "zones-random"


class TableFormat(StrEnum):
    parquet = "parquet"
    csv = "csv"


class WrenchFrame(StrEnum):
    base = "base"
    tool = "tool"


class Objective(StrEnum):
    max = "max"
    rms = "rms"
    compliance = "compliance"


class Program(StrEnum):
    auto = "auto"
    krl = "krl"
    urscript = "urscript"
    rapid = "rapid"
    fanuc_ls = "fanuc-ls"
    none = "none"


class SimFormat(StrEnum):
    """Simulator description written by ``campaign export`` (analysis.export.sim_model)."""

    mjcf = "mjcf"
    urdf = "urdf"
    sdf = "sdf"


class RotationSource(StrEnum):
    reflectors = "reflectors"
    probe = "probe"


def json_ready(value):
    """``value`` with numpy scalars/arrays as Python numbers/lists and NaN/inf as None."""
    if isinstance(value, dict):
        return {str(k): json_ready(v) for k, v in value.items()}
    if isinstance(value, (list, tuple)):
        return [json_ready(v) for v in value]
    if hasattr(value, "tolist"):
        return json_ready(value.tolist())
    if isinstance(value, float) and not math.isfinite(value):
        return None
    if isinstance(value, Path):
        return str(value)
    return value
