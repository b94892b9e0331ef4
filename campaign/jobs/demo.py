"""The ``demo`` job: the whole chain on the simulated lab, from a protocol with a ``[fake_lab]``.

plan -> acquire (the simulated lab, the real drivers over loopback, the safety
question answered: nothing real moves) -> analyze, into one directory:
``OUT/plan``, ``OUT/run`` (the run directory) and ``OUT/run/analysis``. Each step
is its own job (:mod:`campaign.jobs.plan`, :mod:`~campaign.jobs.acquire`,
:mod:`~campaign.jobs.analyze`) with its options left at their defaults, so the
demo's files are those the three commands would write. The simulated lab draws
its noise from the protocol's ``[fake_lab]`` seed: the same options give the same
numbers, whichever face runs the job.
"""

from __future__ import annotations

import time
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from analysis.errors import InputError
from campaign.jobs.option_checks import Note, Stage, no_note, no_stage

#: the shipped protocol the demo runs by default (Dumas et al. 2011, KUKA KR240-2)
DEFAULT_PROTOCOL = "kr240-2"


@dataclass(frozen=True)
class DemoOptions:
    """out: the directory of the plan, the run and its analysis (new or empty);
    protocol: a protocol file with a ``[fake_lab]`` table (None: the shipped KR240-2
    protocol); report: write plan_map.png and the analysis' HTML/PDF report; tests:
    test poses planned (None: the protocol's); candidates: candidate poses the
    planner draws; time_scale: the simulated lab's time runs this many times faster
    than the wall clock (None: the protocol's ``[fake_lab]`` time_scale)."""

    out: Path
    protocol: Path | None = None
    report: bool = True
    tests: int | None = None
    candidates: int = 10000
    time_scale: float | None = None


@dataclass
class DemoResult:
    """protocol: the protocol file run; plan, acquisition, analysis: the three jobs'
    results (analysis None when the acquisition did not complete); elapsed_s: wall
    clock time of the whole demo (s)."""

    protocol: Path
    plan: Any
    acquisition: Any
    analysis: Any = None
    elapsed_s: float = 0.0

    @property
    def succeeded(self) -> bool:
        """Acquired completely and analysed: the command's exit status 0."""
        return self.analysis is not None

    def to_json(self) -> dict:
        """The document ``campaign demo --json`` prints: each job's own document."""
        return {"status": "complete" if self.succeeded else self.acquisition.status,
                "protocol": str(self.protocol), "plan": self.plan.to_json(),
                "acquisition": self.acquisition.to_json(),
                "analysis": None if self.analysis is None else self.analysis.to_json(),
                "elapsed_s": self.elapsed_s}


def demo_protocol(o: DemoOptions) -> Path:
    """The protocol file of the demo: ``o.protocol``, else the shipped KR240-2 one."""
    if o.protocol is not None:
        path = Path(o.protocol)
        if not path.is_file():
            raise InputError("protocol file not found", where=str(path))
        return path
    from campaign.shipped_protocols import shipped_protocol

    return shipped_protocol(DEFAULT_PROTOCOL)


def check_demo_dir(out: Path) -> None:
    """Refuse a demo directory that is a link, a file, or a non-empty directory."""
    from analysis.output_files import refuse_link

    refuse_link(out)
    if out.exists() and not out.is_dir():
        raise InputError("exists and is not a directory", where=str(out))
    if out.exists() and any(out.iterdir()):
        raise InputError("demo directory exists and is not empty; choose another --out",
                         where=str(out))


def run(o: DemoOptions, say: Note = no_note, stage: Stage = no_stage, reporter=None,
        on_assumptions: Callable[[dict], None] | None = None,
        warn: Callable[[str], None] | None = None,
        should_abort: Callable[[], bool] | None = None) -> DemoResult:
    """Plan, acquire on the simulated lab and analyse into ``o.out``.

    ``say``: a line per step (and the plan's summary); ``stage``: around long steps;
    ``reporter``: the acquisition's progress (:class:`campaign.acquire.progress.Reporter`,
    default silent); ``on_assumptions`` and ``warn``: the analysis' hooks;
    ``should_abort``: polled at each phase of the acquisition (True: its Ctrl-C path, the
    run recorded as aborted, no analysis). Bad input
    raises InputError before anything is written; a failed or aborted acquisition
    returns a result without analysis (the run directory says why).
    """
    from campaign.jobs import acquire, analyze, plan
    from campaign.protocol import load_protocol

    if o.time_scale is not None and not o.time_scale > 0:
        raise InputError("expected a positive number", where="--time-scale")
    protocol_file = demo_protocol(o)
    protocol = load_protocol(protocol_file)
    if protocol.lab is None:
        raise InputError("the demo runs on the simulated lab: the protocol needs a "
                         "[fake_lab] table", where=protocol.where("fake_lab"))
    out = Path(o.out)
    check_demo_dir(out)
    t0 = time.monotonic()
    say(f"1/3 plan: {protocol.campaign.name}")
    planned = plan.run(plan.PlanOptions(protocol_file, out / "plan", candidates=o.candidates,
                                        tests=o.tests, figure=o.report), stage=stage)
    say(planned.text.rstrip("\n"))
    say("2/3 acquire on the simulated lab (real drivers over loopback)")
    acquired = acquire.run(acquire.AcquireJobOptions(
        plan=out / "plan", out=out / "run", fake=True, assume_yes=True,
        time_scale=o.time_scale), reporter, say=say, should_abort=should_abort)
    result = DemoResult(protocol_file, planned, acquired)
    if acquired.succeeded:
        say("3/3 analyze the run")
        result.analysis = analyze.run(analyze.AnalyzeOptions(run_dir=out / "run",
                                                             report=o.report),
                                      stage=stage, on_assumptions=on_assumptions, warn=warn)
    result.elapsed_s = time.monotonic() - t0
    return result
