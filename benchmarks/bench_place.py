"""Speed of the placement search's inner work: (placement, point, tool angle) evaluations.

One evaluation = closed-form IK of the target pose in one configuration, joint
limits, J at P, and the deflection of P under the tool-frame wrench (linear
compliance without K_C). Three implementations of the same work, timed the same
way (best of ``--repeat``, wall clock and process CPU time), outputs compared:

* batched: :func:`analysis.placement.evaluate.evaluate`, which for a spherical
  wrist takes J from the IK's frames in structure-of-arrays form;
* general batched: the same IK, then J from the general chain kinematics
  (``evaluate(..., general=True)``, the previous implementation's route);
* per point (the baseline, made as fast as we could write it): the same
  closed-form IK written for one pose on Python floats (:class:`ScalarWristIK`,
  the equations of :mod:`analysis.model.ik_soa`; calling the batched solver
  with one pose costs ~20x more), the joint limits on floats, Pinocchio's frame
  Jacobian at P with one ``Data`` created once, and the deflection in three
  small numpy products.

Two tools: the bare flange (the wrist centre on the tool axis, so the arm is
solved once per point for all tool angles) and a tool offset sideways (arm
solved per angle). Also timed: the whole search step for one configuration
(:func:`analysis.placement.search.evaluate_chunk`: evaluation, continuous angle
selection, verification). The machine's load average is printed: the
development machine is shared, wall-clock figures vary with it. Ends with one
JSON line.

The whole command (issue 36): ``campaign place`` on the README example
(``--search readme``; 3.8e6 evaluations) and (``--search 1e8``; both by default)
the same box at 25 mm steps in x and y and 50 mm in z (9.7e7 evaluations), each
in a subprocess on the local Dask cluster (2 workers on the 2-core machine):
wall, user and system time of the command and its worker processes
(``RUSAGE_CHILDREN``), the search's evaluations/s, its estimate against the
search's time (placement.json's ``run``; also what the probe's wall time alone would
have said), the probe's rate per process, and the search's evaluations per CPU second
of its workers against the probe's per CPU second (the search's own overheads, which
the machine's load does not change); then issue 36's targets, met or not.

    python benchmarks/bench_place.py [--placements 16] [--sample 300] [--repeat 5]
        [--search both|readme|1e8|none]
"""

from __future__ import annotations

import argparse
import json
import os
import re
import resource
import subprocess
import sys
import tempfile
import time
from math import atan2, cos, inf, pi, sin, sqrt
from pathlib import Path

import numpy as np
import pinocchio as pin
from _load import LoadWindow

from analysis.model.ik import IKSolver
from analysis.model.robots import load_robot, with_tool
from analysis.placement.evaluate import OK, Problem, evaluate
from analysis.placement.poses import target_poses
from analysis.placement.search import evaluate_chunk

FLAGS = (-1, -1, -1)
LWA = pin.ReferenceFrame.LOCAL_WORLD_ALIGNED
NAN3 = np.full(3, np.nan)


def timed(fn, repeat):
    """(result, best wall time (s), best CPU time (s)) of ``repeat`` calls."""
    wall = cpu = np.inf
    for _ in range(repeat):
        t0, c0 = time.perf_counter(), time.process_time()
        out = fn()
        wall = min(wall, time.perf_counter() - t0)
        cpu = min(cpu, time.process_time() - c0)
    return out, wall, cpu


