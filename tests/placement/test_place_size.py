"""campaign place: the size of a search is said and bounded before any work; bad values.

Part of the bad-input corpus: each refusal is one line, exit 2, no traceback, no
warning, and nothing is written (:func:`tests.refusal.assert_refused`).
"""

from __future__ import annotations

import json
import re
from types import SimpleNamespace

import numpy as np
import pytest

from analysis.errors import InputError
from analysis.model.robots import load_robot
from analysis.placement.grid import PlacementGrid
from analysis.placement.search import result_bytes, run_dask, run_local
from campaign.cli import main
from campaign.use.place_run import DEFAULT_MAX_EVALUATIONS, SearchSize, check_size
from tests.placement.test_place import WRENCH, _problem, _write_path
from tests.refusal import assert_refused


def _args(tmp_path, *extra, wrench=WRENCH):
    path = tmp_path / "part.csv"
    if not path.exists():
        _write_path(path)
    args = ["place", "--robot", "kr240-2", "--path", str(path), "--out", str(tmp_path / "out"),
            "--x-mm", "1400..1800", "--y-mm", "-200..200", "--z-mm", "200..300",
            "--x-step-mm", "200", "--y-step-mm", "200", "--z-step-mm", "100",
            "--tool-angle-step-deg", "30", "--config", "-1,-1,-1", "--workers", "0"]
    return [*args, *(["--wrench", wrench] if wrench is not None else []), *extra]


def test_printed_count_is_the_grid_size_and_chunking_changes_nothing(tmp_path, capsys):
    """3 x 3 x 2 placements (x, y, z), yaw 0; 8 points; -180..180 by 30 deg leaves out
    +180 (a full turn): 12 angles; one configuration."""
    expected = len(range(1400, 1801, 200)) * len(range(-200, 201, 200)) * 2 * 1 * 8 * 12 * 1
    assert expected == 1728
    capsys.readouterr()
    assert main(_args(tmp_path, "--chunk", "1")) == 0
    text = " ".join(capsys.readouterr().out.split())
    found = re.search(r"search: (\d+) placements x (\d+) points x (\d+) tool angles x (\d+) "
                      r"configurations = (\d+) evaluations", text)
    assert found, text
    p, n, a, c, e = map(int, found.groups())
    assert (p, n, a, c) == (18, 8, 12, 1) and e == expected == p * n * a * c
    est = re.search(r"expected ([\d.e+-]+) (s|min|h) on 1 process and ([\d.e+-]+) MiB "
                    r"\(timed probe of (\d+) placements", text)
    assert est, text
    assert float(est.group(3)) >= result_bytes(18, 8) / 2**20 and int(est.group(4)) == 18
    one = json.loads((tmp_path / "out" / "placement.json").read_text())
    assert one["search_space"]["evaluations"] == expected
    assert main(_args(tmp_path, "--force")) == 0  # automatic chunk: all 18 in one task
    whole = json.loads((tmp_path / "out" / "placement.json").read_text())
    one.pop("run"), whole.pop("run")
    assert one == whole


def test_grid_rows_are_meshgrid_order_and_chunks_equal_one_pass():
    robot = load_robot("kr240-2")
    grid = PlacementGrid(np.array([1.2, 1.6, 2.0, 2.8]), np.array([-0.3, 0.3]),
                         np.array([0.3]), np.array([0.0, 0.5, 1.0]))
    G = np.stack(np.meshgrid(*grid.axes, indexing="ij"), axis=-1).reshape(-1, 4)
    assert len(grid) == 24 and np.array_equal(grid.full(), G)
    assert np.array_equal(grid[17], G[17]) and np.array_equal(grid[5:11], G[5:11])
    assert np.array_equal(grid[-1], G[-1]) and grid[20:99].shape == (4, 4)
    problem = _problem(robot, None, None)
    whole = run_local(problem, G, chunk=len(G))
    for chunk in (1, 5, 24):
        part = run_local(problem, grid, chunk=chunk)
        for f in ("value", "config", "angle", "reason", "point"):
            np.testing.assert_array_equal(getattr(part, f), getattr(whole, f))
    assert np.isfinite(whole.value).sum() > 0 and np.isinf(whole.value).sum() > 0


def test_dask_windows_equal_the_local_run(monkeypatch):
    """More tasks than the submission window: gathered in order, same results."""
    from distributed import Client, LocalCluster

    import analysis.placement.search as search

    monkeypatch.setattr(search, "DASK_WINDOW", 2)
    robot = load_robot("kr240-2")
    grid = PlacementGrid(np.array([1.2, 1.6, 2.0, 2.8]), np.array([-0.3, 0.3]),
                         np.array([0.3]), np.array([0.0, 0.5]))
    problem = _problem(robot, None, None)
    local = run_local(problem, grid, chunk=3)
    with LocalCluster(n_workers=1, threads_per_worker=1, processes=False,
                      dashboard_address=None) as cluster, Client(cluster) as client:
        remote = run_dask(problem, grid, 3, client)  # 16 placements: 6 tasks, 3 windows
    for f in ("value", "config", "angle", "reason", "point"):
        np.testing.assert_array_equal(getattr(remote, f), getattr(local, f))


