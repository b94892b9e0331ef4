"""The planner's gear-flank count (campaign.planning.flanks) against the simulated lab's
lost motion, and the preload fraction that keeps every joint on one flank."""

from __future__ import annotations

import numpy as np
import pytest

from analysis.kinetostatics import realistic as R
from analysis.model.gravity import gravity_torques
from analysis.model.kinematics import pin_jacobian
from analysis.model.robots import load_robot
from campaign.planning.flanks import flank_changes, keeping_preload

BAND = np.array([2e-4, 2e-4, 2e-4, 4e-4, 4e-4, 4e-4])


@pytest.fixture(scope="module")
def setup():
    robot = load_robot("kr240-2")
    rng = np.random.default_rng(7)
    lo, hi = np.maximum(robot.lower, -np.pi), np.minimum(robot.upper, np.pi)
    q = rng.uniform(lo, hi, (40, 6))
    w = np.concatenate([rng.normal(0, 2000, (40, 3)), rng.normal(0, 200, (40, 3))], axis=1)
    return robot, q, w


def test_flips_are_the_simulated_labs_lost_motion_steps(setup):
    """A joint the planner counts travels its band in the lab (the output's offset from
    the motor side changes between the reference and the loaded state), and no other."""
    robot, q, w = setup
    lab = R.RealisticLab(lost_motion=BAND, gravity="flanks")
    w_ref = 0.1 * w
    step = (R.lost_motion_offset(robot, lab, q, w)
            - R.lost_motion_offset(robot, lab, q, w_ref))
    planned = flank_changes(robot, q, w, w_ref)
    assert np.array_equal(planned, step != 0)
    assert planned.sum() > 10  # the random loads do flip joints
    # by hand (Pinocchio's J, the gravity torques): sign of J^T w - g at each reading
    for p in range(5):
        g = gravity_torques(robot, q[p][None])[0]
        J = pin_jacobian(robot, q[p])
        assert np.array_equal(planned[p], np.sign(J.T @ w_ref[p] - g) != np.sign(J.T @ w[p] - g))


def test_unloaded_reference_flips_joint_1_under_a_lateral_load():
    """Axis 1 is vertical: no gravity torque, so the unloaded reference leaves it mid-band
    and any load with a torque about it moves it (issue 31)."""
    robot = load_robot("kr240-2")
    q = robot.from_controller(np.deg2rad([0.0, -90.0, 90.0, 0.0, 30.0, 0.0]))[None]
    w = np.array([[0.0, 2200.0, 0.0, 0.0, 0.0, 0.0]])
    assert flank_changes(robot, q, w, np.zeros((1, 6)))[0, 0]
    assert not flank_changes(robot, q, w, 0.05 * w)[0, 0]


def test_keeping_preload_is_the_threshold(setup):
    """Above the returned fraction no joint changes flank; just below it one does."""
    robot, q, w = setup
    f = keeping_preload(robot, q, w)
    assert np.all(np.isfinite(f)) and np.all((f >= 0) & (f < 1))
    above = (f * (1 + 1e-9) + 1e-12)[:, None] * w
    assert not flank_changes(robot, q, w, above).any()
    some = f > 1e-6
    below = (f * (1 - 1e-6))[:, None] * w
    assert np.all(flank_changes(robot, q[some], w[some], below[some]).any(axis=1))


def test_planner_keeps_flanks_with_a_preload_and_counts_the_labs_flips(tmp_path):
    """Lost-motion lab (KR240-2, gravity flanks): with an unloaded reference every planned
    test flips joints (joint 1 at least); with preload_fraction 0.3 the planner drops the
    flipping candidates and its plan flips none. Its count is the simulated lab's: the
    lost-motion offsets of the lab built from the protocol change on exactly those joints."""
    from pathlib import Path

    from analysis.kinetostatics.realistic_lab import realistic_lab
    from campaign.planning.plan_output import summary_dict
    from campaign.planning.planner import make_plan
    from campaign.protocol import load_protocol

    root = Path(__file__).resolve().parents[2]
    text = (root / "protocols" / "kr240-2.toml").read_text().replace(
        "[fake_lab]\n", '[fake_lab]\ngravity = "flanks"\n'
        "lost_motion_rad = [2e-4, 2e-4, 2e-4, 4e-4, 4e-4, 4e-4]\n")
    counts = {}
    for f in (0.0, 0.3):
        path = tmp_path / f"lm-{f}.toml"
        path.write_text(text.replace('method = "cable-pulley"\n',
                                     f'method = "cable-pulley"\npreload_fraction = {f}\n'))
        protocol = load_protocol(path)
        plan = make_plan(protocol, candidates=1000)
        flanks_summary = summary_dict(plan)["gear_flanks"]
        q = plan.candidates.q[plan.chosen.pose]
        w = protocol.wrenches()[plan.chosen.case]
        w_ref = protocol.reference_wrenches()[plan.chosen.case]
        lab = realistic_lab(plan.robot, protocol.lab)
        step = (R.lost_motion_offset(plan.robot, lab, q, w)
                - R.lost_motion_offset(plan.robot, lab, q, w_ref))
        assert flanks_summary["changes"] == int(np.sum(step != 0))
        counts[f] = flanks_summary["changes"]
    assert counts[0.0] >= len(plan.chosen.pose)  # joint 1 flips in every test unloaded
    assert counts[0.3] == 0


