"""Commands that write never write through a symbolic link, never leave stale or empty
outputs behind, and ``analyze`` replaces an earlier analysis only with ``--force``, as a whole.

Each refusal is checked for: exit status 2, one line on stderr starting ``error:``, no
traceback, the link's outside target unchanged and nothing left behind.
"""

from __future__ import annotations

import errno
import hashlib
import json
import os
from pathlib import Path

import numpy as np
import pytest

from analysis.errors import InputError
from analysis.model.robots import load_robot
from analysis.output_files import (
    SymlinkRefused,
    created_dir,
    replaced_dir,
    replacing,
    write_text,
)
from campaign.cli import main
from tests.refusal import assert_refused, outside_dir, tree
from tests.use._campaigns import NOISE
from tests.use.conftest import analyze, write_tests_csv
from tests.use.test_compensation import _path_points
from tests.use.test_compensation import _write_path as write_joint_path

ROOT = Path(__file__).resolve().parents[2]
PROTOCOL = str(ROOT / "protocols" / "kr240-2.toml")


@pytest.fixture
def outside(tmp_path) -> Path:
    return outside_dir(tmp_path)


def refused(capsys, argv: list[str], *watched: Path, message: str = "is a symbolic link",
            code: int = 2) -> str:
    """Run ``campaign ARGV``; assert a one-line refusal and that ``watched`` are unchanged."""
    return assert_refused(capsys, argv, message, watch=watched, code=code)


def _with_link(out: Path, name: str, target: Path) -> Path:
    """``out`` holding one earlier file and ``name`` -> ``target``."""
    out.mkdir(parents=True, exist_ok=True)
    (out / "earlier.txt").write_text("earlier\n")
    (out / name).symlink_to(target)
    return out


# -- the helpers ------------------------------------------------------------------------------

def test_replacing_never_writes_through_a_link_even_one_planted_after_the_check(tmp_path,
                                                                               outside):
    target = tmp_path / "a.json"
    (tmp_path / "b.json").symlink_to(outside / "victim.txt")
    with pytest.raises(SymlinkRefused, match="b.json: is a symbolic link"):
        write_text(tmp_path / "b.json", "x")
    with replacing(target) as tmp:
        tmp.write_text("new\n")
        target.symlink_to(outside / "victim.txt")  # a race: planted between check and rename
    assert not target.is_symlink() and target.read_text() == "new\n"
    assert (outside / "victim.txt").read_text() == "not yours\n"
    assert sorted(p.name for p in tmp_path.iterdir()) == ["a.json", "b.json", "outside"]


def test_replacing_removes_its_temporary_file_when_the_writer_fails(tmp_path):
    (tmp_path / "t.parquet").write_bytes(b"old")
    with pytest.raises(OSError, match="No space"), replacing(tmp_path / "t.parquet") as tmp:
        tmp.write_bytes(b"par")
        raise OSError(errno.ENOSPC, os.strerror(errno.ENOSPC))
    assert [p.name for p in tmp_path.iterdir()] == ["t.parquet"]
    assert (tmp_path / "t.parquet").read_bytes() == b"old"


def test_replaced_dir_keeps_the_old_output_when_the_body_fails_and_swaps_it_whole(tmp_path):
    out = tmp_path / "analysis"
    out.mkdir()
    (out / "report.html").write_text("old report\n")
    with pytest.raises(InputError, match="not empty; choose another or add --force to "
                                         "replace its contents"), replaced_dir(out, False):
        pass
    with pytest.raises(RuntimeError), replaced_dir(out, True) as new:
        write_text(new / "results.json", "{}\n")
        raise RuntimeError("the analysis failed")
    assert tree(out) == {".": "dir", "report.html": hashlib.sha256(b"old report\n").hexdigest()}
    with replaced_dir(out, True) as new:
        write_text(new / "results.json", "{}\n")
    assert sorted(p.name for p in out.iterdir()) == ["results.json"]
    assert sorted(p.name for p in tmp_path.iterdir()) == ["analysis"]  # no .new-/.old- left


def test_created_dir_removes_only_what_it_created(tmp_path):
    with pytest.raises(InputError), created_dir(tmp_path / "a" / "b" / "out"):
        raise InputError("refused")
    assert list(tmp_path.iterdir()) == []
    (tmp_path / "kept").mkdir()
    with pytest.raises(InputError), created_dir(tmp_path / "kept"):
        raise InputError("refused")
    assert (tmp_path / "kept").is_dir()


# -- analyze ----------------------------------------------------------------------------------

@pytest.fixture
def tests_csv(tmp_path) -> Path:
    csv = tmp_path / "tests.csv"
    write_tests_csv(csv)
    return csv


