"""Leave-one-pose-out validation (crossval) and the held-out poses' check against their
total uncertainty (holdout_check).
"""
