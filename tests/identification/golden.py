"""The identification's golden corpus: campaigns that exercise every path, and their results.

``python -m tests.identification.golden --write DIR`` analyses every case of :data:`CASES`
with the analyze job (``campaign analyze``, no report) and writes ``DIR/<case>.json``: the
case's results.json with its strings and volatile fields dropped (one line of JSON);
``tests/identification/test_golden.py`` flattens it to ``{"key.path[i]": number}``
(booleans as 0/1) and compares the current code's numbers to the committed files in
``golden/``.

The cases: the README walk-through's run (the KR240-2 protocol's 5 poses x 3 repeats,
simulated at the paper's stiffness, written as a run directory) with each method and a
robust mode; a simulated 6-pose campaign per method; each robust mode with wls and exact
on the same campaign with three glitches; the outlier flags and refits (ols and exact on
the glitched campaign); a tool point; translations only; the residual-scaled covariance
with three joints; two poses closer than the held-out radius (held out together); and the
1200-test campaign of ``test_streamed_identify.py`` with the block sizes shrunk so that
every large-campaign path runs (ols and exact).

The script names no module of ``analysis.identification`` by a fixed path where the
package layout may change: :func:`_module` takes the first of several that exists, so the
same script writes the golden files from an older tree
(``PYTHONPATH=OLD python tests/identification/golden.py --write DIR``).
"""

from __future__ import annotations

import argparse
import contextlib
import importlib
import json
import math
import sys
import tempfile
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

HERE = Path(__file__).resolve().parent
GOLDEN_DIR = HERE / "golden"
#: results.json fields dropped: identifiers, dates, paths, digests, versions
VOLATILE = ("report_id", "tests_data", "model_file", "assumptions.robot_file")


def _module(*names: str):
    """The first of the modules ``names`` that can be imported (old and new layouts)."""
    for name in names:
        try:
            return importlib.import_module(name)
        except ModuleNotFoundError:
            continue
    raise ModuleNotFoundError(f"none of {names}")


def _where(attr: str, *names: str) -> list:
    """Every module of ``names`` that can be imported and has ``attr``."""
    out = []
    for name in names:
        try:
            mod = importlib.import_module(name)
        except ModuleNotFoundError:
            continue
        if hasattr(mod, attr):
            out.append(mod)
    return out


P = "analysis.identification."
#: the block sizes the streamed case shrinks, each where it is read (old and new layouts)
STREAMED = {
    "TALL_ROWS": (600, [P + "lsq", P + "linalg.lsq"]),
    "TEST_BLOCK": (97, [P + "lsq", P + "linalg.lsq", P + "estimate"]),
    "ROW_BLOCK": (50, [P + "lsq", P + "linalg.lsq"]),
    "RESIDUAL_ROWS_HELD": (100, [P + "estimate", P + "outliers", P + "checks.outliers"]),
    "EVAL_BLOCK": (101, [P + "gauss_newton", P + "estimators.gauss_newton",
                        P + "streaming.blocks"]),
    "LAZY_TESTS": (300, [P + "per_test", P + "streaming.per_test"]),
    "FOLD_CHUNK": (7, [P + "crossval", P + "validation.crossval", P + "validation.downdate"]),
}


@contextlib.contextmanager
def streamed_sizes():
    """The large-campaign paths on a small campaign: the block sizes shrunk, restored after."""
    saved = []
    for attr, (value, names) in STREAMED.items():
        mods = _where(attr, *names)
        if not mods:
            raise RuntimeError(f"no module has {attr}: update golden.STREAMED")
        for mod in mods:
            saved.append((mod, attr, getattr(mod, attr)))
            setattr(mod, attr, value)
    _clear_caches()
    try:
        yield
    finally:
        for mod, attr, value in saved:
            setattr(mod, attr, value)
        _clear_caches()


def _clear_caches() -> None:
    """Empty the module-level caches of the layout the golden files were first written
    with (commit fc8521e: the Jacobian cache ``_J_CACHE`` of
    ``analysis/identification/fitting.py``, whose fits are now
    ``estimators/fit_solvers.py``, and ``poses._LAST``), so the script still runs on that
    tree. The present layout keeps no module-level cache
    (``tests/identification/test_no_module_caches.py``): nothing is found there."""
    for mod in _where("_J_CACHE", P + "fitting"):  # the pre-restructure module name
        mod._J_CACHE.clear()
    for mod in _where("_LAST", P + "poses"):
        mod._LAST.clear()