class ScalarWristIK:
    """The closed-form spherical-wrist IK of :mod:`analysis.model.ik_soa` for one pose,
    on Python floats (``math``): the same equations and branch signs, no arrays.

    Built from the solver's normalised chain; ``solve(R, p)`` returns the six
    joint angles (rad, wrapped to (-pi, pi]) or None where the branch has no
    solution.
    """

    def __init__(self, chain, flags):
        L = chain
        self.flags = flags
        self.rot = [m.tolist() for m in L.rot]  # rot[i][r][c]
        self.pos = [v.tolist() for v in L.pos]
        self.tool, self.k6z, self.k6x = L.tool, L.k6z, L.k6x
        self.lateral, self.s3 = float(L.lateral), int(L.s3)
        t = L.pos[2][:2]
        w = L.wrist[:2]
        R2 = L.rot[2][:2, :2]
        T = R2.T @ t
        self.t, self.w, self.R2 = t.tolist(), w.tolist(), R2.tolist()
        self.tw = float(t @ t + w @ w)
        self.A3, self.B3 = float(T @ w), float(T[1] * w[0] - T[0] * w[1])
        w2 = L.rot[4][:, 2]
        x = L.rot[4] @ L.rot[5][:, 2]
        self.w2, self.x = w2.tolist(), x.tolist()
        self.c12 = float(w2[2])
        self.wx = float(w2 @ x)
        self.xx = float(x @ x)
        self.n12 = [-float(w2[1]), float(w2[0]), 0.0]
        self.nn = float(w2[0] ** 2 + w2[1] ** 2)
        xp = x - self.wx * w2
        self.xp, self.wxp = xp.tolist(), np.cross(w2, xp).tolist()
        self.frame3 = [L.rot[3][:, i].tolist() for i in range(3)]

    @staticmethod
    def _branch(a, b, rhs, sign, slack):
        rho2 = a * a + b * b
        if not (rho2 > slack * slack and rhs * rhs <= rho2 * (1.0 + 1e-12) ** 2):
            return None
        root = sqrt(max(rho2 - rhs * rhs, 0.0))
        if sign < 0:
            root = -root
        return (a * rhs - b * root) / rho2, (b * rhs + a * root) / rho2

    def _to_base(self, v, frame, c, s):
        rot = self.rot
        for i in range(frame - 1, -1, -1):
            v = (c[i] * v[0] - s[i] * v[1], s[i] * v[0] + c[i] * v[1], v[2])
            m = rot[i]
            v = (m[0][0] * v[0] + m[0][1] * v[1] + m[0][2] * v[2],
                 m[1][0] * v[0] + m[1][1] * v[1] + m[1][2] * v[2],
                 m[2][0] * v[0] + m[2][1] * v[1] + m[2][2] * v[2])
        return v

    def solve(self, R, p):
        shoulder, elbow, wrist = self.flags
        rot, pos = self.rot, self.pos
        centre = (p + R.dot(self.tool)).tolist()
        z6, x6 = R.dot(self.k6z).tolist(), R.dot(self.k6x).tolist()
        m, o = rot[0], pos[0]
        d = (centre[0] - o[0], centre[1] - o[1], centre[2] - o[2])
        e = tuple(m[0][j] * d[0] + m[1][j] * d[1] + m[2][j] * d[2] for j in range(3))
        u = (rot[1][0][2], rot[1][1][2], rot[1][2][2])
        cs1 = self._branch(u[0] * e[0] + u[1] * e[1], u[0] * e[1] - u[1] * e[0],
                           self.lateral - u[2] * e[2], shoulder, 1e-9)
        if cs1 is None:
            return None
        c1, s1 = cs1
        E = (c1 * e[0] + s1 * e[1], c1 * e[1] - s1 * e[0], e[2])
        m, o = rot[1], pos[1]
        d = (E[0] - o[0], E[1] - o[1], E[2] - o[2])
        f0 = m[0][0] * d[0] + m[1][0] * d[1] + m[2][0] * d[2]
        f1 = m[0][1] * d[0] + m[1][1] * d[1] + m[2][1] * d[2]
        cs3 = self._branch(self.A3, self.B3, 0.5 * (f0 * f0 + f1 * f1 - self.tw),
                           elbow * self.s3, 1e-12)
        if cs3 is None:
            return None
        c3, s3 = cs3
        t, w, R2 = self.t, self.w, self.R2
        wr0, wr1 = c3 * w[0] - s3 * w[1], s3 * w[0] + c3 * w[1]
        ux = t[0] + R2[0][0] * wr0 + R2[0][1] * wr1
        uy = t[1] + R2[1][0] * wr0 + R2[1][1] * wr1
        q2 = atan2(ux * f1 - uy * f0, ux * f0 + uy * f1)
        c2, s2 = cos(q2), sin(q2)
        c, s = [c1, c2, c3], [s1, s2, s3]
        F = [self._to_base(v, 3, c, s) for v in self.frame3]
        y = [F[i][0] * z6[0] + F[i][1] * z6[1] + F[i][2] * z6[2] for i in range(3)]
        w2, c12, den = self.w2, self.c12, self.c12 * self.c12 - 1.0
        alpha = (c12 * self.wx - y[2]) / den
        beta = (c12 * y[2] - self.wx) / den
        g2 = (self.xx - alpha * alpha - beta * beta - 2.0 * alpha * beta * c12) / self.nn
        if not g2 > -1e-9:
            return None
        gamma = sqrt(max(g2, 0.0))
        if wrist < 0:
            gamma = -gamma
        n12 = self.n12
        z = (beta * w2[0] + gamma * n12[0], beta * w2[1] + gamma * n12[1], alpha + beta * w2[2])
        xp, wxp = self.xp, self.wxp
        q5 = atan2(wxp[0] * z[0] + wxp[1] * z[1] + wxp[2] * z[2],
                   xp[0] * z[0] + xp[1] * z[1] + xp[2] * z[2])
        q4 = atan2(z[0] * y[1] - z[1] * y[0], z[0] * y[0] + z[1] * y[1])
        c4, s4, c5, s5 = cos(q4), sin(q4), cos(q5), sin(q5)
        v = [F[i][0] * x6[0] + F[i][1] * x6[1] + F[i][2] * x6[2] for i in range(3)]
        for (cc, ss, m) in ((c4, s4, rot[4]), (c5, s5, rot[5])):
            v = (cc * v[0] + ss * v[1], cc * v[1] - ss * v[0], v[2])
            v = tuple(m[0][j] * v[0] + m[1][j] * v[1] + m[2][j] * v[2] for j in range(3))
        q = [atan2(s1, c1), q2, atan2(s3, c3), q4, q5, atan2(v[1], v[0])]
        return [pi - (pi - a) % (2 * pi) for a in q]


