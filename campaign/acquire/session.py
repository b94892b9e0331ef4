"""One ``campaign acquire`` session: plan -> safety -> run directory -> instruments -> runner.

Order matters for safety and for the record: the plan is checked against the
limits and printed (dry run) before anything is connected; the operator
confirms; the instruments are connected; then the run directory's
``metadata.json`` is written (with each instrument's ``describe()``), and only
then does anything move.
"""

from __future__ import annotations

import getpass
import hashlib
import os
import sys
from collections.abc import Callable
from dataclasses import dataclass
from importlib.metadata import PackageNotFoundError, version
from pathlib import Path
from typing import Any

from analysis.errors import InputError
from campaign.acquire.checks import limits_for
from campaign.acquire.clock import SimulatedClock, WallClock, describe, utc
from campaign.acquire.ending import ending
from campaign.acquire.instruments import open_instruments
from campaign.acquire.interrupts import interrupt_reason
from campaign.acquire.preflight import dry_run_text, motion_limits, planned_tests
from campaign.acquire.progress import Reporter
from campaign.acquire.robot_claim import hold as hold_robot
from campaign.acquire.rundir import (
    PLAN,
    TESTS,
    RunDir,
    WriteFailure,
    export_parquet,
    read_tests,
    require_new_run_dir,
)
from campaign.acquire.runner import Runner, RunSettings
from campaign.acquire.settle import SettleRule, rule_for
from campaign.planning.plan_output import load_plan
from campaign.protocol import Protocol
from campaign.protocol_copy import portable_copy
from campaign.protocol_robot import protocol_robot
from drivers.errors import SafetyRefusal
from drivers.safety import require_confirmation

PACKAGES = ("robot-stiffness-campaign", "numpy", "pandas", "pyarrow", "pin", "typer", "rich",
            "pyserial", "python-can", "ur-rtde", "pydantic")


@dataclass
class AcquireOptions:
    """Options of one session (see ``campaign acquire --help``)."""

    fake: bool = False
    assume_yes: bool = False
    dry_run: bool = False
    time_scale: float | None = None
    settle_scale: float = 0.5
    operator: str | None = None


@dataclass
class Outcome:
    """What a session did: status, reason, run directory, counts."""

    status: str
    reason: str
    run_dir: Path | None
    ok: int = 0
    failed: int = 0
    #: False when the Parquet exports could not be written (the run is complete in its
    #: text tables; the command then exits with status 1)
    exported: bool = True


def software_versions() -> dict[str, str]:
    out = {"python": sys.version.split()[0]}
    for name in PACKAGES:
        try:
            out[name] = version(name)
        except PackageNotFoundError:
            out[name] = "not installed"
    return out


def _sha(text: str) -> str:
    return hashlib.sha256(text.encode("utf-8")).hexdigest()


def check_time_scale(time_scale: float | None, fake: bool) -> None:
    """Refuse a ``--time-scale`` that is not in (0, MAX_TIME_SCALE] or given without
    ``--fake`` (InputError naming the option)."""
    from campaign.protocol import MAX_TIME_SCALE

    if time_scale is None:
        return
    if not fake:
        raise InputError("--time-scale only applies to the simulated lab (--fake)",
                         where="--time-scale")
    if not time_scale > 0:
        raise InputError("time scale must be positive", where="--time-scale")
    if not time_scale <= MAX_TIME_SCALE:
        raise InputError(f"expected at most {MAX_TIME_SCALE:g}, got {time_scale:g}",
                         where="--time-scale")


def _protocol_copy_name(protocol: Protocol) -> str:
    suffix = Path(protocol.path).suffix.lower() or ".toml"
    return f"protocol{suffix}"


def write_tests_sidecar(run_path: Path, protocol: Protocol, robot: Any) -> None:
    """tests.meta.json next to tests.csv: robot, tool, noise model
    (see campaign/run_format/tests_meta.py).

    Written when the run starts (and on resume when missing), so a copy of the
    run's tests.csv analysed on its own keeps its tool point and noise figures.
    """
    from campaign.run_format.tests_meta import sidecar_path, sidecar_record, write_sidecar
    from campaign.run_noise import noise_from_protocol, protocol_noise_source

    csv_path = Path(run_path) / TESTS
    if os.path.lexists(sidecar_path(csv_path)):
        return  # a link there is refused by RunDir.open
    record = sidecar_record(
        robot_key=protocol.campaign.robot, robot_name=robot.name,
        tool_xyz_mm=protocol.tool.xyz_mm, tool_rpy_deg=protocol.tool.rpy_deg,
        tool_mass_kg=protocol.tool.mass_kg, noise=noise_from_protocol(protocol),
        noise_source=protocol_noise_source(protocol), csv_name=TESTS,
        protocol_sha256=_sha(protocol.text))
    try:
        write_sidecar(csv_path, record)
    except OSError as err:
        raise WriteFailure(sidecar_path(csv_path), err) from err


