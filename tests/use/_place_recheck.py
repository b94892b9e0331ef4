"""The small placement problem the re-check tests of model classes share: two points 5 cm
apart under one wrench, tool axis down, KR240-2 placed 1.6 m in front of them."""

from __future__ import annotations

import numpy as np

WRENCH = np.array([[400.0, 250.0, -2000.0, 0.0, 0.0, 20.0]] * 2)  # N, N m, tool frame
PLACEMENT = np.array([1.6, 0.0, 0.2, 0.0])  # x, y, z (m), yaw (rad)


def recheck(robot, k: np.ndarray):
    """(path details at :data:`PLACEMENT`, the wrenches in the base frame (2, 6)) of the
    two-point problem for ``robot`` with joint stiffness ``k`` (N m/rad)."""
    from analysis.placement.details import path_details
    from analysis.placement.evaluate import Problem
    from analysis.placement.poses import base_wrench

    problem = Problem(robot=robot, points=np.array([[0.0, 0.0, 0.0], [0.05, 0.0, 0.0]]),
                      axes=np.array([[0, 0, -1.0]] * 2), wrench=WRENCH,
                      angles=np.radians([0.0, 30.0]), k=k, length=0.682,
                      min_inv_kappa=0.05, margin=np.radians(2), max_step=np.radians(10),
                      objective="max", flags=((-1, -1, -1),))
    got = path_details(problem, PLACEMENT, (-1, -1, -1), np.array([0, 1]))
    return got, base_wrench(got.target[:, :3, :3], WRENCH)
