"""Model classes (analysis/identification/models): names, identifiability, intervals that
cover the truth, the selection rule. Campaigns of the shop lab's physics
(analysis/identification/studies/model_classes.py), one effect at a time."""

from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np
import pytest

from analysis.errors import InputError
from analysis.identification.estimate import identify
from analysis.identification.models import fit as F
from analysis.identification.models.names import EXTRAS, NAMES, parse_model
from analysis.identification.models.select import select_model
from analysis.identification.poses import pose_groups
from analysis.identification.studies import model_classes as mc
from analysis.model.gravity import gear_torques


@pytest.fixture(scope="module")
def shop():
    return mc.shop_lab()


def _data(robot, tests, noise, lab=None):
    res = identify(robot, tests, "exact", noise=noise, validate=False)
    taus = (gear_torques(robot, tests.q, np.zeros(6)), gear_torques(robot, tests.q, tests.w))
    return res, F.prepare(robot, tests, res.joints, res.x, noise, "exact", taus,
                          pose_groups(tests.q, np.radians(5)),
                          compensator=None if lab is None else lab.compensator)


def test_names_parse_and_refuse():
    assert parse_model("links+lost-motion").extras == ("lost-motion", "links")
    assert parse_model("joints+links").name == "links"
    assert parse_model(None).extras == () and parse_model("auto").auto
    assert set(EXTRAS) < set(NAMES)
    with pytest.raises(InputError, match="--model"):
        parse_model("links+backlash")


def test_lost_motion_bands_within_their_intervals(shop):
    robot, lab, k, loads, noise = shop
    lost = replace(lab, links=(), compensator=None, gravity="flanks")
    inside = total = 0
    for seed in range(3):
        tests, _ = mc.simulate(robot, lost, k, loads, 12, noise, 100 + seed)
        _, data = _data(robot, tests, noise)
        f = F.fit_class(data, ("lost-motion",))
        assert 0.75 < f.chi2_nu < 1.3, f.chi2_nu  # joints alone: ~25
        for name, v, s in zip(f.names, f.values, f.se, strict=True):
            truth = lost.lost_motion[int(name[2:]) - 1]
            inside += int(abs(v - truth) <= F.Z95 * s)
            total += 1
        # k within its 95 % intervals of the lab's k (no link bending to absorb)
        assert np.all((f.k_ci[:, 0] <= k * 1.001) & (k * 0.999 <= f.k_ci[:, 1]))
    assert total >= 15 and inside >= total - 2  # 95 %: about 1 miss in 18 expected


def test_joint_never_flipped_is_named_not_identifiable(shop):
    robot, lab, k, loads, noise = shop
    lost = replace(lab, links=(), compensator=None, gravity="flanks")
    tests, _ = mc.simulate(robot, lost, k, loads, 6, noise, 7)
    _, data = _data(robot, tests, noise)
    # no load at all on joint 1 and the flanks never change: zero its torques' change
    tau_ref, tau_load = data.gear_torques
    tau_load = tau_load.copy()
    tau_load[:, 0] = np.where(np.sign(tau_load[:, 0]) != np.sign(tau_ref[:, 0]),
                              tau_ref[:, 0], tau_load[:, 0])
    f = F.fit_class(replace(data, gear_torques=(tau_ref, tau_load)), ("lost-motion",))
    assert "2b1" not in f.names
    assert ("2b1", "not identifiable: no test changes the sign of its gear torque") in f.fixed


def test_links_class_identifies_combinations_and_covers_projection(shop):
    robot, lab, k, loads, noise = shop
    links = replace(lab, lost_motion=None, compensator=None, gravity="off")
    tests, d_true = mc.simulate(robot, links, k, loads, 12, noise, 11)
    res, data = _data(robot, tests, noise)
    f = F.fit_class(data, ("links",))
    ref = F.fit_class(replace(data, tests=replace(tests, d=d_true)), ("links",))
    assert res.chi2_reduced > 20 and 0.75 < f.chi2_nu < 1.35
    assert f.names == ref.names and 20 < len(f.names) < 42
    fixed = ", ".join(n for n, _ in f.fixed).split(", ")
    assert len(f.names) + len(fixed) == 42
    z = (f.values - ref.values) / f.se
    assert np.mean(np.abs(z) <= F.Z95) >= 0.85  # 95 % expected; 34 correlated parameters
    # the true arm's noise-free displacements are matched by the class (model error ~0)
    assert ref.chi2 < 0.05 * f.chi2


