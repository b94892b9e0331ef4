"""The named choices of the analysis, each listed once: estimators, robust modes, the
robot files' geometry conventions.

Every other list of these names derives from here: the identification's checks, the
jobs' option enums (:mod:`campaign.jobs.choices`), the command line's ``--help``, the web
API's request models and the page's menus (read from the API's OpenAPI document).
``tests/project/test_layers.py`` checks that no other module spells a list again.
Only the standard library: the command line imports it at start-up.
"""

from __future__ import annotations

#: the estimators of the joint compliances (``--method``), in the order menus show them:
#: ordinary and weighted least squares on the linearised model, and the exact nonlinear fit
METHODS: tuple[str, ...] = ("ols", "wls", "exact")
#: the estimators that fit the linearised model (their linearisation bias is corrected)
LINEARISED_METHODS: tuple[str, ...] = ("ols", "wls")
#: the estimator used when none is given (``campaign analyze``, ``robustness``, the GUI)
DEFAULT_METHOD = "exact"

#: the robust modes of the fit (``--robust``): none, or IRLS with Huber's or Tukey's weights
ROBUST_MODES: tuple[str, ...] = ("none", "huber", "tukey")
#: the robust modes that re-weight (every mode but "none")
REWEIGHTING_MODES: tuple[str, ...] = ROBUST_MODES[1:]

#: the geometry conventions a robot file may declare (``convention``): the chain in
#: standard (Denavit-Hartenberg) or modified (Khalil-Kleinfinger) DH parameters
GEOMETRY_CONVENTIONS: tuple[str, ...] = ("standard_dh", "modified_dh")
