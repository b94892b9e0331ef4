"""``campaign robustness``: Monte-Carlo spread of the identified k vs number of tests (Fig. 7)."""

from __future__ import annotations

from pathlib import Path

import typer
from rich.console import Console
from rich.table import Table

from analysis.errors import InputError
from campaign.cli.terminal import (
    DEFAULT_METHOD,
    PANEL_NOISE,
    PANEL_OUTPUT,
    PANEL_ROBOT,
    Method,
    RotationSource,
    print_json,
    print_wrapped,
)
from campaign.options import TOOL_RPY_HELP, TOOL_XYZ_HELP, numbers_option


def parse_tests(text: str) -> list[int]:
    """``"1..20"``, ``"1,2,5,10"`` or a mix (``"1..5,10,20"``) -> sorted test counts."""
    out: set[int] = set()
    for part in text.split(","):
        part = part.strip()
        try:
            if ".." in part:
                lo, hi = (int(v) for v in part.split(".."))
                if hi < lo:
                    raise ValueError
                out.update(range(lo, hi + 1))
            else:
                out.add(int(part))
        except ValueError as err:
            raise InputError(f"{part!r} is not a count or a range a..b", where="--tests") from err
    return sorted(out)  # the job refuses none, < 1 and too many


#: panel of --help (campaign.cli.terminal)
_STUDY = "Monte-Carlo study"
_TRACKER = "Rotation measurement"

def _print(console: Console, summary, title: str) -> None:
    table = Table(title=title)
    table.add_column("tests", justify="right")
    for j in sorted(summary["joint"].unique()):
        table.add_column(f"k{j} std/k (%)", justify="right")
    for n, s in summary.groupby("n_tests"):
        table.add_row(str(n), *[f"{100 * v:.2f}" for v in s.sort_values("joint")["relative_std"]])
    console.print(table)


