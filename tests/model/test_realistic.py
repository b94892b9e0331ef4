"""The realistic arm's physics (analysis.kinetostatics.realistic), each effect against an
independent computation from its equations, and every effect at zero giving today's
joint-spring numbers bit for bit."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pinocchio as pin
import pytest

from analysis.kinetostatics import realistic as R
from analysis.kinetostatics.equilibrium import displacement_screw
from analysis.model.gravity import gravity_torques
from analysis.model.kinematics import pin_jacobian, pin_tool_pose, pose_difference
from analysis.model.robots import load_robot


@pytest.fixture(scope="module")
def kr240():
    return load_robot("kr240-2")


def _poses(robot):
    return robot.from_controller(np.deg2rad([[0.0, -90.0, 90.0, 0.0, 30.0, 0.0],
                                             [20.0, -60.0, 100.0, 30.0, 40.0, 10.0],
                                             [-35.0, -40.0, 60.0, -80.0, -50.0, 120.0]]))


W = np.array([3000.0, -2000.0, 1500.0, 100.0, -200.0, 300.0])


def test_no_effect_is_todays_model_bit_for_bit(kr240):
    q = _poses(kr240)
    k = kr240.nominal_stiffness
    today = displacement_screw(kr240, q, k, W)
    for lab in (R.RealisticLab(), R.RealisticLab(lost_motion=np.zeros(6)),
                R.RealisticLab(lost_motion=np.zeros(6), gravity="flanks")):
        assert np.array_equal(R.displacement(kr240, lab, k, q, np.zeros(6), W), today)
    assert not R.RealisticLab().active


def _pin_distal(robot, q, link):
    """Link ``link``'s distal frame by Pinocchio: joint link's placement times joint
    link+1's fixed placement."""
    data = robot.model.createData()
    pin.forwardKinematics(robot.model, data, q)
    return (data.oMi[link] * robot.model.jointPlacements[link + 1]).homogeneous


def _virtual_chain_jacobian(robot, q, link, h=1e-7):
    """J_l by finite differences of a chain with six virtual joints inserted at link's
    distal frame D: P(eps) = D Exp(eps) D^-1 P, eps = [t; r] in D's axes."""
    D = _pin_distal(robot, q, link)
    P = pin_tool_pose(robot, q)
    rel = np.linalg.inv(D) @ P
    J = np.zeros((6, 6))
    for i in range(6):
        cols = []
        for sgn in (-1.0, 1.0):
            eps = np.zeros(6)
            eps[i] = sgn * h
            E = np.eye(4)
            E[:3, :3] = pin.exp3(eps[3:])
            E[:3, 3] = eps[:3]
            cols.append(D @ E @ rel)
        J[:, i] = pose_difference(cols[0], cols[1]) / (2 * h)
    return J


def test_link_compliance_against_a_chain_with_virtual_joints(kr240):
    q = _poses(kr240)
    rng = np.random.default_rng(4)
    A = rng.normal(size=(6, 6))
    C2 = (A @ A.T) * 1e-9
    C3 = np.diag([1e-9, 2e-9, 3e-9, 4e-9, 5e-9, 6e-9])
    lab = R.RealisticLab(links=(R.LinkCompliance(2, C2), R.LinkCompliance(3, C3)))
    twist = R.link_twist(kr240, lab, q, W)
    for p in range(len(q)):
        J2 = _virtual_chain_jacobian(kr240, q[p], 2)
        J3 = _virtual_chain_jacobian(kr240, q[p], 3)
        expected = J2 @ C2 @ J2.T @ W + J3 @ C3 @ J3.T @ W
        assert np.max(np.abs(twist[p] - expected)) < 1e-6 * np.max(np.abs(expected))
    # the measured displacement adds the links' twist, at the joints' equilibrium, to the
    # joints' displacement (linear superposition, to the second order of the rotations)
    k = kr240.nominal_stiffness
    d = R.displacement(kr240, lab, k, q, np.zeros(6), W)
    joints = displacement_screw(kr240, q, k, W)
    at_equilibrium = R.link_twist(kr240, lab, q + R.joint_deflection(kr240, lab, k, q, W), W)
    diff = d - joints - at_equilibrium
    assert np.max(np.abs(diff[:, :3])) < 1e-12
    # rotations compose: the rotation vectors add up to the BCH term |phi x psi| / 2
    bch = 0.5 * np.linalg.norm(joints[:, 3:], axis=1) * np.linalg.norm(at_equilibrium[:, 3:],
                                                                        axis=1)
    assert np.all(np.linalg.norm(diff[:, 3:], axis=1) <= 1.05 * bch + 1e-15)


