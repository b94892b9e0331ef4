"""Identification of the joint compliances x = 1/k from stiffness tests.

``estimate`` (``identify``: the entry point) builds a ``problem`` (the robot, tests,
noise model, joints and options as one object) and runs its stages: ``estimators/``
(OLS, WLS, exact, the robust modes, behind one interface, chosen by name),
``corrections/`` (wrench and encoder errors in variables, the linearisation bias),
``validation/`` (leave-one-pose-out), ``statistics`` and ``intervals`` (covariance,
chi-square, the reported intervals; formulas in ``uncertainty``), ``checks/`` (outliers,
noise ratio, plausibility, tool point); ``result`` holds the outcome and writes
results.json. Beside them: ``io/`` (tests import, model export), ``linalg/`` (least
squares on per-test blocks), ``streaming/`` (per-test blocks made when sliced, for large
campaigns), ``studies/`` (Monte-Carlo robustness), ``compare/`` (two campaigns),
``noise`` (the noise model) and ``poses`` (grouping tests into poses). Map:
docs/identification_code.md.
"""
