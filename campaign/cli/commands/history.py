"""``campaign history``: the fleet ledger (add, list, trend, check, verify).

Each sub-command parses its options, calls one job of :mod:`campaign.jobs.history`
and presents its result; the ledger is ``--db URL`` or ``STIFFNESS_CAMPAIGN_DB``.
``check`` exits 3 when it raises an alarm, ``verify`` when a recorded file changed.
"""

from __future__ import annotations

import json
from pathlib import Path

import typer

from campaign.cli.terminal import echo

#: exit status of ``check`` with an alarm and of ``verify`` with a mismatch
EXIT_ALARM = 3

DB_HELP = ("The ledger: an SQLite file path, sqlite:///PATH or postgresql://user@host/db "
           "(default: the STIFFNESS_CAMPAIGN_DB environment variable).")


def _json(doc: dict) -> None:
    typer.echo(json.dumps(doc, indent=2))


def _k(v) -> str:
    return "-" if v is None else f"{v / 1e3:.1f}"


def register(app: typer.Typer) -> None:
    history = typer.Typer(add_completion=False, no_args_is_help=True,
                          help="The fleet ledger: every campaign of every robot, trends "
                          "with intervals, and an alarm when a joint loses stiffness.")
    app.add_typer(history, name="history")

    @history.command("add")
    def add_cmd(
        paths: list[Path] = typer.Argument(..., help="Run directories, analysis "
                                           "directories or results.json files."),
        db: str = typer.Option(None, "--db", help=DB_HELP),
        robot_id: str = typer.Option(None, "--robot-id", help="The robot's identity when "
                                     "the run names no serial (or to override it)."),
        date: str = typer.Option(None, "--date", help="Campaign date (ISO 8601) when the "
                                 "run has none."),
        supersedes: str = typer.Option(None, "--supersedes", help="report_id of the record "
                                       "this campaign corrects."),
        as_json: bool = typer.Option(False, "--json", help="Print JSON."),
    ) -> None:
        """Record campaigns in the ledger (once per report_id)."""
        from campaign.jobs.history import AddOptions, add

        result = add(AddOptions(tuple(paths), db, robot_id, date, supersedes))
        if as_json:
            _json(result.to_json())
            return
        for r in result.rows:
            verb = "recorded" if r["added"] else "already recorded"
            echo(f"{verb}: {r['report_id']} robot {r['robot']} ({r['date']})")

    @history.command("list")
    def list_cmd(
        robot: str = typer.Option(None, "--robot", help="Only this robot."),
        db: str = typer.Option(None, "--db", help=DB_HELP),
        as_json: bool = typer.Option(False, "--json", help="Print JSON (SI units)."),
    ) -> None:
        """The recorded campaigns, oldest first per robot."""
        from campaign.jobs.history import listing

        result = listing(db, robot)
        if as_json:
            _json(result.to_json())
            return
        echo(f"{'robot':<16} {'date':<25} {'report_id':<21} estimator")
        for c in result.campaigns:
            echo(f"{c['robot']:<16} {c['date']:<25} {c['report_id']:<21} {c['estimator']}")

    @history.command("trend")
    def trend_cmd(
        robot: str = typer.Option(..., "--robot", help="The robot."),
        db: str = typer.Option(None, "--db", help=DB_HELP),
        reference: str = typer.Option(None, "--reference", help="report_id of the reference "
                                      "campaign (default: the first comparable one)."),
        plot: Path = typer.Option(None, "--plot", help="Write the trend plot (.png, .pdf or "
                                  ".svg)."),
        as_json: bool = typer.Option(False, "--json", help="Print JSON (SI units)."),
    ) -> None:
        """k per joint over time with 95 % intervals, and the change against the reference."""
        from campaign.jobs.history import trend

        result = trend(db, robot, reference, plot)
        if as_json:
            _json(result.to_json())
            return
        echo(f"robot {robot}: k in kN m/rad; reference {result.reference}")
        echo(f"{'date':<11} {'report_id':<21} " + " ".join(f"{'k' + str(j):>8}"
                                                          for j in range(1, 7)))
        for c in result.campaigns:
            note = "" if c["compared"] or c["reference"] else f"  (left out: {c['reason']})"
            echo(f"{c['date'][:10]:<11} {c['report_id']:<21} "
                 + " ".join(f"{_k(v):>8}" for v in c["k_Nm_per_rad"]) + note)
        if result.plot:
            echo(f"wrote {result.plot}")

    @history.command("check")
    def check_cmd(
        robot: str = typer.Option(None, "--robot", help="Only this robot (default: all)."),
        db: str = typer.Option(None, "--db", help=DB_HELP),
        min_change: float = typer.Option(5.0, "--min-change", help="Drop worth an alarm, "
                                         "percent of the reference's stiffness."),
        alpha: float = typer.Option(0.05, "--alpha", help="Level: chance of a false alarm "
                                    "per campaign over the six joints."),
        reference: str = typer.Option(None, "--reference", help="report_id of the reference "
                                      "campaign (with --robot)."),
        as_json: bool = typer.Option(False, "--json", help="Print JSON."),
    ) -> None:
        """Has a joint lost more than --min-change percent of its stiffness? Exit 3 if so."""
        from campaign.jobs.history import check

        result = check(db, robot, min_change / 100.0, alpha, reference)
        if as_json:
            _json(result.to_json())
        else:
            for r in result.robots:
                echo(f"robot {r['robot']}: {r['status']} (reference {r['reference']}, "
                     f"latest {r['latest']})")
                for x in r["excluded"]:
                    echo(f"  left out {x['report_id']}: {x['reason']}")
            for a in result.alarms:
                iv = "" if a["interval"] is None else \
                    f", interval [{a['interval'][0]:.2f}, {a['interval'][1]:.2f}] %"
                echo(f"ALARM robot {a['robot']} joint {a['joint']}: "
                     f"{a['change_percent']:+.2f} %{iv} ({a['test']})")
        if result.alarmed:
            raise typer.Exit(EXIT_ALARM)

    @history.command("verify")
    def verify_cmd(
        robot: str = typer.Option(None, "--robot", help="Only this robot."),
        db: str = typer.Option(None, "--db", help=DB_HELP),
        as_json: bool = typer.Option(False, "--json", help="Print JSON."),
    ) -> None:
        """Re-hash the recorded files that exist; exit 3 when one changed."""
        from campaign.jobs.history import verify

        result = verify(db, robot)
        if as_json:
            _json(result.to_json())
        else:
            echo(f"{result.checked} file(s) re-hashed, {len(result.mismatches)} mismatch(es), "
                 f"{len(result.missing)} no longer there")
            for m in result.mismatches:
                echo(f"MISMATCH {m['report_id']} {m['file']}: {m['path']}")
        if result.mismatches:
            raise typer.Exit(EXIT_ALARM)
