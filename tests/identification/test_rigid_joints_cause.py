"""A misfit of a fit with joints left out by --joints names those joints, taken as rigid, as
the first likely cause (the audit: the demo run with --joints 1,2,3 and rotations measured,
reduced chi-square 855, listed the tool point, units, sign convention and noise figures only)."""

from __future__ import annotations

from analysis.identification.checks.plausibility import problems
from analysis.identification.estimate import identify
from analysis.identification.noise import NoiseModel

from ._sim import simulate

NOISE = NoiseModel()


def test_joints_left_out_are_the_first_cause(kr240, zone_poses, w_eff):
    k0 = kr240.nominal_stiffness
    tests = simulate(kr240, zone_poses[:6], w_eff, k0, NOISE, seed=2)
    sub = identify(kr240, tests, "exact", joints=[0, 1, 2], noise=NOISE, validate=False)
    (misfit,) = [p for p in problems(sub, k0) if p.startswith("misfit")]
    causes = misfit.split("likely causes, most likely first: ")[1]
    assert causes.startswith("(1) joint(s) 4, 5, 6 taken as rigid (--joints)")
    assert "--joints 1,2,3,4,5,6" in causes
    assert "(2) the tool point P" in causes
    # all six identified: no such cause, and no misfit
    full = identify(kr240, tests, "exact", noise=NOISE, validate=False)
    assert not any(p.startswith("misfit") for p in problems(full, k0))
    # the translations-only variant keeps its own first cause (the wrist, rotations missing)
    trans = simulate(kr240, zone_poses[:6], w_eff, k0, NOISE, seed=2, rotations=False)
    res = identify(kr240, trans, "exact", noise=NOISE, validate=False)
    found = [p for p in problems(res, k0) if p.startswith("misfit")]
    for p in found:
        assert "(1) the wrist joints 4-6 taken as rigid (no rotation measured" in p
        assert "(--joints): a compliant" not in p