def register(app: typer.Typer) -> None:
    @app.command("robustness")
    def robustness(
        robot: str = typer.Option(..., help="Built-in name, robot file or URDF.",
            rich_help_panel=PANEL_ROBOT),
        tip: str = typer.Option(None, help="Tool frame of a URDF.", rich_help_panel=PANEL_ROBOT),
        tool_xyz_mm: str = typer.Option(None, help=TOOL_XYZ_HELP, rich_help_panel=PANEL_ROBOT),
        tool_rpy_deg: str = typer.Option(None, help=TOOL_RPY_HELP, rich_help_panel=PANEL_ROBOT),
        joint_stiffness: str = typer.Option(
            None, help="True k1,...,k6 (N m/rad); default the model's nominal values.",
            rich_help_panel=PANEL_ROBOT),
        wrench: str = typer.Option(
            None, help="fx,fy,fz (N), mx,my,mz (N m) at P, base frame; default the paper's "
            "w_eff = 0,2200,2200,200,200,0.", rich_help_panel=PANEL_ROBOT),
        tests: str = typer.Option("1..20", help="Numbers of tests, e.g. 1..20 or 1,2,5,10.",
            rich_help_panel=_STUDY),
        trials: int = typer.Option(1000, help="Monte-Carlo trials per number of tests.",
            rich_help_panel=_STUDY),
        method: Method = typer.Option(
            DEFAULT_METHOD, help="exact (the default, as campaign analyze: nonlinear, ~100 x "
            "slower than the linear fits), ols (the paper's estimator as in its Fig. 7, "
            "without the linearisation-bias correction of campaign analyze), or wls.",
            rich_help_panel=_STUDY),
        seed: int = typer.Option(0, help="Random seed.", rich_help_panel=_STUDY),
        pool_size: int = typer.Option(2000, help="Poses drawn from the zones and simulated.",
            rich_help_panel=_STUDY),
        min_dexterity: float = typer.Option(
            0.2, help="Minimum 1/kappa_F of the normalized Jacobian of a drawn pose.",
            rich_help_panel=_STUDY),
        translation_sigma_um: float = typer.Option(
            None, "--translation-sigma-um",
            help="Override: sigma of one displacement component (um).",
            rich_help_panel=PANEL_NOISE),
        rotation_sigma_urad: float = typer.Option(
            None, "--rotation-sigma-urad", help="Override: sigma of one rotation component "
            "(urad).", rich_help_panel=PANEL_NOISE),
        old_translation: float = typer.Option(None, "--sigma-translation-um", hidden=True),
        old_rotation: float = typer.Option(None, "--sigma-rotation-urad", hidden=True),
        rotation_source: RotationSource = typer.Option(
            None, help="reflectors (3 reflectors on the tool, default) or probe (6-DoF).",
            rich_help_panel=_TRACKER),
        reflector_radius_mm: float = typer.Option(
            None, help="Circumradius of the reflector triangle (mm), default 100.",
            rich_help_panel=PANEL_NOISE),
        tracker_distance_m: float = typer.Option(
            None, help="Tracker-to-tool distance (m), default 3.", rich_help_panel=PANEL_NOISE),
        force_sigma_n: float = typer.Option(
            None, "--force-sigma-N", help="Sigma of a force component (N), default 15.6.",
            rich_help_panel=PANEL_NOISE),
        moment_sigma_nm: float = typer.Option(
            None, "--moment-sigma-Nm", help="Sigma of a moment component (N m), default 2.5.",
            rich_help_panel=PANEL_NOISE),
        encoder_resolution_deg: float = typer.Option(
            None, help="Joint encoder resolution (deg), default 0.001.",
            rich_help_panel=PANEL_NOISE),
        out: Path = typer.Option(None, help="Directory for robustness.csv/.png/.json.",
            rich_help_panel=PANEL_OUTPUT),
        as_json: bool = typer.Option(False, "--json", help="Print the settings and the "
                                     "table as JSON (SI units) instead of the table.",
            rich_help_panel=PANEL_OUTPUT),
    ) -> None:
        """Spread of the identified joint stiffness against the number of tests.

        Poses are drawn from the robot's good zones (whole joint range for
        robots without zones) with 1/kappa_F >= --min-dexterity; displacements
        come from the nonlinear equilibrium; normal noise on displacement,
        wrench and joint angles; identification as in the paper (eqs. 16-21).
        """
        import numpy as np

        from campaign.cli.commands.analyze import _alias
        from campaign.jobs.robustness import RobustnessOptions, run

        def scaled(v, f):
            return None if v is None else v * f

        sigma_translation_um = _alias(translation_sigma_um, old_translation,
                                      "--translation-sigma-um")
        sigma_rotation_urad = _alias(rotation_sigma_urad, old_rotation, "--rotation-sigma-urad")
        options = RobustnessOptions(
            robot, tip, numbers_option(tool_xyz_mm, "--tool-xyz-mm"),
            numbers_option(tool_rpy_deg, "--tool-rpy-deg"),
            numbers_option(joint_stiffness, "--joint-stiffness"),
            numbers_option(wrench, "--wrench"), parse_tests(tests), trials, method, seed,
            pool_size, min_dexterity, scaled(sigma_translation_um, 1e-6),
            scaled(sigma_rotation_urad, 1e-6), rotation_source,
            scaled(reflector_radius_mm, 1e-3), tracker_distance_m, force_sigma_n,
            moment_sigma_nm, scaled(encoder_resolution_deg, np.pi / 180.0), out)
        console = Console(stderr=as_json)
        bar = _Bar(console)
        result = run(options, progress=bar.advance, started=bar.start,
                     note=lambda text: print_wrapped(console, text))
        summary, settings = result.table, result.settings
        if not as_json:
            _print(console, summary, f"{settings['robot']}: relative spread of k "
                   f"({settings['method']}, {trials} trials)")
        print_wrapped(console, settings["method_note"])
        for note in settings["notes"]:
            print_wrapped(console, f"note: {note}")
        for path in result.files:
            print_wrapped(console, f"wrote {path}")
        if as_json:
            print_json(result.to_json())


class _Bar:
    """The Monte-Carlo progress bar of the command line (on ``console``; transient)."""

    def __init__(self, console: Console) -> None:
        self.console, self.progress, self.task, self.done = console, None, None, 0

    def start(self, total: int):
        from rich.progress import BarColumn, Progress, TextColumn, TimeRemainingColumn

        self.progress = Progress(TextColumn("{task.description}"), BarColumn(),
                                 TextColumn("{task.completed}/{task.total} identifications"),
                                 TimeRemainingColumn(), console=self.console, transient=True)
        self.task = self.progress.add_task("Monte-Carlo", total=total)
        return self.progress

    def advance(self, done: int, total: int) -> None:
        self.progress.advance(self.task, done - self.done)
        self.done = done