def base_metadata(protocol: Protocol, plan_text: str, plan_source: Path, robot: Any,
                  tests: list, opts: AcquireOptions, time_scale: float) -> dict[str, Any]:
    """Metadata written before anything is connected (see docs/run_format.md).

    ``repeats`` is the plan's (the same for every test as the planner writes it;
    the protocol's if the plan's differ), ``n_planned_measurements`` the sum over tests.
    """
    n_tests = len(tests)
    per_test = {t.repeats for t in tests}
    repeats = per_test.pop() if len(per_test) == 1 else protocol.campaign.repeats
    n_measurements = sum(t.repeats for t in tests)
    meta: dict[str, Any] = {
        "started_utc": utc(), "ended_utc": None,
        "operator": opts.operator or getpass.getuser(),
        # a login name is not a person's name: the report says which it is
        "operator_source": "--operator" if opts.operator else "OS user (no --operator given)",
        "campaign": protocol.campaign.name,
        "protocol_file": _protocol_copy_name(protocol), "protocol_source": protocol.path,
        "protocol_sha256": _sha(protocol.text),
        "robot": {"name": robot.name, "key": protocol.campaign.robot},
        "tool": protocol.tool.model_dump(),
        "instruments": {role: {"driver": spec.driver, "address": spec.address}
                        for role, spec in protocol.instruments.items()},
        "software": software_versions(),
        "plan_file": PLAN, "plan_source": str(plan_source), "plan_sha256": _sha(plan_text),
        "n_planned_tests": n_tests, "repeats": repeats,
        "n_planned_measurements": n_measurements,
        "fake": opts.fake, "fake_lab": None, "time_scale": time_scale,
        "time_stamps": describe(opts.fake),
        "command": sys.argv, "sessions": [],
    }
    if opts.fake and protocol.lab is not None:
        meta["fake_lab"] = dict(protocol.lab, time_scale=time_scale)
    return meta