# ---- the campaigns ---------------------------------------------------------------------

TRUE_K = np.array([1409800.0, 400760.0, 935280.0, 360000.0, 370000.0, 380000.0])
SIM_POSES_DEG = np.array([
    [0, 40, -200, 45, 45, 45],
    [20, 80, -220, 30, 60, -30],
    [0, 10, 15, 45, 45, 45],
    [-20, 120, 15, 60, 30, 10],
    [10, 60, -180, -40, 50, 80],
    [-30, 50, -190, 20, -45, 60],
], dtype=float)
SIM_WRENCHES = np.array([
    [0, 2200, 2200, 200, 200, 0],
    [0, -2200, 2200, -200, 200, 0],
    [2200, 0, 2200, 200, -200, 0],
    [0, 2200, -2200, 200, 200, 0],
], dtype=float)
SIM_REPEATS = 2
SIM_SIGMA = np.array([30e-6] * 3 + [20e-6] * 3)
SIM_FORCE_SIGMA, SIM_MOMENT_SIGMA = 0.5, 0.05
#: (test, component, size): the glitched campaign's three outliers (m, rad)
GLITCHES = ((5, 1, 0.6e-3), (20, 2, -0.5e-3), (33, 4, 0.4e-3))
CSV_COLUMNS = (["pose"] + [f"q{i}_deg" for i in range(1, 7)]
               + ["fx_N", "fy_N", "fz_N", "mx_Nm", "my_Nm", "mz_Nm"]
               + ["dx_mm", "dy_mm", "dz_mm", "rx_mrad", "ry_mrad", "rz_mrad"])


def _robot():
    from analysis.model.robots import load_robot

    return load_robot("kr240-2")


def _write_csv(path: Path, pose, q, w, d) -> Path:
    """Tests (SI) in the CSV import format (deg, N, N m, mm, mrad), every digit kept."""
    rows = [",".join(CSV_COLUMNS)]
    for i in range(len(q)):
        cells = [str(pose[i])] + [repr(float(v)) for v in np.degrees(q[i])] \
            + [repr(float(v)) for v in w[i]] + [repr(float(v)) for v in 1e3 * d[i]]
        rows.append(",".join("" if c == "nan" else c for c in cells))
    path.write_text("\n".join(rows) + "\n")
    return path


def _simulate(robot, q, w, seed: int, sigma, force_sigma, moment_sigma):
    from analysis.kinetostatics.equilibrium import displacement_screw

    rng = np.random.default_rng(seed)
    d = displacement_screw(robot, q, TRUE_K, w) + rng.normal(size=q.shape) * sigma
    wn = w + rng.normal(size=w.shape) * np.array([force_sigma] * 3 + [moment_sigma] * 3)
    return wn, d


def sim_campaign(path: Path, glitch: bool = False, rotations: bool = True,
                 near_pair: bool = False, seed: int = 11) -> Path:
    """The 6-pose simulated campaign (4 loads x 2 repeats per pose) as a CSV file."""
    robot = _robot()
    poses = SIM_POSES_DEG.copy()
    if near_pair:
        poses[5] = poses[4] + [0.5, -0.3, 0.4, 0.2, 0.0, -0.5]  # 0.9 deg from pose 5
    per = len(SIM_WRENCHES) * SIM_REPEATS
    q = np.radians(np.repeat(poses, per, axis=0))
    w = np.tile(np.repeat(SIM_WRENCHES, SIM_REPEATS, axis=0), (len(poses), 1))
    wn, d = _simulate(robot, q, w, seed, SIM_SIGMA, SIM_FORCE_SIGMA, SIM_MOMENT_SIGMA)
    if glitch:
        for i, c, size in GLITCHES:
            d[i, c] += size
    if not rotations:
        d[:, 3:] = np.nan
    pose = np.repeat([f"S{i + 1}" for i in range(len(poses))], per)
    return _write_csv(path, pose, q, wn, d)


