"""Identification of the joint compliances x = 1/k from stiffness tests.

Modules, one step each: ``measurements`` (the tests as arrays, CSV import),
``noise`` (measurement noise model), ``linear_model`` (the paper's A x = d),
``lsq`` and ``batch_lsq`` (OLS/WLS), ``gauss_newton`` and ``exact_fit`` (the
nonlinear equilibrium fit), ``uncertainty`` (intervals), ``crossval``
(leave-one-pose-out), ``estimate`` (the ``identify`` entry point choosing among
them), ``result`` (results.json) and ``robustness`` (Monte-Carlo study).
"""