def acquire(plan_dir: Path | None, out: Path | None, resume: Path | None,
            opts: AcquireOptions, reporter: Reporter,
            say: Callable[[str], None] = print, ask: Callable[[str], str] = input,
            on_event: Callable[[dict[str, Any]], None] | None = None) -> Outcome:
    """Run (or resume) a campaign; see the module docstring for the order of steps.

    Raises
    ------
    InputError
        Bad plan or options, a plan outside the limits, a refused confirmation.
    """
    if (plan_dir is None) == (resume is None):
        raise InputError("give either --plan PLAN_DIR (a new run) or --resume RUN_DIR",
                         where="campaign acquire")
    check_time_scale(opts.time_scale, opts.fake)
    run: RunDir | None = None
    if out is not None and resume is None:
        require_new_run_dir(out)  # before anything is connected
    if resume is not None:
        run = RunDir.open(resume)
        try:
            protocol, plan, plan_text = load_plan(resume)
        except BaseException:
            run.close()
            raise
        if bool(run.metadata.get("fake")) != opts.fake:
            run.close()
            how = "with" if run.metadata.get("fake") else "without"
            raise InputError(f"this run was started {how} --fake; resume it the same way",
                             where=str(resume))
        where_plan = str(resume / "plan.csv")
    else:
        protocol, plan, plan_text = load_plan(plan_dir)
        where_plan = str(plan_dir / "plan.csv")
    try:
        robot = protocol_robot(protocol)
        tests = planned_tests(protocol, plan, robot, where=where_plan)
        done = run.finished() if run is not None else set()
        if run is not None and all((t.test_id, r) in done for t in tests
                                   for r in range(1, t.repeats + 1)):
            return _nothing_to_resume(run, reporter)
        rule = _settle_rule(protocol, 1.0, opts.settle_scale)  # robot time, for the estimate
        say(dry_run_text(tests, robot, protocol, done,
                         settle_s=(rule.window - 1) * rule.interval))
        if opts.dry_run:
            say("dry run: nothing connected, nothing moved")
            if run is not None:  # a dry run in a long-lived process must not keep the lock
                run.close()
            return Outcome("dry-run", "", resume)
        lab_scale = None
        if opts.fake:
            lab_scale = opts.time_scale or (protocol.lab or {}).get("time_scale") or 1.0
        try:
            require_confirmation("", assume_yes=opts.assume_yes, ask=ask,
                                 say=lambda s: say(s) if s else None)
        except SafetyRefusal as err:
            raise InputError(str(err), where="confirmation") from None
    except BaseException:
        if run is not None:
            run.close()
        raise
    # one robot, one acquisition: a hardware run claims its robot machine-wide before
    # anything is connected (the claim ends with this function, or with the process)
    claim = None
    try:
        claim = None if opts.fake else hold_robot(_robot_name(protocol))
        inst = open_instruments(protocol, opts.fake, lab_scale)
    except BaseException:
        if claim is not None:
            claim.release()
        if run is not None:
            run.close()
        raise
    counts = {"ok": 0, "failed": 0}
    try:
        inst.connect()  # an unreachable instrument leaves no run directory behind
        if run is None:
            meta = base_metadata(protocol, plan_text, plan_dir, robot, tests, opts,
                                 lab_scale or 1.0)
            if protocol.preloaded:
                meta["reference_wrench"] = {
                    "text": "load cases with preload_fraction take their reference readings "
                            "under that fraction of the test wrench; tests.csv gives the "
                            "measured reference wrench (base frame, at P) in fx_ref_N.."
                            "mz_ref_Nm and the displacement loaded minus reference",
                    "preload_fraction": {c.name: c.preload_fraction
                                         for c in protocol.load_cases}}
            copy_text, beside = portable_copy(protocol)  # the robot file in the run too
            meta["protocol_sha256"] = _sha(copy_text)
            run = RunDir.create(out, meta, _protocol_copy_name(protocol), copy_text,
                                plan_text, beside)
        try:
            status, reason = _run_session(run, inst, robot, tests, protocol, opts,
                                          lab_scale, reporter, on_event, counts)
        except WriteFailure as err:
            # only before the runner started: it handles its own write failures
            status, reason = "failed", f"{err}; nothing moved; free space or fix the " \
                                       "permissions, then resume the run"
            try:
                run.set_status(status, reason, ended_utc=utc())
            except WriteFailure:
                pass
    except BaseException as err:
        interrupted = isinstance(err, KeyboardInterrupt) and run is not None
        if run is not None and run.metadata.get("status") == "running":
            try:
                if isinstance(err, KeyboardInterrupt):
                    run.set_status("aborted", interrupt_reason(err), ended_utc=utc())
                else:
                    run.set_status("failed", f"{type(err).__name__}: {err}", ended_utc=utc())
            except WriteFailure:
                pass  # the original error says more than a second failed write
        if not interrupted:
            raise
        # Ctrl-C outside the runner (connecting, exporting): the run is recorded as
        # aborted; the operator still gets the closing lines and the resume command
        status, reason = "aborted", interrupt_reason(err)
    finally:
        inst.close()
        if claim is not None:
            claim.release()
        if run is not None:
            run.close()
    outcome = Outcome(status, reason, run.path, counts["ok"], counts["failed"],
                      exported=counts.get("exported", 1) == 1)
    total = sum(t.repeats for t in tests)
    reporter.finish(status, reason, {**ending(run.path, run.session, status, opts.fake, total),
                                     "ok_this_session": outcome.ok,
                                     "failed_this_session": outcome.failed})
    return outcome


def _robot_name(protocol: Protocol) -> str:
    """The robot an acquisition drives, as its claim names it: "driver address"."""
    spec = protocol.instruments["robot"]
    return f"{spec.driver} {spec.address}"


def _settle_rule(protocol: Protocol, time_scale: float, settle_scale: float) -> SettleRule:
    noise = (protocol.instruments["pose"].noise.translation_um or 30.0) * 1e-6
    return rule_for(noise, time_scale, settle_scale)