def test_beam_compliance_against_a_chain_of_segments():
    """A cantilever cut into many rigid segments joined by rotational springs EI/ds bends
    like the Euler-Bernoulli beam: tip deflection and slope under a tip force and moment."""
    L, E, G = 1.15, 2.1e11, 8.1e10
    I, J, A = R.box_section(0.30, 0.012)
    assert I == pytest.approx((0.30**4 - 0.276**4) / 12)
    C = R.beam_compliance(L, E, G, I, J, A)
    m = 4000
    ds = L / m
    s = (np.arange(m) + 0.5) * ds  # spring positions
    F, M = 1000.0, 300.0
    # force F along y at the tip, moment M about z: bending moment at s is F (L - s) + M
    kappa = (F * (L - s) + M) / (E * I) * ds
    slope = kappa.sum()
    deflection = np.sum(kappa * (L - s))
    assert C[1, 1] * F + C[1, 5] * M == pytest.approx(deflection, rel=1e-6)
    assert C[5, 1] * F + C[5, 5] * M == pytest.approx(slope, rel=1e-6)
    # force along z: the tip turns about -y
    assert C[4, 2] * F == pytest.approx(-np.sum(F * (L - s) / (E * I) * ds), rel=1e-6)
    assert C[0, 0] == pytest.approx(L / (E * A)) and C[3, 3] == pytest.approx(L / (G * J))
    assert np.allclose(C, C.T)


def test_lost_motion_step_is_the_band_on_the_flipped_joints(kr240):
    """Rigid joints (k huge): the displacement is the pose change of the output angles
    moving from mid/flank to flank, half a band times the change of sign of the gear torque
    (J^T w - g, by Pinocchio), joint by joint."""
    q = _poses(kr240)
    k = np.full(6, 1e15)
    band = np.array([2e-4, 2e-4, 2e-4, 4e-4, 4e-4, 4e-4])
    lab = R.RealisticLab(lost_motion=band, gravity="flanks")
    d = R.displacement(kr240, lab, k, q, np.zeros(6), W)
    flips = 0
    for p in range(len(q)):
        g = gravity_torques(kr240, q[p][None])[0]
        t_ref = -g
        t_load = pin_jacobian(kr240, q[p]).T @ W - g
        s_ref = 0.5 * band * np.where(np.abs(t_ref) < 1e-6, 0.0, np.sign(t_ref))
        s_load = 0.5 * band * np.sign(t_load)
        flips += int(np.sum(s_ref != s_load))
        expected = pose_difference(pin_tool_pose(kr240, q[p] + s_ref),
                                   pin_tool_pose(kr240, q[p] + s_load))
        assert np.max(np.abs(d[p] - expected)) < 1e-9
    assert flips >= 3  # the loads do flip joints (joint 1 at least, no gravity torque)


def test_compensator_torque_by_hand():
    """Axis z, spring from a = (-0.3, 0, 0) on the base to b = r (cos q, sin q, 0) on the
    arm: lever arm of the spring line about the axis = |a x b| / L."""
    robot = load_robot("kr240-2")
    comp = R.compensator_for(robot, 1, [-0.3, 0.0, 0.0], [0.2, 0.0, 0.0], 2e5, 5e3)
    q = np.linspace(robot.lower[1], robot.upper[1], 7)
    tau, dtau = R.compensator_torque(comp, q)
    axis = robot.chain.axes[1]
    assert np.allclose(axis, [0, 0, 1])
    b = 0.2 * np.stack([np.cos(q), np.sin(q), np.zeros_like(q)], axis=-1)
    L = np.hypot(b[:, 0] + 0.3, b[:, 1])
    # longest spring over the range: q = 0 is in [-146, 0] deg (b farthest from a)
    assert comp.extended_length == pytest.approx(0.5)
    force = 5e3 + 2e5 * (0.5 - L)
    # torque of the force pushing b away from a: (b x F u)_z
    u = (b - np.array([-0.3, 0.0, 0.0])) / L[:, None]
    expected = force * (b[:, 0] * u[:, 1] - b[:, 1] * u[:, 0])
    assert np.allclose(tau, expected, rtol=1e-12, atol=1e-9)
    h = 1e-6
    fd = (R.compensator_torque(comp, q + h)[0] - R.compensator_torque(comp, q - h)[0]) / (2 * h)
    assert np.allclose(dtau, fd, rtol=1e-6, atol=1e-3)


