"""Per-test blocks made when sliced: the large-campaign form of J, the design, the
covariances.
"""