def streamed_campaign(path: Path) -> Path:
    """The 1200-test campaign of ``test_streamed_identify.py`` (80 poses x 15 loads, one
    1 mm glitch, the default noise model's sigmas) as a CSV file."""
    sample_poses = _module(P + "robustness", P + "studies.robustness").sample_poses
    noise = _module(P + "noise").NoiseModel()
    robot = _robot()
    rng = np.random.default_rng(21)
    poses = sample_poses(robot, 80, rng, min_inverse_condition=0.3)
    q = np.repeat(poses, 15, axis=0)
    w_eff = np.array([0.0, 2200.0, 2200.0, 200.0, 200.0, 0.0])
    w = w_eff * rng.uniform(0.3, 0.6, size=(len(q), 1)) * rng.choice([-1.0, 1.0], (len(q), 1))
    wn, d = _simulate(robot, q, w, 4, noise.displacement_sigma, noise.force_sigma,
                      noise.moment_sigma)
    d[37, 1] += 1e-3
    pose = np.repeat([f"Z{i + 1}" for i in range(len(poses))], 15)
    return _write_csv(path, pose, q, wn, d)


def walkthrough_run(path: Path) -> Path:
    """The README walk-through's run: the KR240-2 protocol's design, simulated (seed 1)."""
    from tests.report.report_runs import simulated_rows, write_run

    return write_run(path, simulated_rows(1))


# ---- the cases ---------------------------------------------------------------------------

SIM_NOISE = {"translation_sigma_m": 30e-6, "rotation_sigma_rad": 20e-6,
             "force_sigma_N": SIM_FORCE_SIGMA, "moment_sigma_Nm": SIM_MOMENT_SIGMA}


@dataclass(frozen=True)
class Case:
    """One analysis of the corpus: its data (``source``) and the analyze job's options."""

    name: str
    source: str  # "run", "sim", "glitch", "translations", "near", "streamed"
    options: dict = field(default_factory=dict)
    streamed: bool = False


CASES = (
    Case("run-exact", "run"),
    Case("run-ols", "run", {"method": "ols"}),
    Case("run-wls", "run", {"method": "wls"}),
    Case("run-exact-tukey", "run", {"robust": "tukey"}),
    Case("sim-ols", "sim", {"method": "ols", **SIM_NOISE}),
    Case("sim-wls", "sim", {"method": "wls", **SIM_NOISE}),
    Case("sim-exact", "sim", {"method": "exact", **SIM_NOISE}),
    *(Case(f"glitch-{m}-{r}", "glitch", {"method": m, "robust": r, **SIM_NOISE})
      for m in ("wls", "exact") for r in ("huber", "tukey")),
    Case("glitch-ols-outliers", "glitch", {"method": "ols", **SIM_NOISE}),
    Case("glitch-exact-outliers", "glitch", {"method": "exact", **SIM_NOISE}),
    Case("sim-exact-tool", "sim", {"method": "exact", "tool_xyz_mm": (0.0, 0.0, 80.0),
                                   "tool_rpy_deg": (0.0, 0.0, 0.0), **SIM_NOISE}),
    Case("sim-wls-translations", "translations", {"method": "wls", **SIM_NOISE}),
    Case("sim-exact-translations", "translations", {"method": "exact", **SIM_NOISE}),
    Case("sim-exact-residual-123", "sim", {"method": "exact", "covariance": "residual",
                                           "joints": "1,2,3", **SIM_NOISE}),
    Case("near-exact-heldout", "near", {"method": "exact", **SIM_NOISE}),
    Case("near-ols-heldout", "near", {"method": "ols", **SIM_NOISE}),
    Case("streamed-ols", "streamed", {"method": "ols"}, streamed=True),
    Case("streamed-exact", "streamed", {"method": "exact"}, streamed=True),
)


def _source(case: Case, tmp: Path) -> dict:
    """The analyze job's input options of the case's data (made once per source)."""
    made = tmp / f"data-{case.source}"
    if case.source == "run":
        if not made.exists():
            walkthrough_run(made)
        return {"run_dir": made}
    csv = made.with_suffix(".csv")
    if not csv.exists():
        if case.source == "streamed":
            streamed_campaign(csv)
        else:
            sim_campaign(csv, glitch=case.source == "glitch",
                         rotations=case.source != "translations",
                         near_pair=case.source == "near")
    return {"measurements": csv, "robot": "kr240-2"}


