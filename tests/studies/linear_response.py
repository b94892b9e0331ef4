"""The exact fit's error at one seeded campaign, predicted from the noise draws alone.

For the campaign of :func:`tests.studies.zscore_study.campaign` (same seed, same draws),
without fitting: the first-order response of the weighted least-squares estimate to the
noise, ``x_hat - x = B sum_tests F^T W e`` with ``B = (sum F^T W F)^-1``, F the exact
model's Jacobian in x, W the fit's weights (the inverse of
:func:`~analysis.identification.streaming.covariances.covariances_per_test`), all at the
truth, and e the residual noise of each test:

    e = e_d - (df/dw) e_w - (df/dq) e_q

(e_d the displacement noise, e_w the wrench's, e_q the encoders'; df/dw and df/dq of the
exact model by central differences, not the linear model's J C J^T the weights use).
Returns, per joint of k,

* ``z_lin`` = -(B b)_j / sqrt(B_jj) (k = 1/x: the sign flips), and its parts from the
  tracker (``z_d``), the F/T sensor (``z_w``) and the encoders (``z_q``), which the fit's
  z must equal to first order (the wrench errors-in-variables shift it corrects is even
  in the noise and not in this response);
* ``var_ratio``: the variance of that response given the campaign's poses and loads,
  ``B (sum F^T W Sigma W F) B`` with the true per-test covariance Sigma (noise figures
  as simulated), over the fit's ``B``: 1 when the interval is the right size for this
  campaign, whatever its number of tests.

    PYTHONPATH=. python -m tests.studies.linear_response --tests 1e6 --seed 1034

prints one JSON line (``fit_z`` too with ``--fit``: the fit's z for comparison).
Memory: blocks of 20 000 tests; CPU ~55 s at 1e6 tests (13 model evaluations a test).

:func:`linear_model_response` is the same response of the linear model (F = A, the
wrench noise through J C J^T, no equilibrium solved; the tracker and F/T parts, the
encoders' left out), ~5 s at 1e6 tests, for many seeds:

    PYTHONPATH=. python -m tests.studies.linear_response --linear --tests 1e6 \
        --seed 1100 --seeds 200

prints a JSON line per seed and a last one with the mean and sd of z_lin per joint. Given
the poses, that z_lin is exactly normal with variance B (sum A^T W Sigma W A) B / B_jj <= 1
(Sigma the simulated covariance; W leaves out only the encoders' part of Sigma^-1), so its
spread over seeds says how wide the fit's z may scatter by chance alone at that N.
"""

from __future__ import annotations

import argparse
import json
import sys
import time

import numpy as np

from analysis.identification.estimators.exact_model import model_displacement_state
from analysis.identification.noise import NoiseModel
from analysis.identification.streaming.covariances import covariances_per_test
from analysis.model.kinematics import jacobian
from analysis.model.robots import load_robot
from tests.studies.zscore_study import _draws, _simulation

BLOCK = 20_000
#: central-difference steps: N, N m, rad (the model is smooth; errors ~h^2, far below 1e-6)
STEP_FORCE, STEP_MOMENT, STEP_ANGLE = 1e-3, 1e-4, 1e-7
ZERO = NoiseModel(translation_sigma_override=0.0, rotation_sigma_override=0.0,
                  force_sigma=0.0, moment_sigma=0.0, joint_sigma_override=0.0)


def _derivative(f, base, steps):
    """(m, 6, k) central differences of f (m, 6) in each column of base (m, k)."""
    out = np.empty(base.shape[:1] + (6, base.shape[1]))
    for i, h in enumerate(steps):
        e = np.zeros(base.shape[1])
        e[i] = h
        out[:, :, i] = (f(base + e) - f(base - e)) / (2 * h)
    return out


