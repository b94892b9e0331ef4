"""Benchmark: ``--model auto`` on the shop lab, one all-effects campaign of the model-class
study (issue 32: <= 30 s CPU per campaign, so that >= 100 campaigns run on a shared
2-core machine), and its two batched stages against their per-call loops, timed in the
same run.

Work measured:

* campaign: :func:`analysis.identification.studies.model_classes.one_campaign` of seed
  ``--seed`` (simulation, the joint-only exact fit, ``auto``'s backward elimination,
  the study's projection fit), CPU seconds; before this benchmark's branch (per-call
  loops below) 17-19 s CPU on seeds 100-102;
* physics model: the displacement of the realistic-arm physics (gravity and the
  compensator) at the fit's point and its 8 forward-difference neighbours (6 joint
  compliances, the spring's preload and rate): one
  :func:`~analysis.kinetostatics.realistic.displacement_cases` call against a loop of
  :func:`~analysis.kinetostatics.realistic.displacement` calls (the baseline);
* flank grid: joint 2's flank patterns on the 61 x 61 spring grid of the flank search,
  ``_flank_patterns`` at once against a loop of ``_flank_pattern`` per grid point.

Before any ratio, the batched outputs are checked equal to the loops' (bit for bit).
Timing: CPU time (``time.process_time``), best of ``--repeat`` runs per side, the sides
interleaved, BLAS pinned to one thread. Run: ``python benchmarks/bench_model_classes.py
[--repeat 3] [--seed 100]``. Ends with one JSON line.
"""

from __future__ import annotations

import argparse
import time
from dataclasses import replace

import numpy as np
from _load import LoadWindow
from threadpoolctl import threadpool_limits

from analysis.identification.models import fit as F
from analysis.identification.studies import model_classes as mc
from analysis.kinetostatics.realistic import RealisticLab, displacement, displacement_cases
from analysis.model.gravity import gear_torques


def cpu(fn):
    """(cpu seconds, result) of one call."""
    c0 = time.process_time()
    out = fn()
    return time.process_time() - c0, out


def main() -> None:
    load = LoadWindow()
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--repeat", type=int, default=3, help="runs per side (best is kept)")
    ap.add_argument("--seed", type=int, default=100, help="the campaign's seed")
    args = ap.parse_args()
    robot, lab, k, loads, noise = mc.shop_lab()
    tests, _ = mc.simulate(robot, lab, k, loads, 12, noise, args.seed)
    comp = lab.compensator
    spring = np.array([comp.preload, comp.rate])
    x = 1.0 / np.asarray(k, float)
    # the point and its forward-difference neighbours, as the fit's physics model
    xs, springs = [x], [spring]
    for j in range(6):
        xh = x.copy()
        xh[j] += F.FD_STEP * abs(x[j])
        xs.append(xh)
        springs.append(spring)
    for i, h in enumerate((F.FD_PRELOAD, F.FD_RATE)):
        sh = spring.copy()
        sh[i] += h
        xs.append(x)
        springs.append(sh)
    ks, springs = 1.0 / np.array(xs), np.array(springs)
    w0 = np.zeros(6)
    glab = RealisticLab(gravity="on", compensator=comp)

    def loop_physics():
        return np.stack([displacement(robot, replace(glab, compensator=replace(
            comp, preload=float(s[0]), rate=float(s[1]))), kc, tests.q, w0, w0 + tests.w)
            for kc, s in zip(ks, springs, strict=True)])

    def batched_physics():
        return displacement_cases(robot, glab, ks, tests.q, w0, w0 + tests.w, springs)

    taus = (gear_torques(robot, tests.q, np.zeros(6)), gear_torques(robot, tests.q, tests.w))
    data = F.ClassData(robot, tests, tuple(range(6)), noise, "exact", x, taus,
                       np.zeros((len(tests.q), 6, 6)), np.zeros(len(tests.q)),
                       compensator=comp)
    u = np.linspace(-F.FLANK_SEARCH_SE, F.FLANK_SEARCH_SE, F.FLANK_GRID)
    pp = comp.preload + np.repeat(u, u.size) * 50.0
    rr = comp.rate + np.tile(u, u.size) * 500.0

    def loop_flanks():
        return [F._flank_pattern(data, (p, r)) for p, r in zip(pp, rr, strict=True)]

    def batched_flanks():
        return F._flank_patterns(data, pp, rr)

    best = {key: np.inf for key in ("campaign", "phys_loop", "phys_batched", "flank_loop",
                                    "flank_batched")}
    out = {}
    with threadpool_limits(limits=1):
        for _ in range(args.repeat):
            for key, fn in (("phys_loop", loop_physics), ("phys_batched", batched_physics),
                            ("flank_loop", loop_flanks), ("flank_batched", batched_flanks)):
                c, out[key] = cpu(fn)
                best[key] = min(best[key], c)
        c, o = cpu(lambda: mc.one_campaign(robot, lab, k, loads, 12, noise, args.seed))
        best["campaign"] = c
    assert np.array_equal(out["phys_loop"], out["phys_batched"])
    ref, ld = out["flank_batched"]
    assert all(p == (tuple(ref[g].tolist()), tuple(ld[g].tolist()))
               for g, p in enumerate(out["flank_loop"]))
    ratio_phys = best["phys_loop"] / best["phys_batched"]
    ratio_flank = best["flank_loop"] / best["flank_batched"]
    print(f"campaign seed {args.seed}: {best['campaign']:.2f} s CPU ({o.chosen}, covered "
          f"{o.covered}/{o.total}; target <= 30 s)")
    print(f"physics model, 9 cases: loop {1e3 * best['phys_loop']:.1f} ms, batched "
          f"{1e3 * best['phys_batched']:.1f} ms CPU: {ratio_phys:.1f}x; flank grid "
          f"{pp.size} springs: loop {1e3 * best['flank_loop']:.1f} ms, batched "
          f"{1e3 * best['flank_batched']:.1f} ms: {ratio_flank:.1f}x (outputs identical)")
    load.emit({"benchmark": "model_classes", "seed": args.seed, "threads": 1,
               "repeat": args.repeat, "campaign_cpu_s": round(best["campaign"], 3),
               "chosen": o.chosen, "physics_loop_cpu_ms": round(1e3 * best["phys_loop"], 3),
               "physics_batched_cpu_ms": round(1e3 * best["phys_batched"], 3),
               "physics_speedup_cpu": round(ratio_phys, 2),
               "flank_loop_cpu_ms": round(1e3 * best["flank_loop"], 3),
               "flank_batched_cpu_ms": round(1e3 * best["flank_batched"], 3),
               "flank_speedup_cpu": round(ratio_flank, 2), "target_campaign_cpu_s": 30.0,
               "baseline": "per-call loops of displacement() and _flank_pattern() (the code "
                           "before the batching), same run; outputs checked identical",
               "timing": f"CPU time (time.process_time), best of {args.repeat} runs per "
                         "side, interleaved (campaign: one run), BLAS pinned to 1 thread"})


if __name__ == "__main__":
    main()
