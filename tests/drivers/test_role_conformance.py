"""Every registered driver fills its role, and every fake of the lab works with its driver."""

from __future__ import annotations

import inspect

import numpy as np
import pytest

from drivers.readings import JointAngles, Point, Pose, Wrench
from drivers.registry import BUILTIN, load_driver_class, open_driver
from drivers.roles import ForceTorqueSensor, LoadApplicator, PoseTracker, RobotController

pytestmark = pytest.mark.timeout(60)
ROLES = (RobotController, ForceTorqueSensor, PoseTracker, LoadApplicator)


@pytest.mark.parametrize("name", sorted(BUILTIN))
def test_builtin_driver_is_a_concrete_role(name):
    cls = load_driver_class(name)
    assert issubclass(cls, ROLES), name
    assert not inspect.isabstract(cls), (name, cls.__abstractmethods__)


@pytest.mark.parametrize("name", ["ati-netft", "robotiq-ft300", "ati-netcan", "emscon",
                                  "geocom", "kuka-kvp", "lab-load"])
def test_lab_fake_speaks_with_its_driver(lab, name):
    world = lab.world
    reflectors = {k: v for k, v in world.settings.reflectors.items() if k != "P"}
    extra = {"reflectors": reflectors, "aim": world.aim} if name in ("emscon", "geocom") else {}
    drv = open_driver(name, lab.addresses[name], **extra)
    with drv:
        desc = drv.describe()
        assert desc["address"] == lab.addresses[name] and desc["driver"] == type(drv).__name__
        if isinstance(drv, ForceTorqueSensor):
            w = drv.read_wrench(10)
            assert isinstance(w, Wrench) and w.value.shape == (6,) and desc["unit"] == "N, N m"
            assert all(isinstance(s, Wrench) for s in drv.stream(3))
        elif isinstance(drv, PoseTracker):
            assert isinstance(drv.measure_point("P"), Point)
            pose = drv.measure_pose()
            assert isinstance(pose, Pose) and pose.value.shape == (4, 4)
            assert desc["unit"] == "m"
        elif isinstance(drv, RobotController):
            q = drv.read_joints()
            assert isinstance(q, JointAngles) and q.unit == "rad" and q.value.shape == (6,)
            assert desc["joint_unit"] == "rad"
        else:
            assert isinstance(drv, LoadApplicator)
            from drivers.roles import LoadCase

            drv.apply(LoadCase("x", np.array([0, 0, -10.0, 0, 0, 0])))
            np.testing.assert_allclose(world.load(), [0, 0, -10, 0, 0, 0])
            drv.remove()
            assert desc["frame"] == "robot base"