def fit_limits_one(q, lower, upper):
    """:func:`analysis.model.ik.fit_limits` for one pose on floats: each angle moved by
    whole turns into [lower, upper] (the turn nearest the middle); None if one fits in none."""
    out = []
    for a, lo, hi in zip(q, lower, upper, strict=True):
        mid, best, gap = 0.5 * (lo + hi), None, inf
        for turn in (-2, -1, 0, 1, 2):
            cand = a + 2 * pi * turn
            if lo <= cand <= hi and abs(cand - mid) < gap:
                best, gap = cand, abs(cand - mid)
        if best is None:
            return None
        out.append(best)
    return out


class PerPoint:
    """The evaluation of one target pose (the baseline): the scalar IK above, the limits
    on floats, Pinocchio's frame Jacobian at P (``Data`` once) and the deflection
    ``J_p K_theta^-1 J^T w`` under the tool wrench turned to the base frame."""

    def __init__(self, robot, solver, w_tool, k, margin):
        self.ik = ScalarWristIK(solver.normal, FLAGS)
        self.lower = (robot.lower + margin).tolist()
        self.upper = (robot.upper - margin).tolist()
        self.model, self.data, self.tip = robot.model, robot.model.createData(), robot.tip_frame
        self.W = np.asarray(w_tool, dtype=float).reshape(2, 3)  # rows: force, moment
        self.inv_k = 1.0 / np.asarray(k, dtype=float)

    def __call__(self, T):
        R = T[:3, :3]
        q = self.ik.solve(R, T[:3, 3])
        q = None if q is None else fit_limits_one(q, self.lower, self.upper)
        if q is None:
            return NAN3
        pin.computeJointJacobians(self.model, self.data, np.array(q))
        J = pin.getFrameJacobian(self.model, self.data, self.tip, LWA)
        w = self.W.dot(R.T).ravel()  # [R f; R m]
        return J[:3].dot(w.dot(J) * self.inv_k)


