"""The simulated world with a realistic arm (issue 31): effects at zero change nothing,
the effects' readings follow analysis.kinetostatics.realistic, drifts follow the lab's
simulated time, and the shop protocol runs through the fakes."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

from analysis.errors import InputError
from analysis.kinetostatics import realistic as R
from analysis.kinetostatics.realistic_lab import realistic_lab
from campaign.acquire.instruments import lab_settings
from campaign.protocol import load_protocol
from drivers.sim.settings import LabSettings
from drivers.sim.world import SETTLED_AFTER, World

ROOT = Path(__file__).resolve().parents[2]
SHOP = ROOT / "protocols" / "kr240-2-shop.toml"
QUIET = dict(force_noise=0.0, torque_noise=0.0, tracker_noise=0.0, tracker_angle_noise=0.0,
             instruments=())
W = np.array([0.0, 2200.0, 2200.0, 200.0, 200.0, 0.0])
Q_CTRL = np.deg2rad([10.0, -60.0, 100.0, 30.0, 40.0, 10.0])


def _loaded(world: World) -> np.ndarray:
    world.move(Q_CTRL, speed=1e6)
    world.apply_load(W)
    world._t_change -= 1e6  # settled (the state is the equilibrium after SETTLED_AFTER tau)
    return world.true_tool_pose()


def test_effects_at_zero_are_the_joint_spring_world_bit_for_bit():
    clean = _loaded(World(LabSettings(**QUIET)))
    zero = World(LabSettings(**QUIET, lost_motion=(0.0,) * 6, links=(
        {"link": 2, "compliance": np.zeros((6, 6)).tolist()},)))
    assert zero.lab.active  # the realistic path, with nothing to add
    assert np.array_equal(_loaded(zero), clean)


def test_world_reading_is_the_realistic_displacement_plus_drift():
    """Reference (unloaded) and loaded tracker readings of the world with the shop
    protocol's effects differ by the realistic displacement of P and the drift over one
    load change (SETTLED_AFTER x settle_time of simulated time)."""
    settings = lab_settings(load_protocol(SHOP), None)
    for k, v in QUIET.items():
        setattr(settings, k, v)
    world = World(settings)
    world.move(Q_CTRL, speed=1e6)
    world._t_change -= 1e6
    p0 = world.tracker_point("P")
    f0 = world.sensor_wrench()
    T0 = world.true_tool_pose()
    _loaded(world)
    p1 = world.tracker_point("P")
    world.remove_load()
    world._t_change -= 1e6
    # two load changes later the unloaded F/T reading has drifted by 2 x 3 s of its rate
    f2 = world.sensor_wrench()
    assert np.allclose(f2 - f0, np.asarray(settings.ft_drift) * 2 * SETTLED_AFTER
                       * settings.settle_time, rtol=0, atol=1e-9)
    drift = np.asarray(settings.tracker_drift) * SETTLED_AFTER * settings.settle_time
    q = world.robot.from_controller(Q_CTRL)
    d = R.displacement(world.robot, world.lab, world.k, q[None], np.zeros(6), W)[0]
    Rbt = world.base_in_tracker[:3, :3]
    assert np.max(np.abs((p1 - p0) - (Rbt @ d[:3] + drift))) < 1e-12
    assert np.linalg.norm(drift) == pytest.approx(5.0e-6, rel=0.01)  # 5 um per test
    # the reference reading is the sagged arm on its gravity flanks, not the rigid pose
    rigid = world.nominal_tool_pose()
    assert np.linalg.norm(T0[:3, 3] - rigid[:3, 3]) > 1e-4


def test_shop_protocol_turns_every_effect_on():
    protocol = load_protocol(SHOP)
    lab = protocol.lab
    assert lab["gravity"] == "on" and len(lab["links"]) == 2
    assert lab["lost_motion"] == (2e-4, 2e-4, 2e-4, 4e-4, 4e-4, 4e-4)
    world_lab = realistic_lab(World(lab_settings(protocol, None)).robot,
                              lab_settings(protocol, None).effects())
    assert world_lab.active and world_lab.compensator is not None
    assert "ASSUMED" in SHOP.read_text()


@pytest.mark.parametrize("table, message", [
    ("[[fake_lab.links]]\nlink = 2\ncompliance = [[1, 2, 0, 0, 0, 0], [0, 1, 0, 0, 0, 0], "
     "[0, 0, 1, 0, 0, 0], [0, 0, 0, 1, 0, 0], [0, 0, 0, 0, 1, 0], [0, 0, 0, 0, 0, 1]]\n",
     "symmetric"),
    ("[[fake_lab.links]]\nlink = 2\nbeam = { E_Pa = 2e11, G_Pa = 8e10, width_m = 0.2, "
     "wall_m = 0.01, I_m4 = 1e-4, J_m4 = 1e-4, A_m2 = 1e-2 }\n", "either width_m"),
    ("lost_motion_rad = [2e-4, 2e-4, 2e-4, 4e-4, 4e-4, 0.3]\n", "implausible"),
    ('gravity = "yes"\n', "gravity"),
])
def test_bad_effects_are_one_line_errors(tmp_path, table, message):
    text = (ROOT / "protocols" / "kr240-2.toml").read_text()
    path = tmp_path / "p.toml"
    # keys go right after the [fake_lab] header, tables at the end
    if table.startswith("["):
        path.write_text(text + "\n" + table)
    else:
        path.write_text(text.replace("[fake_lab]\n", "[fake_lab]\n" + table))
    with pytest.raises(InputError, match=message) as err:
        load_protocol(path)
    assert "\n" not in str(err.value)


def test_lost_motion_needs_a_mass_model():
    robot = World(LabSettings(**QUIET, robot="irb6640",
                              true_joint_stiffness=(1e6,) * 6)).robot
    with pytest.raises(InputError, match="no mass model"):
        realistic_lab(robot, {"lost_motion": (2e-4,) * 6})


@pytest.mark.timeout(300)
def test_shop_protocol_through_the_fakes(tmp_path):
    """acquire --fake of the shop protocol (real drivers over loopback, one repeat): the
    run completes and records the lab's effects in its metadata."""
    from tests.acquire.conftest import plan_and_acquire

    run = plan_and_acquire(load_protocol(SHOP), tmp_path, time_scale=200.0, candidates=500)
    meta = json.loads((run / "metadata.json").read_text())
    assert meta["fake_lab"]["gravity"] == "on"
    assert meta["fake_lab"]["lost_motion"] == [2e-4, 2e-4, 2e-4, 4e-4, 4e-4, 4e-4]
    rows = (run / "tests.csv").read_text().splitlines()
    assert len(rows) == 1 + 5


