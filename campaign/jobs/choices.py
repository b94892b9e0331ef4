"""The choices of the jobs' options (enums) and the JSON form of their results.

Shared by the faces: the command line offers these choices (``campaign.cli.common``
re-exports them for the commands), the web API reads them from the options records.
Only the standard library at import time: every command module imports them at start-up.
"""

from __future__ import annotations

import math
from enum import StrEnum
from pathlib import Path


class Method(StrEnum):
    """Estimator of the joint compliances (analysis.identification.estimate.METHODS)."""

    ols = "ols"
    wls = "wls"
    exact = "exact"


#: the estimator of ``campaign analyze`` and ``robustness`` when none is given, and the
#: Monte-Carlo trials per point; here (no numpy) so that ``--help`` can show them cheaply
DEFAULT_METHOD = "exact"
DEFAULT_TRIALS = 200


class Covariance(StrEnum):
    """Covariance of the estimate: the noise figures taken as known, or scaled by chi-square."""

    model = "model"
    residual = "residual"


class Robust(StrEnum):
    """Robust fitting of ``campaign analyze``
    (analysis.identification.estimators.irls.ROBUST_METHODS)."""

    none = "none"
    huber = "huber"
    tukey = "tukey"


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