def test_clean_lab_keeps_joints_with_todays_k(shop):
    robot, lab, k, loads, noise = shop
    clean = replace(lab, links=(), lost_motion=None, compensator=None, gravity="off")
    tests, _ = mc.simulate(robot, clean, k, loads, 8, noise, 21)
    res, data = _data(robot, tests, noise)
    sel = select_model(data, parse_model("auto"))
    assert sel.chosen.name == "joints" and sel.accepted
    assert {"joints", "gravity+compensator+lost-motion+links"} <= {c.name for c in
                                                                    sel.candidates}
    # the class "joints" is the joint-spring fit: the same k as today's identification
    assert np.allclose(sel.chosen.k, res.k, rtol=1e-6)


@dataclass(frozen=True)
class _Result:
    """The fields of an identification result that the widening reads and writes."""

    misfit_accepted: tuple
    joints: tuple
    x: np.ndarray
    cov_x: np.ndarray
    se_k: np.ndarray
    ci: np.ndarray
    warnings: tuple
    assumptions: dict


def test_accepted_misfit_widens_intervals_by_heldout_scale():
    from analysis.identification.models.apply import widened

    x = np.full(6, 2e-6)
    cov = np.diag(np.full(6, 1e-16))
    base = _Result(
        misfit_accepted=("misfit",), joints=(0, 1, 2, 3, 4, 5), x=x, cov_x=cov,
        se_k=np.sqrt(np.diag(cov)) / x**2, ci=np.zeros((6, 2)), warnings=(),
        assumptions={"model_classes": {"prediction_sigma_scale": 2.0, "chosen": "links"}})
    out = widened(base)
    assert np.allclose(out.cov_x, 4 * cov) and np.allclose(out.se_k, 2 * base.se_k)
    half = (1 / (x - F.Z95 * 2e-8) - 1 / (x + F.Z95 * 2e-8)) / 2
    assert np.allclose((out.ci[:, 1] - out.ci[:, 0]) / 2, half)
    assert "widened by 2 x" in out.warnings[-1]
    assert widened(replace(base, misfit_accepted=())).cov_x is cov


def test_preloaded_tests_joint_class_equals_the_joint_fit(shop):
    """References under a preload (TestArrays.w_ref, w the difference): the class fit
    solves both equilibria as the joint fit does, so 'joints' gives its k."""
    from analysis.kinetostatics.realistic import RealisticLab, displacement

    robot, _, k, loads, noise = shop
    rng = np.random.default_rng(5)
    poses = mc.sample_poses(robot, 6, rng, min_inverse_condition=0.3)
    q = np.repeat(poses, len(loads), axis=0)
    w = np.tile(loads, (6, 1))
    w_ref = 0.3 * w
    d = displacement(robot, RealisticLab(), k, q, w_ref, w_ref + w)
    d = d + rng.normal(size=d.shape) * noise.displacement_sigma
    tests = mc.TestArrays(pose=np.array([f"P{i // 3}" for i in range(len(q))]), q=q, w=w,
                          d=d, measured=np.ones((len(q), 6), bool),
                          line=np.arange(len(q)) + 2, w_ref=w_ref)
    res, data = _data(robot, tests, noise)
    f = F.fit_class(data, ())
    assert np.allclose(f.k, res.k, rtol=1e-6)
    assert 0.6 < f.chi2_nu < 1.5


def test_compensator_with_lost_motion_finds_joint_2s_flanks(shop):
    """Shop lab, every effect, seed 101, noise-free: letting joint 2's flanks follow the
    fitted spring settled on wrong ones (chi2 150.6 over 216 equations, 2b2 = 1.14e-4 rad
    for the lab's 2e-4); the flank-pattern search fits the true displacements to chi2
    2.5 with 2b2 = 2.14e-4 (its gauge: the link bending absorbed)."""
    robot, lab, k, loads, noise = shop
    tests, d_true = mc.simulate(robot, lab, k, loads, 12, noise, 101)
    _, data = _data(robot, replace(tests, d=d_true), noise, lab)
    f = F.fit_class(data, ("gravity", "compensator", "lost-motion", "links"))
    assert f.chi2 < 10.0, f.chi2
    got = dict(zip(f.names, f.values, strict=True))
    assert abs(got["2b2"] / lab.lost_motion[1] - 1.0) < 0.1, got["2b2"]
    assert any(n == "joint 2 flanks" for n, _ in f.fixed)