def test_the_shop_plan_flips_fewer_gears_than_the_flank_blind_one(monkeypatch):
    """protocols/kr240-2-shop.toml (lost motion, unloaded references: joints 1 and 6 carry
    no gravity torque and flip in every test): the planner's design changes fewer flanks
    than the same planner blind to them, its worst relative se within the tolerance."""
    from pathlib import Path

    from campaign.planning import planner
    from campaign.protocol import load_protocol

    shop = load_protocol(Path(__file__).resolve().parents[2] / "protocols" / "kr240-2-shop.toml")

    def flips(plan):
        q = plan.candidates.q[plan.chosen.pose]
        return int(flank_changes(plan.robot, q, shop.wrenches()[plan.chosen.case],
                                 shop.reference_wrenches()[plan.chosen.case]).sum())

    chosen = planner.make_plan(shop, candidates=2000)
    monkeypatch.setattr(planner, "_flank_counts", lambda *a: None)
    blind = planner.make_plan(shop, candidates=2000)
    assert flips(chosen) < flips(blind), (flips(chosen), flips(blind))
    worst = [float(np.max(p.chosen.se / p.k_prior)) for p in (chosen, blind)]
    assert worst[0] <= planner.FLANK_SE_TOLERANCE * worst[1]


def test_link_alias_is_the_joint_only_fits_error():
    """The k error the planner predicts from the shop's assumed link compliances equals
    the error of a weighted joint-only fit of the realistic lab's noiseless displacement
    (links 2 and 3 alone), to the model's nonlinearity (compliances: dx/x = -dk/k)."""
    from pathlib import Path

    from analysis.identification.estimate import identify
    from analysis.identification.io.measurements import TestArrays
    from analysis.identification.noise import NoiseModel
    from analysis.identification.studies.robustness import sample_poses
    from analysis.kinetostatics.realistic_lab import realistic_lab
    from campaign.planning.link_alias import link_alias, protocol_links
    from campaign.protocol import load_protocol

    robot = load_robot("kr240-2")
    shop = load_protocol(Path(__file__).resolve().parents[2] / "protocols" / "kr240-2-shop.toml")
    links = protocol_links(shop, robot)
    assert [lc.link for lc in links] == [2, 3]
    q = np.repeat(sample_poses(robot, 6, np.random.default_rng(5), min_inverse_condition=0.3),
                  3, axis=0)
    w = np.tile(shop.wrenches()[:3], (6, 1))
    k = robot.nominal_stiffness
    sigma = np.array([30e-6] * 3 + [20e-6] * 3)
    d = R.displacement(robot, realistic_lab(robot, {"links": shop.fake_lab.effects()["links"]}),
                       k, q, np.zeros(6), w)
    m = len(q)
    tests = TestArrays(pose=np.array([f"P{i // 3}" for i in range(m)]), q=q, w=w, d=d,
                       measured=np.ones((m, 6), bool), line=np.arange(m) + 2)
    noise = NoiseModel(translation_sigma_override=30e-6, rotation_sigma_override=20e-6,
                       force_sigma=0.0, moment_sigma=0.0, joint_sigma_override=0.0)
    fit = identify(robot, tests, "wls", noise=noise, validate=False)
    alias = link_alias(robot, q, w, k, sigma, links)
    assert np.max(np.abs(alias)) > 0.05  # the links matter at these poses
    assert np.allclose(fit.x * k - 1, -alias, atol=0.01 + 0.05 * np.abs(alias))
