"""Every noise source is an option, and residuals name a declared noise that is off by > 2x."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest

from analysis.identification.estimate import identify
from analysis.identification.io.measurements import TestArrays
from analysis.kinetostatics.equilibrium import displacement_screw
from campaign.jobs.analyze import AnalyzeOptions
from campaign.jobs.analyze_noise import NoiseOverrides
from tests.studies._coverage import NOISE, campaign_setup


@pytest.fixture(scope="module")
def setup(own_protocol_path):
    return campaign_setup(own_protocol_path, poses=8)


def _tests(setup, actual, seed=0):
    robot, q, W, k = setup
    qq = np.repeat(q, len(W), axis=0)
    ww = np.tile(W, (len(q), 1))
    d = displacement_screw(robot, qq, k, ww)
    rng = np.random.default_rng(seed)
    wm = ww + rng.normal(size=ww.shape) * actual.wrench_sigma_at(ww)
    dm = d + rng.normal(size=d.shape) * actual.displacement_sigma
    return TestArrays(pose=np.repeat([f"P{i}" for i in range(len(q))], len(W)), q=qq, w=wm,
                      d=dm, measured=np.ones(d.shape, bool), line=np.arange(len(qq)) + 2)


def _notes(res):
    return [w for w in res.warnings if "times the declared noise" in w]


def test_declared_noise_right_gives_no_note(setup):
    res = identify(setup[0], _tests(setup, NOISE), "exact", noise=NOISE, validate=False)
    assert _notes(res) == []


def test_tracker_noise_three_times_declared_is_named(setup):
    actual = replace(NOISE, translation_sigma_override=3 * NOISE.translation_sigma)
    res = identify(setup[0], _tests(setup, actual), "exact", noise=NOISE, validate=False)
    notes = _notes(res)
    assert len(notes) == 1 and notes[0].startswith("translation residuals are")
    assert "tracker noise looks too small" in notes[0]
    # the option by its current name, not the hidden old --sigma-translation-um
    assert notes[0].endswith("the options --translation-sigma-um)") and "--sigma-" not in notes[0]
    ratio = float(notes[0].split(" are ")[1].split(" times")[0])
    assert 2.4 < ratio < 3.6


def test_rotation_noise_declared_four_times_too_large_is_named(setup):
    declared = replace(NOISE, rotation_sigma_override=4 * NOISE.rotation_sigma)
    res = identify(setup[0], _tests(setup, NOISE), "exact", noise=declared, validate=False)
    notes = _notes(res)
    assert len(notes) == 1 and notes[0].startswith("rotation residuals")
    assert "too large" in notes[0]
    assert "--rotation-sigma-urad" in notes[0] and "--sigma-" not in notes[0]


def test_cli_noise_options_reach_the_model():
    noise, used = NoiseOverrides.typed(force_sigma_N=2.0, joint_sigma_urad=7.0, force_pct=0.5,
                                       moment_pct=0.25).applied(NOISE)
    assert noise.force_sigma == 2.0
    assert noise.joint_sigma == pytest.approx(7e-6)
    assert noise.force_relative == pytest.approx(0.005)
    assert noise.moment_relative == pytest.approx(0.0025)
    assert used == ["--force-sigma-N", "--joint-sigma-urad", "--force-pct", "--moment-pct"]
    # 0.5 % of a 1000 N reading in quadrature with 2 N
    s = noise.wrench_sigma_at(np.array([600.0, 0, 800.0, 0, 0, 0]))
    assert s[0] == pytest.approx(np.hypot(2.0, 5.0))


def test_the_noise_overrides_are_named_records_of_the_options():
    """Each override names its options field, its NoiseModel field and its option: nothing
    is paired by position; an unknown option is an error, not a shifted value."""
    import dataclasses

    overrides = dataclasses.fields(NoiseOverrides)
    assert {f.name for f in overrides} <= {f.name for f in dataclasses.fields(AnalyzeOptions)}
    assert {f.metadata["noise_field"] for f in overrides} <= {
        f.name for f in dataclasses.fields(NOISE)}
    si = NoiseOverrides.typed(moment_pct=0.25, translation_sigma_um=30.0)
    assert si.moment_relative == pytest.approx(0.0025)
    assert si.translation_sigma_m == pytest.approx(30e-6)
    given = {f.name for f in overrides if getattr(si, f.name) is not None}
    assert given == {"translation_sigma_m", "moment_relative"}
    # the options record (flat: the web API's body) carries them back as the same record
    options = AnalyzeOptions.with_noise(si, trials=7)
    assert options.noise_overrides == si and options.trials == 7
    assert options.moment_relative == pytest.approx(0.0025) and options.force_sigma_N is None
    assert AnalyzeOptions().noise_overrides == NoiseOverrides()
    with pytest.raises(ValueError, match="--force-sigma"):
        NoiseOverrides.typed(force_sigma=1.0)


def test_a_negative_override_is_refused_naming_its_option():
    from analysis.errors import InputError

    with pytest.raises(InputError, match="positive") as caught:
        NoiseOverrides(force_sigma_N=-1.0).applied(NOISE)
    assert caught.value.where == "--force-sigma-N"
    # a zero relative figure is allowed (no proportional part), a zero sigma is not
    assert NoiseOverrides(force_relative=0.0).applied(NOISE)[0].force_relative == 0.0
    with pytest.raises(InputError):
        NoiseOverrides(moment_sigma_Nm=0.0).applied(NOISE)


def test_the_job_reads_the_noise_overrides_only_as_the_record():
    """No code of the analyze job, its command or its web handler reads one of the seven
    flat fields by name: the record (:attr:`AnalyzeOptions.noise_overrides`) carries them,
    the command builds it (``AnalyzeOptions.with_noise``)."""
    import ast
    import dataclasses
    from pathlib import Path

    root = Path(__file__).resolve().parents[2]
    names = {f.name for f in dataclasses.fields(NoiseOverrides)}
    paths = [*sorted((root / "campaign" / "jobs").glob("analyze*.py")),
             root / "campaign" / "cli" / "commands" / "analyze.py",
             root / "campaign" / "web" / "api_jobs.py"]
    reads = [f"{p.relative_to(root)}:{node.lineno}: .{node.attr}"
             for p in paths for node in ast.walk(ast.parse(p.read_text()))
             if isinstance(node, ast.Attribute) and node.attr in names]
    assert len(paths) >= 5 and reads == []


def test_the_web_body_keeps_the_flat_noise_fields(tmp_path):
    """The API's request schema is unchanged: the seven overrides are flat fields of
    ``AnalyzeOptions``, each an optional number or null."""
    import dataclasses

    pytest.importorskip("fastapi", reason="fastapi is not installed (pip install fastapi)")
    from campaign.web.app import create_app

    schema = create_app(tmp_path, "tok-0123456789abcdef").openapi()
    body = schema["components"]["schemas"]["AnalyzeOptions"]
    props = body["properties"]
    for f in dataclasses.fields(NoiseOverrides):
        assert f.name not in body.get("required", []) and "default" not in props[f.name]
        assert {t.get("type") for t in props[f.name]["anyOf"]} == {"number", "null"}, f.name
    assert "noise_overrides" not in props
