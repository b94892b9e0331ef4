"""Bias corrections of the estimators: the wrench noise in the regressor (wrench_eiv), the
encoder noise in J (encoder_eiv), the linear model's linearisation bias (linear_bias).
"""