def _analyze_args(csv: Path, out: Path, *extra: str) -> list[str]:
    return ["analyze", "--measurements", str(csv), "--robot", "kr240-2", "--out", str(out),
            "--no-report", "--translation-sigma-um", f"{1e6 * NOISE.displacement_sigma[0]:.6g}",
            "--rotation-sigma-urad", f"{1e6 * NOISE.displacement_sigma[3]:.6g}",
            "--force-sigma-N", "1e-9", "--moment-sigma-Nm", "1e-9", *extra]


def test_analyze_refuses_an_earlier_analysis_and_force_replaces_it_whole(tmp_path, capsys):
    out = analyze(tmp_path, "a")
    capsys.readouterr()
    first = json.loads((out / "results.json").read_text())
    (out / "report.html").write_text("an earlier report, covariance model\n")  # stale
    csv = tmp_path / "a.csv"
    refused(capsys, _analyze_args(csv, out, "--covariance", "residual"), out,
            message="output directory exists and is not empty; choose another or add --force "
                    "to replace its contents")
    assert main(_analyze_args(csv, out, "--covariance", "residual", "--force")) == 0
    capsys.readouterr()
    names = sorted(p.name for p in out.iterdir())
    assert names == ["analysis.json", "model.toml", "residuals.csv", "results.json",
                     "validation.csv"]  # the old report.html is gone with the old analysis
    second = json.loads((out / "results.json").read_text())
    assert first["covariance_source"] == "model" and second["covariance_source"] == "residual"
    assert not [p for p in tmp_path.iterdir() if p.name.startswith(".a.")]


@pytest.mark.parametrize("name", ["results.json", "model.toml", "residuals.csv",
                                  "report.html"])
def test_analyze_force_refuses_a_link_in_its_output(tmp_path, capsys, outside, tests_csv,
                                                    name):
    out = _with_link(tmp_path / "out", name, outside / "victim.txt")
    refused(capsys, _analyze_args(tests_csv, out, "--force"), out, outside)


def test_analyze_refuses_an_output_directory_that_is_a_link(tmp_path, capsys, outside,
                                                            tests_csv):
    (tmp_path / "out").symlink_to(outside / "dir")
    refused(capsys, _analyze_args(tests_csv, tmp_path / "out"), outside)
    (tmp_path / "dangling").symlink_to(outside / "missing")
    refused(capsys, _analyze_args(tests_csv, tmp_path / "dangling", "--force"), outside)
    assert not (outside / "missing").exists()


def test_a_refused_analysis_leaves_no_output_directory(tmp_path, capsys, tests_csv):
    out = tmp_path / "new" / "analysis"
    args = _analyze_args(tests_csv, out)
    args[args.index("--translation-sigma-um") + 1] = "0.01"  # a misfit: refused by the checks
    refused(capsys, args, tmp_path, message="refused, the data do not support this stiffness")
    assert not (tmp_path / "new").exists()
    refused(capsys, [*_analyze_args(tests_csv, out), "--report", "--trials", "3"], tmp_path,
            message="--trials: need at least 10 trials")


# -- plan, place, maps, compensate, robustness, compare, demo --------------------------------

def _plan(out: Path, *extra: str) -> list[str]:
    return ["plan", "--protocol", PROTOCOL, "--out", str(out), "--candidates", "300",
            "--no-figure", *extra]


@pytest.mark.parametrize("name", ["plan.csv", "summary.json", "protocol.toml"])
def test_plan_force_refuses_a_link_in_its_output(tmp_path, capsys, outside, name):
    out = _with_link(tmp_path / "out", name, outside / "victim.txt")
    refused(capsys, _plan(out, "--force"), out, outside)


def test_plan_refuses_a_link_as_output_and_a_failed_plan_leaves_no_directory(tmp_path, capsys,
                                                                            outside):
    (tmp_path / "out").symlink_to(outside / "dir")
    refused(capsys, _plan(tmp_path / "out"), outside)
    refused(capsys, _plan(tmp_path / "new" / "plan", "--weights", "1,x"), tmp_path,
            message="--weights")
    assert not (tmp_path / "new").exists()


def _part(tmp_path: Path) -> Path:
    path = tmp_path / "part.csv"
    t = np.linspace(0, 2 * np.pi, 6, endpoint=False)
    path.write_text("x_mm,y_mm,z_mm,ax,ay,az\n" + "".join(
        f"{50 * np.cos(a):.6f},{50 * np.sin(a):.6f},0,0,0,-1\n" for a in t))
    return path


def _place(tmp_path: Path, out: Path, x_mm: str, *extra: str) -> list[str]:
    return ["place", "--robot", "kr240-2", "--path", str(_part(tmp_path)), "--out", str(out),
            "--x-mm", x_mm, "--y-mm", "0", "--z-mm", "200", "--x-step-mm", "1000",
            "--tool-angle-step-deg", "60", "--wrench", "400,250,-300,0,0,20", "--workers",
            "0", *extra]


