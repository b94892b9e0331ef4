"""The estimators behind one interface: the registry, the problem object, their outcomes.

Each estimator from :func:`analysis.identification.estimators.registry.estimator` fits a
simulated 6-pose KR240-2 campaign through the same call, ``fit(problem)``, and its
estimate equals the fit made directly with the functions it wraps (exactly: the same
arithmetic); the problem makes J and the pose groups once.
"""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from analysis.errors import InputError
from analysis.identification.estimators.base import EstimatorFit
from analysis.identification.estimators.fit_solvers import fit_exact, fit_linear
from analysis.identification.estimators.irls import robust_fit
from analysis.identification.estimators.registry import GAUSSIAN, ROBUST, estimator
from analysis.identification.noise import NoiseModel
from analysis.identification.problem import (
    METHODS,
    ROBUST_METHODS,
    IdentificationProblem,
    IdentifyOptions,
)

from ._sim import simulate

NOISE = NoiseModel(translation_sigma_override=30e-6, rotation_sigma_override=20e-6,
                   force_sigma=0.5, moment_sigma=0.05)


@pytest.fixture(scope="module")
def tests_(kr240, zone_poses, w_eff):
    q = np.repeat(zone_poses[:6], 4, axis=0)
    signs = np.tile([1.0, -1.0, 0.7, -0.7], 6)[:, None]
    return simulate(kr240, q, w_eff * signs, kr240.nominal_stiffness, NOISE, seed=5)


def _problem(kr240, tests, method="exact", robust="none"):
    return IdentificationProblem.make(kr240, tests, noise=NOISE,
                                      options=IdentifyOptions(method=method, robust=robust))


def test_the_registry_names_every_method_and_mode():
    assert set(GAUSSIAN) == set(METHODS)
    assert set(ROBUST) | {"none"} == set(ROBUST_METHODS)
    for m in METHODS:
        e = estimator(m)
        assert (e.name, e.robust, e.linearised) == (m, "none", m != "exact")
    for m in ("wls", "exact"):
        for r in ("huber", "tukey"):
            e = estimator(m, r)
            assert (e.name, e.robust, e.linearised) == (m, r, m == "wls")
    # one robust estimator for both modes: the mode is its data, and a wrong one is refused
    from analysis.identification.estimators.robust_mode import RobustMode

    assert type(estimator("wls", "huber")) is type(estimator("exact", "tukey")) is RobustMode
    with pytest.raises(ValueError, match="unknown robust mode 'bisquare'"):
        RobustMode(estimator("wls"), "bisquare")


@pytest.mark.parametrize("method", METHODS)
def test_each_gaussian_estimator_equals_its_direct_fit(kr240, tests_, method):
    problem = _problem(kr240, tests_, method)
    out = estimator(method).fit(problem)
    assert isinstance(out, EstimatorFit)
    with pytest.raises(dataclasses.FrozenInstanceError):
        out.kept = None
    joints = problem.joints
    ols = fit_linear(kr240, tests_, joints, NOISE, weighted=False)
    np.testing.assert_array_equal(out.linear["ols"], ols.x)
    if method == "ols":
        np.testing.assert_array_equal(out.fit.x, ols.x)
        assert set(out.linear) == {"ols"}
        return
    wls = fit_linear(kr240, tests_, joints, NOISE, weighted=True)
    np.testing.assert_array_equal(out.linear["wls"], wls.x)
    want = wls if method == "wls" else fit_exact(kr240, tests_, joints, NOISE, start=ols.x)
    np.testing.assert_allclose(out.fit.x, want.x, rtol=1e-12)
    # the compliances are the nominal ones to within a few standard errors
    se = np.sqrt(np.diag(out.fit.bread))
    assert np.all(np.abs(out.fit.x - 1 / kr240.nominal_stiffness[list(joints)]) < 10 * se)
    np.testing.assert_array_equal(out.kept, tests_.measured)


@pytest.mark.parametrize("mode", ["huber", "tukey"])
def test_the_robust_modes_wrap_their_gaussian_fit(kr240, tests_, mode):
    problem = _problem(kr240, tests_, "exact", mode)
    out = estimator("exact", mode).fit(problem)
    start = estimator("exact").fit(_problem(kr240, tests_)).fit.x
    direct = robust_fit(kr240, tests_, problem.joints, NOISE, "exact", mode, start=start)
    np.testing.assert_allclose(out.fit.x, direct.fit.x, rtol=1e-12)
    assert out.robust is not None and out.robust.method == mode
    np.testing.assert_array_equal(out.kept, direct.kept(tests_.measured))


def test_the_problem_makes_what_it_shares_once(kr240, tests_):
    problem = _problem(kr240, tests_)
    assert problem.jacobian is problem.jacobian
    J, A = problem.design
    assert J is problem.jacobian and A.shape == (tests_.m, 6, 6)
    problem.release_design()
    assert "design" not in problem.__dict__ and "jacobian" in problem.__dict__
    assert int(problem.pose_group.max()) + 1 == 6
    other = _problem(kr240, tests_)
    assert other.jacobian is not problem.jacobian  # nothing kept between problems
    np.testing.assert_array_equal(other.jacobian, problem.jacobian)


def test_the_problem_refuses_bad_options(kr240, tests_):
    for options, where in ((IdentifyOptions(method="lsq"), "--method"),
                           (IdentifyOptions(robust="cauchy"), "--robust"),
                           (IdentifyOptions(covariance="sandwich"), "covariance")):
        with pytest.raises(InputError) as err:
            IdentificationProblem.make(kr240, tests_, options=options)
        assert err.value.where == where
    with pytest.raises(InputError):
        IdentificationProblem.make(kr240, tests_, joints=(0, 6))
    assert IdentificationProblem.make(kr240, tests_).joints == tuple(range(6))
    # robust ols is a fit of its own now (the unweighted fit with the robust weights)
    robust_ols = IdentifyOptions(method="ols", robust="huber")
    assert IdentificationProblem.make(kr240, tests_, options=robust_ols).joints == tuple(range(6))
