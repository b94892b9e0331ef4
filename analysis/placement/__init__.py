"""Workpiece placement and tool-axis angle search (``campaign place``).

path: the part path file; poses: tool frames and placements; evaluate: IK,
feasibility and deflection of (placement, point, angle) triples; select: the
tool angle along the path with continuity; search: the grid search, local or on Dask.
"""