def test_place_refuses_links_and_a_failed_search_leaves_no_directory(tmp_path, capsys,
                                                                     outside):
    out = _with_link(tmp_path / "out", "placement.json", outside / "victim.txt")
    refused(capsys, _place(tmp_path, out, "1600", "--force"), out, outside)
    (tmp_path / "link").symlink_to(outside / "dir")
    refused(capsys, _place(tmp_path, tmp_path / "link", "1600"), outside)
    new = tmp_path / "new" / "place"
    refused(capsys, _place(tmp_path, new, "4000..5000"), outside,
            message="no feasible placement among 2")
    assert not (tmp_path / "new").exists()


def test_maps_refuses_links(tmp_path, capsys, outside):
    args = ["maps", "--robot", "kr240-2", "--step", "30", "--force", "--out"]
    out = _with_link(tmp_path / "out", "map_summary.json", outside / "victim.txt")
    refused(capsys, [*args, str(out)], out, outside)
    (tmp_path / "link").symlink_to(outside / "dir")
    refused(capsys, [*args, str(tmp_path / "link")], outside)


def test_compensate_refuses_links(tmp_path, capsys, outside):
    robot = load_robot("kr240-2")
    path = tmp_path / "path.csv"
    write_joint_path(path, np.degrees(_path_points(robot, 5, seed=5)))
    args = ["compensate", "--robot", "kr240-2", "--path", str(path), "--wrench",
            "0,1000,0,0,0,0", "--force", "--out"]
    out = _with_link(tmp_path / "out", "compensated.csv", outside / "victim.txt")
    refused(capsys, [*args, str(out)], out, outside)
    (tmp_path / "link").symlink_to(outside / "dir")
    refused(capsys, [*args, str(tmp_path / "link")], outside)


def test_robustness_refuses_links(tmp_path, capsys, outside):
    args = ["robustness", "--robot", "kr240-2", "--tests", "3", "--trials", "10",
            "--pool-size", "20", "--out"]
    (tmp_path / "link").symlink_to(outside / "dir")
    refused(capsys, [*args, str(tmp_path / "link")], outside)
    out = tmp_path / "out"
    out.mkdir()
    (out / "robustness.csv").symlink_to(outside / "victim.txt")
    refused(capsys, [*args, str(out)], out, outside)


def test_compare_plot_refuses_a_link_a_directory_and_a_missing_directory(identified, tmp_path,
                                                                        capsys, outside):
    other = analyze(tmp_path, "other", seed=11)
    capsys.readouterr()
    args = ["compare", str(identified), str(other), "--plot"]
    (tmp_path / "c.png").symlink_to(outside / "victim.txt")
    refused(capsys, [*args, str(tmp_path / "c.png")], outside,
            message="c.png is a symbolic link")
    refused(capsys, [*args, str(outside / "dir")], outside, message="is a directory")
    refused(capsys, [*args, str(tmp_path / "missing" / "c.png")], outside,
            message="does not exist")


def test_demo_refuses_a_link_as_its_directory(tmp_path, capsys, outside):
    (tmp_path / "demo").symlink_to(outside / "dir")
    refused(capsys, ["demo", "--out", str(tmp_path / "demo"), "--quiet"], outside)
    (tmp_path / "dangling").symlink_to(outside / "missing")
    refused(capsys, ["demo", "--out", str(tmp_path / "dangling"), "--quiet"], outside)


def test_a_failed_analysis_removes_the_parents_it_created(tmp_path):
    out = tmp_path / "a" / "b" / "analysis"
    with pytest.raises(RuntimeError), replaced_dir(out, False) as new:
        write_text(new / "results.json", "{}\n")
        raise RuntimeError("the report failed")
    assert list(tmp_path.iterdir()) == []


def test_a_new_directory_left_by_a_killed_analysis_is_removed_unless_in_use(tmp_path):
    import fcntl

    out = tmp_path / "analysis"
    stale, busy = tmp_path / ".analysis.new-killed", tmp_path / ".analysis.new-busy"
    for d in (stale, busy):
        d.mkdir()
        (d / "results.json").write_text("{}\n")
    fd = os.open(busy, os.O_RDONLY)
    fcntl.flock(fd, fcntl.LOCK_EX)  # another analysis still writing it
    try:
        with replaced_dir(out, False) as new:
            write_text(new / "results.json", "{}\n")
    finally:
        os.close(fd)
    assert sorted(p.name for p in tmp_path.iterdir()) == [".analysis.new-busy", "analysis"]
