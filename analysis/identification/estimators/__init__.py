"""The estimators of the joint compliances, one module each, behind one interface.

``base`` (the :class:`~analysis.identification.estimators.base.Estimator` protocol and
its outcome, :class:`~analysis.identification.estimators.base.EstimatorFit`), ``ols``,
``wls``, ``exact`` (the Gaussian fits), ``robust_mode`` (the robust modes huber and
tukey, IRLS around ols, wls or exact), ``registry`` (an estimator by name).
"""