@pytest.mark.timeout(300)
def test_preloaded_shop_run_records_the_reference_wrench(tmp_path):
    """acquire --fake with preload_fraction 0.2: the reference readings are taken under
    the preload, tests.csv gives its measured wrench (base frame) beside the loaded one,
    and the analysis fits it (exact: the two equilibria; wls: the wrench difference)."""
    import subprocess
    import sys

    import pandas as pd

    from tests.acquire.conftest import plan_and_acquire

    text = SHOP.read_text().replace('method = "cable-pulley"\n',
                                    'method = "cable-pulley"\npreload_fraction = 0.2\n')
    path = tmp_path / "shop-preload.toml"
    path.write_text(text)
    run = plan_and_acquire(load_protocol(path), tmp_path, time_scale=200.0, candidates=500)
    tests = pd.read_csv(run / "tests.csv")
    ref = tests[["fx_ref_N", "fy_ref_N", "fz_ref_N", "mx_ref_Nm", "my_ref_Nm", "mz_ref_Nm"]]
    loaded = tests[["fx_N", "fy_N", "fz_N", "mx_Nm", "my_Nm", "mz_Nm"]]
    # 0.2 x the loaded wrench, to the F/T noise and the sag's rotation of the sensor frame
    err = np.abs(ref.to_numpy() - 0.2 * loaded.to_numpy())
    assert np.all(err[:, :3] < 0.01 * 2200 + 3.0) and np.all(err[:, 3:] < 3.0)
    phases = (run / "samples.jsonl").read_text()
    assert '"reference_before"' in phases and '"reference_after"' in phases
    meta = json.loads((run / "metadata.json").read_text())
    assert meta["reference_wrench"]["preload_fraction"]["eq22"] == 0.2

    def analyze(*extra):
        return subprocess.run([sys.executable, "-m", "campaign", "analyze", str(run),
                               "--accept-misfit", "--json", "--force", *extra],
                              capture_output=True, text=True, cwd=ROOT, timeout=240)

    for method in ("exact", "wls"):
        done = analyze("--method", method, "--out", str(tmp_path / method))
        assert done.returncode == 0, done.stderr
        assert any("preload" in t for t in json.loads(done.stdout)["warnings"])


@pytest.mark.timeout(300)
def test_preloaded_readings_are_the_applied_wrenches(tmp_path):
    """acquire --fake with preload_fraction 0.3 on a lost-motion lab (gravity deciding the
    flanks, no sag): tests.csv's loaded and reference wrenches are the applied ones (the
    plan's, and 0.3 x it), base frame, to the F/T noise. The sensor frame is turned by the
    tracker's rotation measured from the UNLOADED pose: taking the preloaded reference as
    the encoders' pose turned both wrenches (and the displacement) by the preload's
    deflection, 2-5 mrad here (6-14 N off on a 3111 N load; k3 +0.5 % in the fit)."""
    import pandas as pd

    from tests.acquire.conftest import plan_and_acquire

    head = SHOP.read_text().split("\n[fake_lab]\n")[0].replace(
        'method = "cable-pulley"\n', 'method = "cable-pulley"\npreload_fraction = 0.3\n')
    lab = ("\n[fake_lab]\ntrue_joint_stiffness = [1409800, 400760, 935280, 360000, 370000, "
           "380000]\nseed = 2\ntime_scale = 50\nnoise = { translation_um = 30, rotation_urad "
           "= 20, force_N = 0.5, torque_N_m = 0.05 }\ngravity = \"flanks\"\n"
           "lost_motion_rad = [2e-4, 2e-4, 2e-4, 4e-4, 4e-4, 4e-4]\n")
    path = tmp_path / "lost-motion-preload.toml"
    path.write_text(head + lab)
    run = plan_and_acquire(load_protocol(path), tmp_path, time_scale=200.0, candidates=500)
    tests = pd.read_csv(run / "tests.csv")
    plan = pd.read_csv(run / "plan.csv").set_index("test")
    applied = plan.loc[tests["test_id"], ["fx_N", "fy_N", "fz_N", "mx_N_m", "my_N_m",
                                          "mz_N_m"]].to_numpy()
    loaded = tests[["fx_N", "fy_N", "fz_N", "mx_Nm", "my_Nm", "mz_Nm"]].to_numpy()
    ref = tests[["fx_ref_N", "fy_ref_N", "fz_ref_N", "mx_ref_Nm", "my_ref_Nm",
                 "mz_ref_Nm"]].to_numpy()
    for got, want in ((loaded, applied), (ref, 0.3 * applied)):
        off = np.abs(got - want)
        # 0.5 N per reading; the lost-motion offsets (<= 0.2 mrad) turn 3111 N by <= 0.7 N
        assert np.all(off[:, :3] < 3.0) and np.all(off[:, 3:] < 0.3), off.max(axis=0)
