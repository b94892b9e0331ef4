"""Checks of a fit: outliers, the noise ratio, the plausibility refusals, the tool point.
"""
