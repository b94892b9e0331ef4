"""Routes that used to give a silently wrong stiffness: tool point, sidecar, misfit, units,
one pose, extreme numbers; every refusal exits 2 with a message naming the cause."""

from __future__ import annotations

import hashlib
import json
import shutil
from pathlib import Path

import numpy as np
import pytest
from report_runs import POSES_DEG, ROOT, write_csv

from analysis.kinetostatics.equilibrium import displacement_screw
from campaign.acquire.session import write_tests_sidecar
from campaign.cli import main
from campaign.protocol import load_protocol
from campaign.protocol_robot import protocol_robot
from campaign.run_noise import noise_from_protocol

UR10E = ROOT / "protocols" / "ur10e.toml"
#: UR10e poses (model = controller convention, deg), away from its singularities
UR_POSES = np.array([
    [0, -90, 90, -90, 90, 0], [30, -60, 100, -120, 60, 30], [-40, -110, 80, -60, 120, -20],
    [60, -45, 120, -150, 80, 45], [-20, -130, 60, -30, 100, 90], [10, -75, 130, -100, 45, -60],
], dtype=float)
HEADER = ["pose", *[f"q{i}_deg" for i in range(1, 7)], "fx_N", "fy_N", "fz_N", "mx_Nm",
          "my_Nm", "mz_Nm", "dx_mm", "dy_mm", "dz_mm", "rx_mrad", "ry_mrad", "rz_mrad",
          "test_id", "repeat", "status", "flags", "repeatability_mm", "drift_mm",
          "wrench_error_N", "tracker_sigma_mm", "t_utc"]


@pytest.fixture(scope="module")
def ur_run(tmp_path_factory) -> Path:
    """A UR10e run at the protocol's 120 mm tool: equilibrium displacements of P plus the
    protocol's noise (seeded); tests.meta.json written by acquire's own writer."""
    protocol = load_protocol(UR10E)
    robot = protocol_robot(protocol)  # P 120 mm from the flange
    truth = np.array(protocol.fake_lab.true_joint_stiffness)
    noise = noise_from_protocol(protocol)
    loads = protocol.wrenches()
    rng = np.random.default_rng(5)
    q = np.radians(np.repeat(UR_POSES, 2, axis=0))
    w = np.array([loads[i % len(loads)] for i in range(len(q))])
    d = displacement_screw(robot, q, truth, w) + rng.normal(size=(len(q), 6)) * \
        noise.displacement_sigma
    path = tmp_path_factory.mktemp("ur") / "run"
    path.mkdir()
    text = UR10E.read_text()
    (path / "protocol.toml").write_text(text)
    meta = {"format_version": 1, "status": "complete", "reason": "",
            "protocol_sha256": hashlib.sha256(text.encode()).hexdigest(),
            "robot": {"name": robot.name, "key": "ur10e"}, "n_planned_tests": len(q),
            "fake_lab": {"true_joint_stiffness": truth.tolist()}}
    (path / "metadata.json").write_text(json.dumps(meta))
    lines = [",".join(HEADER)]
    for i in range(len(q)):
        cells = [f"P{i // 2 + 1}", *(repr(float(v)) for v in np.degrees(q[i])),
                 *(repr(float(v)) for v in w[i]),
                 *(repr(float(v)) for v in 1e3 * d[i]), str(i + 1), "1", "ok", "", "0.01",
                 "0.0", "0.1", "0.02", "2026-11-20T10:00:00Z"]
        lines.append(",".join(cells))
    (path / "tests.csv").write_text("\n".join(lines) + "\n")
    (path / "events.jsonl").write_text("")
    write_tests_sidecar(path, protocol, robot)
    return path


def _k(out: Path) -> np.ndarray:
    return np.array(json.loads((out / "results.json").read_text())
                    ["joint_stiffness_Nm_per_rad"], dtype=float)


def test_sidecar_re_import_gives_the_runs_k(ur_run, tmp_path, capsys):
    assert main(["analyze", str(ur_run), "--out", str(tmp_path / "run"), "--no-report"]) == 0
    # the run's own tests.csv, imported with its sidecar: no --robot, no tool option needed
    assert main(["analyze", "--measurements", str(ur_run / "tests.csv"),
                 "--out", str(tmp_path / "csv"), "--no-report"]) == 0
    out = capsys.readouterr().out
    np.testing.assert_allclose(_k(tmp_path / "csv"), _k(tmp_path / "run"), rtol=1e-9)
    a = json.loads((tmp_path / "csv" / "results.json").read_text())["assumptions"]
    assert a["tool_point"]["xyz_mm"] == [0.0, 0.0, 120.0]
    assert "tests.meta.json" in a["tool_point"]["source"]
    assert "tests.meta.json" in a["noise"]["source"]
    assert "tests.meta.json" in out and "Assumptions" in out
    run_a = json.loads((tmp_path / "run" / "results.json").read_text())["assumptions"]
    assert "protocol [tool]" in run_a["tool_point"]["source"]
    assert run_a["noise"]["translation_sigma_um"] == pytest.approx(
        a["noise"]["translation_sigma_um"])