def run_clock(run: RunDir, protocol: Protocol, robot: Any, tests: list,
              settle_scale: float) -> WallClock:
    """The clock of the readings' time stamps (:mod:`campaign.acquire.clock`): the lab's
    for a run whose metadata says ``time_stamps`` ``simulated`` (continued from the last
    row of tests.csv on resume), else the wall clock (hardware, or a fake run started
    before the lab had its clock).

    Raises
    ------
    InputError
        The last row's ``t_utc`` is not an ISO 8601 time (names tests.csv and its line).
    """
    stamps = run.metadata.get("time_stamps")
    if not (isinstance(stamps, dict) and stamps.get("clock") == "simulated"):
        return WallClock()
    from drivers.sim.settings import settings_from_protocol
    from drivers.sim.world import SETTLED_AFTER

    rule = _settle_rule(protocol, 1.0, settle_scale)  # robot (simulated) seconds
    lab_settle = settings_from_protocol(protocol.lab or {}).settle_time
    motion = motion_limits(protocol)
    clock = SimulatedClock(motion.speed, motion.acceleration,
                           settle_s=SETTLED_AFTER * lab_settle
                           + (rule.window - 1) * rule.interval,
                           interval_s=rule.interval)
    rows = read_tests(run.path)
    if rows.empty:
        return clock
    last = rows.iloc[-1]
    by_id = {t.test_id: t for t in tests}
    test = by_id.get(int(last["test_id"]))
    try:
        clock.resume(str(last["t_utc"]), None if test is None
                     else robot.to_controller(test.q))
    except ValueError:
        raise InputError(f"t_utc {last['t_utc']!r} is not an ISO 8601 time",
                         where=f"{run.path / TESTS}: line {len(rows) + 1}") from None
    return clock


def _run_session(run: RunDir, inst: Any, robot: Any, tests: list, protocol: Protocol,
                 opts: AcquireOptions, lab_scale: float | None, reporter: Reporter,
                 on_event: Callable[[dict[str, Any]], None] | None,
                 counts: dict[str, int]) -> tuple[str, str]:
    """Record the session in the metadata, run the remaining tests, export Parquet."""
    sessions = run.metadata.setdefault("sessions", [])
    run.session = len(sessions) + 1
    session = {"id": run.session, "started_utc": utc(), "instruments": inst.describe(),
               "lab": inst.lab_addresses or None}
    run.metadata["instruments"] = session["instruments"]
    sessions.append(session)
    run.metadata.update(status="running", reason="")
    run.write_metadata()
    write_tests_sidecar(run.path, protocol, robot)
    reporter.start({"run_dir": str(run.path), "lab": inst.lab_addresses or None})
    settings = RunSettings(settle=_settle_rule(protocol, lab_scale or 1.0, opts.settle_scale))
    runner = Runner(run, robot, tests, inst, reporter, limits_for(protocol),
                    motion_limits(protocol), settings, protocol.safety.max_force_N,
                    protocol.safety.max_moment_N_m, on_event=on_event,
                    clock=run_clock(run, protocol, robot, tests, opts.settle_scale))
    status, reason = runner.run()
    counts.update(runner.counts)
    try:
        export_parquet(run.path)
    except (OSError, ValueError) as err:
        # the measurements are all in tests.csv and samples.jsonl: said in the final
        # line (even with --quiet) and in metadata.json, and the command exits with 1
        counts["exported"] = 0
        why = err.strerror if isinstance(err, OSError) and err.strerror else err
        note = (f"the Parquet exports could not be written ({why}); every measurement is "
                "in tests.csv and samples.jsonl, and campaign analyze writes the exports "
                "when there is room")
        reason = f"{reason}; {note}" if reason else note
        try:
            run.set_status(status, reason, parquet_exported=False)
        except (WriteFailure, InputError):
            pass
    return status, reason


def _nothing_to_resume(run: RunDir, reporter: Reporter) -> Outcome:
    """``--resume`` of a run whose planned tests are all in tests.csv: nothing is started.

    Missing Parquet exports are written, and the status becomes ``complete`` if a
    session ended before saying so (or ``parquet_exported`` true once the exports are
    there); no instrument is connected, nothing moves.
    """
    meta = run.metadata
    exported, why = True, ""
    try:
        if not all((run.path / n).is_file() for n in ("tests.parquet", "samples.parquet")):
            try:
                export_parquet(run.path)
            except (OSError, ValueError) as err:
                exported = False
                why = err.strerror if isinstance(err, OSError) and err.strerror else str(err)
        if meta.get("status") != "complete" or (exported and meta.get("parquet_exported")
                                                is False):
            extra: dict[str, Any] = {"parquet_exported": exported}
            if meta.get("status") != "complete":
                extra["ended_utc"] = utc()
            run.set_status("complete", "", **extra)
        statuses = read_tests(run.path)["status"].astype(str)
    finally:
        run.close()
    ok, failed = int((statuses == "ok").sum()), int((statuses != "ok").sum())
    reason = (f"nothing to resume: all {ok + failed} planned measurements are in tests.csv; "
              "nothing connected, nothing moved")
    if not exported:
        reason += f"; the Parquet exports are still missing ({why})"
    reporter.finish("complete", reason, {"run_dir": str(run.path), "ok": ok, "failed": failed,
                                         "done": ok + failed, "total": ok + failed})
    return Outcome("complete", reason, run.path, ok, failed, exported=exported)
