"""The estimators by name: ``estimator("exact")``, ``estimator("wls", robust="tukey")``."""

from __future__ import annotations

from types import MappingProxyType

from analysis.identification.estimators.exact import Exact
from analysis.identification.estimators.ols import OLS
from analysis.identification.estimators.robust_mode import MODES, RobustMode
from analysis.identification.estimators.wls import WLS

#: the Gaussian fits (``--method``)
GAUSSIAN = MappingProxyType({"ols": OLS, "wls": WLS, "exact": Exact})
#: the robust modes (``--robust``), each around a Gaussian fit: name -> what it does
ROBUST = MODES


def estimator(method: str, robust: str = "none"):
    """The estimator ``method`` (ols, wls, exact), under the robust mode ``robust`` unless
    "none"; names checked by :meth:`~analysis.identification.problem.IdentifyOptions.check`."""
    if robust == "none":
        return GAUSSIAN[method]()
    base = GAUSSIAN[method](final_pass_sums=False) if method == "exact" else GAUSSIAN[method]()
    return RobustMode(base, robust)
