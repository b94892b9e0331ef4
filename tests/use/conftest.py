"""An identified model.toml written by ``campaign analyze`` from simulated tests."""

from __future__ import annotations

import numpy as np
import pandas as pd
import pytest

from analysis.identification.io.columns import CSV_COLUMNS
from analysis.kinetostatics.equilibrium import displacement_screw
from analysis.model.robots import load_robot
from campaign.cli import main
from tests.use._campaigns import NOISE, POSES_DEG, REPEATS, TRUE_K, WRENCHES


def write_tests_csv(path, seed: int = 3, k=TRUE_K) -> None:
    """The demo design's 15 tests with noise, in the public CSV import format."""
    robot = load_robot("kr240-2")
    rng = np.random.default_rng(seed)
    q = np.radians(np.repeat(POSES_DEG, REPEATS, axis=0))
    w = np.repeat(WRENCHES, REPEATS, axis=0)
    d = displacement_screw(robot, q, k, w) + rng.normal(size=(len(q), 6)) * NOISE.displacement_sigma
    data = np.concatenate([np.degrees(q), w, 1e3 * d], axis=1)
    frame = pd.DataFrame(data, columns=CSV_COLUMNS[1:])
    frame.insert(0, "pose", [f"P{i // REPEATS + 1}" for i in range(len(q))])
    frame.to_csv(path, index=False)


#: the simulation's own noise figures: the defaults are larger, and a chi-square far
#: below its degrees of freedom is refused as "too good to be true"
SIGMAS = ["--translation-sigma-um", f"{1e6 * NOISE.displacement_sigma[0]:.6g}",
          "--rotation-sigma-urad", f"{1e6 * NOISE.displacement_sigma[3]:.6g}",
          "--force-sigma-N", "1e-9", "--moment-sigma-Nm", "1e-9"]


def analyze(tmp, name: str, extra=(), seed: int = 3, k=TRUE_K):
    csv = tmp / f"{name}.csv"
    write_tests_csv(csv, seed, k)
    out = tmp / name
    assert main(["analyze", "--measurements", str(csv), "--robot", "kr240-2", "--out",
                 str(out), "--no-report", *SIGMAS, *extra]) == 0
    return out


@pytest.fixture(scope="session")
def identified(tmp_path_factory):
    """Analysis directory (results.json, model.toml) of a simulated KR240-2 campaign."""
    return analyze(tmp_path_factory.mktemp("use"), "full")