def analyse(case: Case, tmp: Path) -> dict:
    """The case's results.json (the analyze job, no report, a refused result kept)."""
    from campaign.jobs.analyze import AnalyzeOptions, run

    out = tmp / f"out-{case.name}"
    options = AnalyzeOptions(**_source(case, tmp), **case.options, out=out, report=False,
                             accept_misfit=True, force=True)
    with streamed_sizes() if case.streamed else contextlib.nullcontext():
        _clear_caches()
        run(options)
    return json.loads((out / "results.json").read_text())


def numbers(doc, prefix: str = "") -> dict[str, float | None]:
    """The numbers of a results.json document, flattened (booleans as 0/1, None kept as
    None: a missing value is a result too); strings and :data:`VOLATILE` fields dropped."""
    out: dict[str, float | None] = {}
    if prefix in VOLATILE:
        return out
    if isinstance(doc, dict):
        for k, v in doc.items():
            out.update(numbers(v, f"{prefix}.{k}" if prefix else str(k)))
    elif isinstance(doc, list):
        for i, v in enumerate(doc):
            out.update(numbers(v, f"{prefix}[{i}]"))
    elif isinstance(doc, bool):
        out[prefix] = float(doc)
    elif isinstance(doc, int | float):
        out[prefix] = float(doc)
    elif doc is None:
        out[prefix] = None
    return out


def stripped(doc, prefix: str = ""):
    """The document with its strings and :data:`VOLATILE` fields dropped (what is kept
    of a case in its golden file; :func:`numbers` flattens it)."""
    if isinstance(doc, dict):
        out = {}
        for k, v in doc.items():
            key = f"{prefix}.{k}" if prefix else str(k)
            if key not in VOLATILE and not isinstance(v, str):
                out[k] = stripped(v, key)
        return out
    if isinstance(doc, list):
        return [stripped(v, f"{prefix}[{i}]") for i, v in enumerate(doc)
                if not isinstance(v, str)]
    return doc


def case_numbers(case: Case, tmp: Path) -> dict:
    """The flattened numbers of the case's results.json, as run now."""
    return numbers(analyse(case, tmp))


def golden_numbers(case: Case, directory: Path = GOLDEN_DIR) -> dict:
    """The flattened numbers of the case's golden file."""
    return numbers(json.loads((directory / f"{case.name}.json").read_text()))


def write(directory: Path, names: list[str] | None = None) -> list[Path]:
    """Write ``<case>.json`` of every case (or of ``names``) into ``directory``."""
    directory.mkdir(parents=True, exist_ok=True)
    paths = []
    with tempfile.TemporaryDirectory(prefix="golden-") as tmp:
        for case in CASES:
            if names and case.name not in names:
                continue
            got = stripped(analyse(case, Path(tmp)))
            path = directory / f"{case.name}.json"
            path.write_text(json.dumps(got, separators=(",", ":")) + "\n")
            paths.append(path)
    return paths


def differences(want: dict, got: dict, rtol: float, atol: float) -> list[str]:
    """Lines naming each key whose value differs beyond ``rtol`` (relative) and ``atol``
    (absolute, for values near zero), or is present on one side only."""
    out = []
    for key in sorted(set(want) | set(got)):
        if key not in got or key not in want:
            out.append(f"{key}: {'missing' if key not in got else 'new'}")
            continue
        a, b = want[key], got[key]
        if a is None or b is None:
            if a is not b:
                out.append(f"{key}: golden {a}, now {b}")
            continue
        if math.isnan(a) or math.isnan(b):
            if not (math.isnan(a) and math.isnan(b)):
                out.append(f"{key}: golden {a}, now {b}")
            continue
        if a == b:
            continue
        if not abs(a - b) <= max(atol, rtol * max(abs(a), abs(b))):
            rel = abs(a - b) / max(abs(a), abs(b))
            out.append(f"{key}: golden {a!r}, now {b!r} (relative {rel:.2e})")
    return out


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--write", type=Path, default=None,
                    help=f"directory for <case>.json (default {GOLDEN_DIR})")
    ap.add_argument("cases", nargs="*", help="case names (default all)")
    a = ap.parse_args(argv)
    for p in write(a.write or GOLDEN_DIR, a.cases or None):
        print(p)
    return 0


if __name__ == "__main__":
    sys.path.append(str(HERE.parents[1]))  # as a file: tests.report importable (PYTHONPATH first)
    sys.exit(main())