def case(robot, args, rng, w_tool, loop):
    """Figures of one robot/tool: rates (evaluations/s) and output agreement."""
    solver = IKSolver.for_robot(robot)
    n_pts = 100
    t = np.linspace(0, 2 * np.pi, n_pts, endpoint=False)
    pts = np.stack([0.15 * np.cos(t), 0.1 * np.sin(t), np.zeros(n_pts)], axis=1)
    problem = Problem(robot=robot, points=pts, axes=np.tile([0, 0, -1.0], (n_pts, 1)),
                      wrench=np.tile(w_tool, (n_pts, 1)),
                      angles=np.radians(np.arange(0, 360, 10.0)), k=robot.nominal_stiffness,
                      length=0.682, min_inv_kappa=0.05, margin=np.radians(2),
                      max_step=np.radians(10), objective="max", flags=(FLAGS,))
    G = np.column_stack([rng.uniform(1.3, 2.0, args.placements),
                         rng.uniform(-0.5, 0.5, args.placements),
                         rng.uniform(0.0, 0.6, args.placements),
                         rng.uniform(-0.5, 0.5, args.placements)])
    R = problem.rotations
    evaluate(problem, solver, G[:1], FLAGS, R)  # warm-up
    tr, wall, cpu = timed(lambda: evaluate(problem, solver, G, FLAGS, R), args.repeat)
    n = tr.cost.size
    gen, g_wall, g_cpu = timed(lambda: evaluate(problem, solver, G, FLAGS, R, general=True),
                               max(1, args.repeat // 2))
    ok = tr.reason == OK
    # same reasons; deflections to 1e-12 of the largest (rounding of two evaluation orders)
    general_agree = bool(np.array_equal(tr.reason, gen.reason)
                         and np.allclose(tr.dp[ok], gen.dp[ok], rtol=0,
                                         atol=1e-12 * np.abs(gen.dp[ok]).max(initial=0))
                         and np.allclose(tr.cost[ok], gen.cost[ok], rtol=1e-12, atol=0))
    fig = {"evaluations": n, "feasible": round(float(ok.mean()), 3),
           "batched_per_s": round(n / wall), "batched_cpu_per_s": round(n / cpu),
           "general_batched_per_s": round(n / g_wall),
           "general_batched_cpu_per_s": round(n / g_cpu),
           "general_batched_agrees": general_agree}
    if loop:
        T = target_poses(G, pts, R).reshape(-1, 4, 4)
        idx = rng.choice(n, size=args.sample, replace=False)
        point = PerPoint(robot, solver, w_tool, robot.nominal_stiffness, problem.margin)
        res, l_wall, l_cpu = timed(lambda: np.array([point(T[i]) for i in idx]),
                                   max(1, args.repeat // 2))
        sok = tr.reason.reshape(-1)[idx] == OK
        agree = bool(np.allclose(res[sok], tr.dp.reshape(-1, 3)[idx][sok], rtol=1e-9, atol=1e-15)
                     and np.all(np.isnan(res[~sok])))
        ref = tr.dp.reshape(-1, 3)[idx][sok]
        rel = float(np.abs(res[sok] - ref).max(initial=0) / np.abs(ref).max(initial=1e-300))
        fig |= {"loop_per_s": round(args.sample / l_wall),
                "loop_cpu_per_s": round(args.sample / l_cpu), "loop_agrees": agree,
                "loop_max_rel_diff": rel}
        chunk, c_wall, c_cpu = timed(lambda: evaluate_chunk(problem, G), 1)
        fig |= {"search_step_per_s": round(n / c_wall), "search_step_cpu_per_s": round(n / c_cpu),
                "search_feasible_placements": int(np.isfinite(chunk.value).sum())}
    return fig


ROOT = Path(__file__).resolve().parents[1]
README_BOX = ["--robot", "kr240-2", "--path", str(ROOT / "examples" / "part_circle.csv"),
              "--x-mm", "1200..2000", "--y-mm", "-600..600", "--z-mm", "0..600"]
SEARCHES = {"readme": README_BOX,
            "1e8": [*README_BOX, "--x-step-mm", "25", "--y-step-mm", "25", "--z-step-mm", "50"]}


def command(name: str) -> dict:
    """``campaign place`` of :data:`SEARCHES` ``name`` in a subprocess: wall, user and
    system time (the command and its Dask workers), the search's figures."""
    with tempfile.TemporaryDirectory(prefix="bench-place-") as tmp:
        r0 = resource.getrusage(resource.RUSAGE_CHILDREN)
        t0 = time.perf_counter()
        done = subprocess.run([sys.executable, "-m", "campaign", "place", *SEARCHES[name],
                               "--out", str(Path(tmp) / "out"), "--program", "none"],
                              capture_output=True, text=True, cwd=ROOT)
        wall = time.perf_counter() - t0
        r1 = resource.getrusage(resource.RUSAGE_CHILDREN)
        if done.returncode != 0:
            raise SystemExit(f"campaign place ({name}) failed: {done.stderr.strip()[-400:]}")
        doc = json.loads((Path(tmp) / "out" / "placement.json").read_text())
    run = doc["run"]
    text = " ".join(done.stdout.split())
    rate = re.search(r"where the search runs: ([\d.e+]+) evaluations/s per process", text)
    user, system = r1.ru_utime - r0.ru_utime, r1.ru_stime - r0.ru_stime
    per_placement = doc["search_space"]["evaluations"] / doc["search_space"]["placements"]
    probe_cpu_rate = (run["probe_placements"] * per_placement / run["probe_cpu_seconds"]
                      if run.get("probe_cpu_seconds") else None)

    def ratio(a: float, b: float) -> float:
        """The larger over the smaller."""
        return round(max(a, b) / max(min(a, b), 1e-9), 3)

    return {"evaluations": doc["search_space"]["evaluations"], "wall_s": round(wall, 2),
            "user_s": round(user, 2), "system_s": round(system, 2),
            "system_over_wall": round(system / wall, 3),
            "search_s": run["seconds"], "expected_s": run["expected_seconds"],
            "estimate_ratio": ratio(run["seconds"], run["expected_seconds"]),
            "estimate_over_search": round(run["expected_seconds"] / run["seconds"], 3),
            # the estimate before the core share (the probe's wall time scaled up)
            "expected_probe_wall_s": run.get("expected_seconds_probe_wall"),
            "estimate_ratio_probe_wall": (ratio(run["seconds"],
                                                run["expected_seconds_probe_wall"])
                                          if run.get("expected_seconds_probe_wall") else None),
            "load_average_at_start": run.get("load_average"),
            "other_runnable_at_start": run.get("other_runnable"),
            "core_share": run.get("core_share"),
            "startup_s": run["startup_seconds"], "placements_per_task": run["placements_per_task"],
            "evaluations_per_s": run["evaluations_per_second"],
            "probe_per_process_per_s": float(rate.group(1)) if rate else None,
            "search_cpu_s": run.get("cpu_seconds"),
            "evaluations_per_cpu_s": run.get("evaluations_per_cpu_second"),
            "probe_per_cpu_s": round(probe_cpu_rate) if probe_cpu_rate else None,
            # the search's evaluations per CPU second of its workers (every thread) over the
            # probe's per CPU second of its thread: the search's own overheads, load apart
            "cpu_rate_over_probe": (round(run["evaluations_per_cpu_second"] / probe_cpu_rate, 3)
                                    if probe_cpu_rate and run.get("evaluations_per_cpu_second")
                                    else None),
            "where": run["where"]}


def main() -> None:
    load_window = LoadWindow()
    ap = argparse.ArgumentParser()
    ap.add_argument("--placements", type=int, default=16)
    ap.add_argument("--sample", type=int, default=300)
    ap.add_argument("--repeat", type=int, default=5)
    ap.add_argument("--search", choices=("readme", "1e8", "both", "none"), default="both",
                    help="whole `campaign place` runs to time (1e8: ~2 min of 2 cores)")
    args = ap.parse_args()
    names = {"readme": ["readme"], "1e8": ["1e8"], "both": ["readme", "1e8"],
             "none": []}[args.search]
    commands = {name: command(name) for name in names}
    for name, c in commands.items():
        print(f"campaign place, {name} ({c['evaluations']:,} evaluations, {c['where']}): "
              f"wall {c['wall_s']} s, user {c['user_s']} s, system {c['system_s']} s "
              f"({c['system_over_wall']:.0%} of wall); search {c['search_s']} s at "
              f"{c['evaluations_per_s']:,.0f} evaluations/s (probe "
              f"{c['probe_per_process_per_s']:.3g}/s per process), estimate "
              f"{c['expected_s']} s (x{c['estimate_ratio']}), "
              f"cluster ready in {c['startup_s']} s, tasks of {c['placements_per_task']}")
        print(f"  load average {c['load_average_at_start']}, other runnable "
              f"{c['other_runnable_at_start']} at the start, {c['core_share']:.0%} "
              f"of a core assumed per process; the probe's wall time alone would have said "
              f"{c['expected_probe_wall_s']} s (x{c['estimate_ratio_probe_wall']}); workers' "
              f"CPU {c['search_cpu_s']} s: {c['evaluations_per_cpu_s']:,} evaluations per CPU "
              f"second, {c['cpu_rate_over_probe']} of the probe's {c['probe_per_cpu_s']:,}")
    if commands:
        from targets import check_all

        for target, status, value in check_all("place", {"commands": commands}):
            if value is not None:
                print(f"  target {target.name} {target.op} {target.limit:g}: {value:.3g} -> "
                      f"{status}")
    w_tool = np.array([400.0, 250.0, -300.0, 0.0, 0.0, 20.0])
    robot = load_robot("kr240-2")
    load0 = os.getloadavg()[0]
    flange = case(robot, args, np.random.default_rng(0), w_tool, loop=True)
    offset = case(with_tool(robot, np.array([0.06, 0.0, 0.2]), np.zeros(3)), args,
                  np.random.default_rng(0), w_tool, loop=False)
    load = round(max(load0, os.getloadavg()[0]), 1)
    f = flange
    print(f"KR240-2, {f['evaluations']} (placement, point, angle) evaluations, "
          f"{f['feasible']:.0%} feasible; load average {load} on {os.cpu_count()} cores")
    print(f"  batched (J from the IK's frames): {f['batched_per_s']:,} /s wall, "
          f"{f['batched_cpu_per_s']:,} /s CPU")
    print(f"  general batched (chain kinematics for J): {f['general_batched_per_s']:,} /s wall, "
          f"{f['general_batched_cpu_per_s']:,} /s CPU; outputs agree: "
          f"{f['general_batched_agrees']}")
    print(f"  per-point Pinocchio loop: {f['loop_per_s']:,} /s wall, {f['loop_cpu_per_s']:,} /s "
          f"CPU on {args.sample}; outputs agree: {f['loop_agrees']} (max difference "
          f"{f['loop_max_rel_diff']:.1e} of the largest deflection)")
    print(f"  whole search step (evaluation + angle selection + verification): "
          f"{f['search_step_per_s']:,} /s wall, {f['search_step_cpu_per_s']:,} /s CPU")
    print(f"  tool offset 60 mm sideways (arm solved per angle): batched "
          f"{offset['batched_per_s']:,} /s wall, {offset['batched_cpu_per_s']:,} /s CPU; "
          f"general batched agrees: {offset['general_batched_agrees']}")
    agree = f["loop_agrees"] and f["general_batched_agrees"] and offset["general_batched_agrees"]
    load_window.emit({"benchmark": "place", "evaluations": f["evaluations"],
                      "batched_evaluations_per_s": f["batched_per_s"],
                      "batched_cpu_evaluations_per_s": f["batched_cpu_per_s"],
                      "general_batched_evaluations_per_s": f["general_batched_per_s"],
                      "loop_evaluations_per_s": f["loop_per_s"],
                      "loop_cpu_evaluations_per_s": f["loop_cpu_per_s"],
                      "ratio": round(f["batched_per_s"] / f["loop_per_s"], 1),
                      "ratio_cpu": round(f["batched_cpu_per_s"] / f["loop_cpu_per_s"], 1),
                      "ratio_vs_general_batched": round(
                          f["batched_per_s"] / f["general_batched_per_s"], 1),
                      "search_step_evaluations_per_s": f["search_step_per_s"],
                      "offset_tool_batched_evaluations_per_s": offset["batched_per_s"],
                      "offset_tool_batched_cpu_evaluations_per_s": offset["batched_cpu_per_s"],
                      "load_average": load, "outputs_agree": bool(agree),
                      "commands": commands,
                      "loop_max_rel_diff": f["loop_max_rel_diff"],
                      "sample": args.sample, "placements": args.placements,
                      "baseline": "per-point loop, made fast: the same closed-form IK "
                                  "written for one pose on Python floats, limits on floats, "
                                  "Pinocchio frame Jacobian (Data once)",
                      "timing": f"wall time (time.perf_counter) and CPU time "
                                f"(time.process_time), best of {args.repeat} runs (the "
                                f"general batched route and the loop best of "
                                f"{max(1, args.repeat // 2)}), BLAS threads at their "
                                "default; the loop on a random sample"})
    if not agree:
        raise SystemExit("outputs disagree")


if __name__ == "__main__":
    main()