def test_import_without_and_with_the_tool_options(ur_run, tmp_path, capsys):
    """A plain copy of tests.csv (no sidecar) measured at a 120 mm tool point.

    Without the tool options P is the flange centre, the assumption is said, and with the
    run's noise figures the misfit is refused naming the tool point first; accepted anyway,
    k is off. With --tool-xyz-mm the k equals the run's.
    """
    csv = tmp_path / "tests.csv"
    shutil.copy(ur_run / "tests.csv", csv)
    assert main(["analyze", str(ur_run), "--out", str(tmp_path / "run"), "--no-report"]) == 0
    nm = noise_from_protocol(load_protocol(UR10E))
    noise = ["--translation-sigma-um", repr(nm.translation_sigma * 1e6),
             "--rotation-sigma-urad", repr(nm.rotation_sigma * 1e6),
             "--force-sigma-N", repr(nm.force_sigma), "--moment-sigma-Nm", repr(nm.moment_sigma)]
    capsys.readouterr()
    flange = ["analyze", "--measurements", str(csv), "--robot", "ur10e", *noise,
              "--out", str(tmp_path / "flange"), "--no-report"]
    assert main(flange) == 2
    captured = capsys.readouterr()
    assert "flange centre assumed" in captured.out
    assert "misfit" in captured.err and "most likely first: (1) the tool point P" in captured.err
    assert not (tmp_path / "flange" / "results.json").exists()
    assert main([*flange, "--accept-misfit"]) == 0
    out = capsys.readouterr().out
    assert "no tool point given" in out and "ACCEPTED WITH --accept-misfit" in out
    res = json.loads((tmp_path / "flange" / "results.json").read_text())
    assert res["assumptions"]["tool_point"]["source"] == "none given: flange centre assumed"
    assert any("no tool point given" in w for w in res["warnings"])
    k_run = _k(tmp_path / "run")
    assert np.max(np.abs(_k(tmp_path / "flange") / k_run - 1)) > 0.2  # the wrong P shows in k
    assert main(["analyze", "--measurements", str(csv), "--robot", "ur10e", *noise,
                 "--tool-xyz-mm", "0,0,120", "--out", str(tmp_path / "tool"),
                 "--no-report"]) == 0
    np.testing.assert_allclose(_k(tmp_path / "tool"), k_run, rtol=1e-9)
    a = json.loads((tmp_path / "tool" / "results.json").read_text())["assumptions"]
    assert a["tool_point"]["source"] == "--tool-xyz-mm"
    assert a["tool_point"]["xyz_mm"] == [0.0, 0.0, 120.0]


def test_explicit_tool_option_overrides_the_sidecar(ur_run, tmp_path, capsys):
    rc = main(["analyze", "--measurements", str(ur_run / "tests.csv"), "--tool-xyz-mm", "0,0,0",
               "--out", str(tmp_path / "o"), "--no-report"])
    captured = capsys.readouterr()
    assert rc == 2 and "misfit" in captured.err
    assert "--tool-xyz-mm (rest from sidecar tests.meta.json)" in captured.out


def test_displacements_in_m_instead_of_mm_are_refused(tmp_path, rows, capsys):
    scaled = [dict(r) for r in rows]
    for r in scaled:
        for c in ("dx_mm", "dy_mm", "dz_mm", "rx_mrad", "ry_mrad", "rz_mrad"):
            r[c] = r[c] / 1000.0  # typed in m and rad
    csv = write_csv(tmp_path / "m.csv", scaled)
    args = ["analyze", "--measurements", str(csv), "--robot", "kr240-2", "--no-report",
            "--out", str(tmp_path / "o")]
    assert main(args) == 2
    err = capsys.readouterr().err
    assert "too good to be true" in err and "displacements typed in m instead of mm" in err
    # the noise options by their current names (the old --sigma-* ones are hidden)
    assert "--translation-sigma-um, --rotation-sigma-urad" in err and "--sigma-" not in err
    assert "implausible stiffness" in err and "--accept-misfit" in err
    assert not (tmp_path / "o" / "results.json").exists()
    assert main([*args, "--accept-misfit"]) == 0
    res = json.loads((tmp_path / "o" / "results.json").read_text())
    assert res["misfit_accepted"]["accepted"]
    kinds = " ".join(res["misfit_accepted"]["problems"])
    assert "too good" in kinds and "implausible stiffness" in kinds
    # ~1000 x the true stiffness, as the units say
    k = np.array(res["joint_stiffness_Nm_per_rad"], dtype=float)
    assert np.all(k[:3] / np.array([1409800.0, 400760.0, 935280.0]) > 300)