def test_equilibrium_with_gravity_and_compensator(kr240):
    """At the solution, K dq = J(theta)^T w - g(theta) + tau_c(theta) (Pinocchio's J)."""
    q = _poses(kr240)
    k = kr240.nominal_stiffness
    comp = R.compensator_for(kr240, 1, [-0.3, 0.0, 0.05], [0.2, 0.1, 0.0], 2e5, 5e3)
    lab = R.RealisticLab(compensator=comp, gravity="on")
    dq = R.joint_deflection(kr240, lab, k, q, W)
    for p in range(len(q)):
        th = q[p] + dq[p]
        rhs = pin_jacobian(kr240, th).T @ W - gravity_torques(kr240, th[None])[0]
        rhs[1] += R.compensator_torque(comp, th[1:2])[0][0]
        assert np.max(np.abs(k * dq[p] - rhs)) < 1e-7 * np.max(np.abs(rhs))


def test_displacement_cases_are_each_cases_own_call_bit_for_bit(kr240):
    """The batched finite-difference evaluation (one Newton loop for C cases, each frozen
    when its own poses converge) gives each case exactly its own displacement() call,
    with gravity, with the compensator's spring per case, and with both."""
    q = _poses(kr240)
    k0 = kr240.nominal_stiffness
    comp = R.compensator_for(kr240, 1, [-0.3, 0.0, 0.05], [0.2, 0.1, 0.0], 2e5, 5e3)
    rng = np.random.default_rng(7)
    ks = k0 * (1.0 + 0.2 * rng.random((4, 6)))  # different Newton iteration counts
    springs = np.array([[5e3, 2e5], [8e3, 1e5], [2e3, 3e5], [5e3, 2e5 + 10.0]])
    w_ref = np.array([100.0, 0.0, -300.0, 0.0, 20.0, 0.0])
    for gravity, spr in (("on", None), ("off", springs), ("on", springs)):
        lab = R.RealisticLab(gravity=gravity, compensator=None if spr is None else comp)
        got = R.displacement_cases(kr240, lab, ks, q, w_ref, W, spr)
        assert got.shape == (4, len(q), 6)
        for c in range(4):
            one = lab if spr is None else R.RealisticLab(
                gravity=gravity, compensator=replace(comp, preload=float(spr[c, 0]),
                                                       rate=float(spr[c, 1])))
            assert np.array_equal(got[c], R.displacement(kr240, one, ks[c], q, w_ref, W))
    with pytest.raises(ValueError):
        R.displacement_cases(kr240, R.RealisticLab(), ks, q, w_ref, W)


def test_compensator_torque_of_a_grid_of_springs_is_each_springs_own():
    """preload and rate as (G, 1) arrays: row g is compensator_torque of spring g."""
    robot = load_robot("kr240-2")
    comp = R.compensator_for(robot, 1, [-0.3, 0.0, 0.0], [0.2, 0.0, 0.0], 2e5, 5e3)
    q = np.linspace(robot.lower[1], robot.upper[1], 7)
    pre, rate = np.array([5e3, 1e3, 9e3]), np.array([2e5, 4e5, 1e4])
    tau, dtau = R.compensator_torque(comp, q, pre[:, None], rate[:, None])
    for g in range(3):
        one = R.compensator_torque(replace(comp, preload=pre[g], rate=rate[g]), q)
        assert np.array_equal(tau[g], one[0]) and np.array_equal(dtau[g], one[1])
