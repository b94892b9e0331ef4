"""Benchmark: 1e5 identifications of 5 tests, batched over trials vs a per-trial loop.

Setting: KR240-2, Table 2 stiffness, the paper's w_eff, poses from the Table
4 zones (a pool simulated once with the nonlinear equilibrium), default
noise model. Timed separately, in the same process:

* simulation of the noisy measurements of all trials (J at the noisy joint
  angles, wrench, displacement);
* batched identification (:func:`analysis.identification.robustness.identify_batch`): A
  from J and the measured wrench (eqs. 16-18), then least squares by QR, for
  OLS (the paper's estimator) and WLS (Cholesky whitening, one reweighting);
* the per-trial loop baseline on a sample of trials: the same A built per
  trial and ``np.linalg.lstsq`` (SVD) per trial, extrapolated to all trials.

The loop and batched estimates are checked to agree on the sample.

Run: ``python benchmarks/bench_identification.py [--trials 100000] [--tests 5] [--loop 5000]``
"""

from __future__ import annotations

import argparse
import time

import numpy as np

from analysis.identification.linear_model import design_block
from analysis.identification.noise import NoiseModel
from analysis.identification.robustness import (
    W_EFF,
    build_pool,
    identify_batch,
    simulate_measurements,
)
from analysis.model.robots import load_robot


def per_trial_loop(Jc: np.ndarray, w: np.ndarray, d: np.ndarray, count: int) -> np.ndarray:
    """OLS of the first ``count`` trials, one np.linalg.lstsq call per trial."""
    out = np.empty((6, count))
    for t in range(count):
        J = np.transpose(Jc[..., t], (2, 1, 0))  # (n, r, j)
        A = design_block(J, w[..., t].T).reshape(-1, 6)
        out[:, t] = np.linalg.lstsq(A, d[..., t].T.reshape(-1), rcond=None)[0]
    return out


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--trials", type=int, default=100_000)
    parser.add_argument("--tests", type=int, default=5)
    parser.add_argument("--loop", type=int, default=5000, help="trials in the loop baseline")
    args = parser.parse_args()

    robot = load_robot("kr240-2")
    noise = NoiseModel()
    rng = np.random.default_rng(0)
    t0 = time.perf_counter()
    pool = build_pool(robot, robot.nominal_stiffness, W_EFF, 2000, rng)
    t_pool = time.perf_counter() - t0

    t0 = time.perf_counter()
    Jc, w, d = simulate_measurements(pool, args.tests, args.trials, noise, rng)
    t_sim = time.perf_counter() - t0

    t0 = time.perf_counter()
    x_ols, _ = identify_batch(Jc, w, d, noise, "ols", with_se=False)
    t_ols = time.perf_counter() - t0
    t0 = time.perf_counter()
    identify_batch(Jc, w, d, noise, "wls", with_se=False)
    t_wls = time.perf_counter() - t0

    n_loop = min(args.loop, args.trials)
    t0 = time.perf_counter()
    x_loop = per_trial_loop(Jc, w, d, n_loop)
    t_loop = (time.perf_counter() - t0) * args.trials / n_loop
    agree = np.max(np.abs(x_loop - x_ols[:, :n_loop]) / np.abs(x_loop))

    print(f"{args.trials} identifications of {args.tests} tests (6 x {6 * args.tests} A each)")
    print(f"  pose pool (2000 poses, nonlinear equilibrium) : {t_pool:7.3f} s")
    print(f"  simulated noisy measurements                  : {t_sim:7.3f} s")
    print(f"  batched OLS (A + QR)                          : {t_ols:7.3f} s")
    print(f"  batched WLS (A + whitening + QR)              : {t_wls:7.3f} s")
    print(f"  per-trial loop, np.linalg.lstsq (from {n_loop})   : {t_loop:7.3f} s")
    print(f"  ratio loop / batched OLS                      : {t_loop / t_ols:7.1f}")
    print(f"  max relative difference loop vs batched       : {agree:.1e}")


if __name__ == "__main__":
    main()