def test_a_good_import_is_not_refused_and_records_its_assumptions(tmp_path, rows):
    csv = write_csv(tmp_path / "ok.csv", rows)
    out = tmp_path / "o"
    assert main(["analyze", "--measurements", str(csv), "--robot", "kr240-2",
                 "--translation-sigma-um", repr(float(30 * np.sqrt(1.5))),
                 "--rotation-sigma-urad", repr(float(20 * np.sqrt(1.5))),
                 "--no-report", "--out", str(out)]) == 0
    res = json.loads((out / "results.json").read_text())
    a = res["assumptions"]
    assert a["tool_point"]["source"] == "none given: flange centre assumed"
    assert "defaults" in a["noise"]["source"] and "--translation-sigma-um" in a["noise"]["source"]
    assert a["method"].startswith("exact")
    assert res["misfit_accepted"] == {"accepted": False, "problems": []}


def test_one_pose_with_encoder_jitter_is_one_pose(tmp_path, rows, capsys):
    """15 tests at one pose, joint angles jittered by 0.0003 deg: refused as one pose."""
    rng = np.random.default_rng(2)
    one = []
    for i, r in enumerate(rows):
        r = dict(r, pose=f"T{i + 1}")
        for j in range(6):
            r[f"q{j + 1}_deg"] = float(POSES_DEG[0, j] + rng.normal() * 3e-4)
        one.append(r)
    csv = write_csv(tmp_path / "one.csv", one)
    assert main(["analyze", "--measurements", str(csv), "--robot", "kr240-2",
                 "--out", str(tmp_path / "o")]) == 2
    err = capsys.readouterr().err
    assert "are at one pose" in err and "lines 2..16" in err


def test_extreme_numbers_are_a_one_line_error(tmp_path, rows, capsys):
    bad = [dict(r) for r in rows]
    bad[3]["fz_N"] = 1e300
    csv = write_csv(tmp_path / "x.csv", bad)
    assert main(["analyze", "--measurements", str(csv), "--robot", "kr240-2",
                 "--out", str(tmp_path / "o")]) == 2
    err = capsys.readouterr().err.strip()
    assert "\n" not in err and str(csv) in err and "line 5, column fz_N" in err
    bad[3]["fz_N"], bad[6]["dy_mm"] = 2200.0, 1e308
    write_csv(csv, bad)
    assert main(["analyze", "--measurements", str(csv), "--robot", "kr240-2",
                 "--out", str(tmp_path / "o")]) == 2
    assert "line 8, column dy_mm" in capsys.readouterr().err


def test_wrench_given_as_the_sensors_reaction_is_refused(ur_run, tmp_path, capsys):
    """The wrench with all six signs flipped (the reaction the F/T sensor feels): the fit is as
    good as the right one (the model is linear in w) but every compliance comes out negative.
    The UR10e has no nominal stiffness, so only the sign check stands between this and a
    results.json."""
    lines = (ur_run / "tests.csv").read_text().splitlines()
    head = lines[0].split(",")
    cols = [head.index(c) for c in ("fx_N", "fy_N", "fz_N", "mx_Nm", "my_Nm", "mz_Nm")]
    flipped = [lines[0]]
    for line in lines[1:]:
        cells = line.split(",")
        for c in cols:
            cells[c] = repr(-float(cells[c]))
        flipped.append(",".join(cells))
    csv = tmp_path / "reaction.csv"
    csv.write_text("\n".join(flipped) + "\n")
    args = ["analyze", "--measurements", str(csv), "--robot", "ur10e", "--tool-xyz-mm",
            "0,0,120", "--out", str(tmp_path / "o"), "--no-report"]
    # the copied CSV has no sidecar: the default F/T figures (15.6 N, 2.5 N m) against these
    # 60-100 N loads would attenuate the compliances by more than a first-order
    # errors-in-variables correction can take, and are refused as such
    assert main(args) == 2
    assert "too small against the force/torque sensor noise" in capsys.readouterr().err
    args += ["--force-sigma-N", "0.1", "--moment-sigma-Nm", "0.005"]  # the run's sensor
    assert main(args) == 2
    err = capsys.readouterr().err
    assert "negative stiffness" in err and "(1) the sign of the wrench" in err
    assert err.count("rad/(N m)") >= 4, err  # the well-determined joints named
    assert not (tmp_path / "o" / "results.json").exists()
    # accepted anyway: the compliances are about the negatives of the right ones (the linear
    # model is odd in w; K_C and the finite deflection are not, hence the 15 %)
    assert main([*args, "--accept-misfit"]) == 0
    res = json.loads((tmp_path / "o" / "results.json").read_text())
    assert any("negative stiffness" in p for p in res["misfit_accepted"]["problems"])
    assert main(["analyze", str(ur_run), "--out", str(tmp_path / "run"), "--no-report"]) == 0
    x_run = np.array(json.loads((tmp_path / "run" / "results.json").read_text())
                     ["joint_compliance_rad_per_Nm"], dtype=float)
    x_neg = np.array(res["joint_compliance_rad_per_Nm"], dtype=float)
    assert np.all(x_neg < 0) and np.allclose(-x_neg, x_run, rtol=0.15)