def test_limits_of_check_size():
    """Default limit without --scheduler; none with it; an explicit limit holds either way;
    memory is bounded whatever the evaluation limit."""
    big = SearchSize(10**6, 100, 36, 8, result_bytes(10**6, 100))
    assert big.evaluations == 2.88e10 > DEFAULT_MAX_EVALUATIONS
    opts = dict(max_evaluations=None, scheduler=None, max_memory_gib=2.0)
    with pytest.raises(InputError, match="above the limit of 1e\\+08"):
        check_size(big, SimpleNamespace(**opts))
    check_size(big, SimpleNamespace(**{**opts, "scheduler": "tcp://127.0.0.1:8786"}))
    check_size(big, SimpleNamespace(**{**opts, "max_evaluations": 3e10}))
    with pytest.raises(InputError, match="raise --max-evaluations"):
        check_size(big, SimpleNamespace(**{**opts, "scheduler": "tcp://127.0.0.1:8786",
                                           "max_evaluations": 1e10}))
    with pytest.raises(InputError, match=r"need 0.388 GiB for their results \(417 bytes "
                                         r"each\), above --max-memory-gib 0.1"):
        check_size(big, SimpleNamespace(**{**opts, "max_evaluations": 1e11,
                                           "max_memory_gib": 0.1}))


BOX_1MM = ["--x-mm", "1200..2000", "--y-mm", "-600..600", "--z-mm", "0..600",
           "--x-step-mm", "1", "--y-step-mm", "1", "--z-step-mm", "1"]


@pytest.mark.parametrize("extra, message", [
    # 1 mm steps: 801 x 1201 x 601 placements, refused before any array is made
    (BOX_1MM, "the search has 578162601 placements x 8 points x 12 tool angles x 1 "
              "configurations = 55503609696 evaluations (5.55e+10), above the limit of 1e+08"),
    ([*BOX_1MM, "--max-evaluations", "1e12"],
     "the search's 578162601 placements need 26.4 GiB for their results (49 bytes each), "
     "above --max-memory-gib 2"),
    (["--max-evaluations", "1000"], "= 1728 evaluations (1.73e+03), above the limit of 1e+03"
                                    ": coarsen the steps or narrow the box, or raise"),
    (["--max-evaluations", "0"], "--max-evaluations: expected a positive number"),
    (["--max-memory-gib", "-1"], "--max-memory-gib: expected a positive size in GiB"),
    (["--x-step-mm", "1e-4"], "--x-mm step: 4e+06 grid values from 1400 to 1800 in steps "
                              "of 0.0001: more than 1e+06"),
    (["--min-inv-kappa", "-0.1"], "--min-inv-kappa: expected 0 <= 1/kappa_F < 1 (0: no "
                                  "singularity check), got -0.1"),
    (["--min-inv-kappa", "1.5"], "--min-inv-kappa: expected 0 <= 1/kappa_F < 1"),
    (["--min-inv-kappa", "nan"], "--min-inv-kappa: expected 0 <= 1/kappa_F < 1"),
])
def test_refusals(tmp_path, capsys, extra, message):
    _write_path(tmp_path / "part.csv")
    assert_refused(capsys, _args(tmp_path, *extra), message, watch=[tmp_path])


@pytest.mark.parametrize("wrench, message", [
    ("0,0,0,0,0,0", "--wrench: the process wrench is zero on every path point"),
    ("", "--wrench: empty value"),
    ("1,2,,3,4,5", "--wrench: item 3 is empty"),
])
def test_zero_or_empty_wrench_refused(tmp_path, capsys, wrench, message):
    _write_path(tmp_path / "part.csv")
    assert_refused(capsys, _args(tmp_path, wrench=wrench), message, watch=[tmp_path])


def test_zero_wrench_columns_refused_and_compliance_objective_still_runs(tmp_path, capsys):
    path = tmp_path / "part.csv"
    lines = _write_path(path).read_text().splitlines()
    path.write_text("\n".join([lines[0] + ",fx_N,fy_N,fz_N,mx_Nm,my_Nm,mz_Nm",
                               *(f"{row},0,0,0,0,0,0" for row in lines[1:])]) + "\n")
    assert_refused(capsys, _args(tmp_path, wrench=None),
                   "part.csv (wrench columns): the process wrench is zero", watch=[tmp_path])
    # the compliance objective needs no wrench: valid JSON, no NaN
    assert main(_args(tmp_path, "--objective", "compliance", wrench=None)) == 0
    text = (tmp_path / "out" / "placement.json").read_text()
    summary = json.loads(text, parse_constant=lambda c: pytest.fail(f"{c} in placement.json"))
    assert summary["objective"] > 0 and summary["objective_unit"] == "mm/kN"