def linear_response(n: int, seed: int, noise: NoiseModel | None = None,
                    fitted: NoiseModel | None = None) -> dict:
    """The first-order error of the exact fit of campaign (n, seed), see the module
    docstring; ``noise``: the figures simulated (default ``NoiseModel()``); ``fitted``:
    those the fit weights with and its interval assumes, if not the same."""
    t0 = time.process_time()
    noise = NoiseModel() if noise is None else noise
    fitted = noise if fitted is None else fitted
    robot = load_robot("kr240-2")
    simulate = _simulation()
    # the same draws with and without the noise figures: noise = noisy - exact
    _, q0, w0, d0 = simulate(n, seed=seed, noise=ZERO)
    _, q1, w1, d1 = simulate(n, seed=seed, noise=noise)
    # the study clips the read angles to the joint range (a pose at a limit)
    q1 = np.clip(q1, robot.lower, robot.upper)
    x = 1.0 / robot.nominal_stiffness
    sd2, sw2, sq2 = noise.displacement_sigma**2, noise.wrench_sigma**2, noise.joint_sigma**2
    M = np.zeros((6, 6))
    V = {s: np.zeros((6, 6)) for s in "dwq"}
    b = {s: np.zeros(6) for s in "dwq"}
    for s in range(0, n, BLOCK):
        sl = slice(s, min(n, s + BLOCK))
        q, w = q0[sl], w0[sl]
        _, F, _, dq = model_displacement_state(robot, q, x, w, True)
        W = np.linalg.inv(covariances_per_test(fitted, jacobian(robot, q), x,
                                               np.ones((len(q), 6), bool), w))
        fw = _derivative(lambda ww, q=q, dq=dq: model_displacement_state(
            robot, q, x, ww, False, dq)[0], w, [STEP_FORCE] * 3 + [STEP_MOMENT] * 3)
        fq = _derivative(lambda qq, w=w, dq=dq: model_displacement_state(
            robot, qq, x, w, False, dq)[0], q, [STEP_ANGLE] * 6)
        WF = W @ F
        M += np.einsum("mij,mik->jk", F, WF)
        cov = {"d": np.broadcast_to(np.diag(sd2), (len(q), 6, 6)),
               "w": (fw * sw2) @ np.swapaxes(fw, -1, -2),
               "q": sq2 * (fq @ np.swapaxes(fq, -1, -2))}
        err = {"d": d1[sl] - d0[sl],
               "w": -np.einsum("mij,mj->mi", fw, w1[sl] - w0[sl]),
               "q": -np.einsum("mij,mj->mi", fq, q1[sl] - q0[sl])}
        for src in "dwq":
            V[src] += np.einsum("mij,mil,mlk->jk", WF, cov[src], WF)
            b[src] += np.einsum("mij,mi->j", WF, err[src])
    B = np.linalg.inv(M)
    se_x = np.sqrt(np.diag(B))
    var = sum(np.diag(B @ V[src] @ B) for src in "dwq")
    z = {src: -(B @ b[src]) / se_x for src in "dwq"}
    return {"tests": n, "seed": seed,
            "var_ratio": (var / se_x**2).tolist(),
            "z_lin": (z["d"] + z["w"] + z["q"]).tolist(),
            "z_d": z["d"].tolist(), "z_w": z["w"].tolist(), "z_q": z["q"].tolist(),
            "se_k": (se_x / x**2).tolist(), "cpu_s": round(time.process_time() - t0, 1)}


def linear_model_response(n: int, seed: int, noise: NoiseModel | None = None) -> dict:
    """The linear model's first-order response to campaign (n, seed)'s tracker and F/T
    draws (see the module docstring): z_lin = z_d + z_w per joint of k."""
    t0 = time.process_time()
    noise = NoiseModel() if noise is None else noise
    robot = load_robot("kr240-2")
    dr = _draws()(robot, n, seed=seed, noise=noise)
    x = 1.0 / robot.nominal_stiffness
    J_pose = jacobian(robot, dr.poses)
    M = np.zeros((6, 6))
    b = {s: np.zeros(6) for s in "dw"}
    for s in range(0, n, BLOCK):
        sl = slice(s, min(n, s + BLOCK))
        J, w = J_pose[dr.index[sl]], dr.wrench[sl]
        A = J * np.einsum("mij,mi->mj", J, w)[:, None, :]   # column j: J_j (J_j . w)
        W = np.linalg.inv(covariances_per_test(noise, J, x, np.ones((len(J), 6), bool), w))
        WA = W @ A
        M += np.einsum("mij,mik->jk", A, WA)
        b["d"] += np.einsum("mij,mi->j", WA, dr.e_d[sl])
        C = (J * x) @ np.swapaxes(J, -1, -2)
        b["w"] -= np.einsum("mij,mi->j", WA, np.einsum("mij,mj->mi", C, dr.e_w[sl]))
    B = np.linalg.inv(M)
    se_x = np.sqrt(np.diag(B))
    z = {src: -(B @ b[src]) / se_x for src in "dw"}
    return {"tests": n, "seed": seed, "z_lin": (z["d"] + z["w"]).tolist(),
            "z_d": z["d"].tolist(), "z_w": z["w"].tolist(),
            "cpu_s": round(time.process_time() - t0, 1)}


def main(argv: list[str] | None = None) -> int:
    from tests.studies.zscore_study import _size, campaign

    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--tests", type=_size, default=10_000)
    ap.add_argument("--seed", type=int, default=1000)
    ap.add_argument("--fit", action="store_true", help="also fit the campaign (its z)")
    ap.add_argument("--linear", action="store_true",
                    help="the linear model's response (tracker and F/T, ~5 s at 1e6 tests)")
    ap.add_argument("--seeds", type=int, default=1, help="with --linear: seeds from --seed on")
    args = ap.parse_args(argv)
    if args.linear:
        rows = []
        for seed in range(args.seed, args.seed + max(1, args.seeds)):
            rows.append(linear_model_response(args.tests, seed))
            print(json.dumps({k: np.round(v, 4).tolist() if isinstance(v, list) else v
                              for k, v in rows[-1].items()}), flush=True)
        z = np.array([r["z_lin"] for r in rows])
        print(json.dumps({"tests": args.tests, "seeds": len(rows),
                          "mean_z_lin": np.round(z.mean(axis=0), 3).tolist(),
                          "sd_z_lin": np.round(z.std(axis=0, ddof=1), 3).tolist()
                          if len(rows) > 1 else None}))
        return 0
    out = linear_response(args.tests, args.seed)
    if args.fit:
        out["fit_z"] = campaign(args.tests, args.seed)["z"]
    print(json.dumps({k: np.round(v, 4).tolist() if isinstance(v, list) else v
                      for k, v in out.items()}))
    return 0


if __name__ == "__main__":
    sys.exit(main())
