"""``campaign robustness``: Monte-Carlo spread of the identified k vs number of tests (Fig. 7)."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import typer
from rich.console import Console
from rich.table import Table

from analysis.errors import InputError
from campaign.cli_common import (
    PANEL_NOISE,
    PANEL_OUTPUT,
    PANEL_ROBOT,
    Method,
    RotationSource,
    print_json,
)
from campaign.commands.analyze import DEFAULT_METHOD
from campaign.options import (
    TOOL_RPY_HELP,
    TOOL_XYZ_HELP,
    robot_option,
    stiffness_option,
    wrench_option,
)


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
    if not out or min(out) < 1:
        raise InputError("numbers of tests must be >= 1", where="--tests")
    if max(out) > 200:
        raise InputError("at most 200 tests per campaign", where="--tests")
    return sorted(out)


def noise_from_options(
    sigma_translation_um, sigma_rotation_urad, rotation_source, reflector_radius_mm,
    tracker_distance_m, force_sigma_N, moment_sigma_Nm, encoder_resolution_deg,
):
    """NoiseModel with the command-line overrides (units as labelled)."""
    from analysis.identification.noise import NoiseModel

    def scaled(v, f):
        return None if v is None else v * f

    return NoiseModel().with_overrides(
        translation_sigma_override=scaled(sigma_translation_um, 1e-6),
        rotation_sigma_override=scaled(sigma_rotation_urad, 1e-6),
        rotation_source=rotation_source,
        reflector_radius=scaled(reflector_radius_mm, 1e-3),
        tracker_distance=tracker_distance_m,
        force_sigma=force_sigma_N,
        moment_sigma=moment_sigma_Nm,
        encoder_resolution=scaled(encoder_resolution_deg, np.pi / 180.0),
    )


#: panel of --help (campaign.cli_common)
_STUDY = "Monte-Carlo study"
_TRACKER = "Rotation measurement"

#: a mean further than this many Monte-Carlo standard errors from the truth is a bias
BIAS_SIGMAS = 4.0


def bias_notes(summary, method: str) -> list[str]:
    """One sentence per joint whose Monte-Carlo mean is off the truth beyond its spread.

    Beyond its spread: ``|mean - k_true| > BIAS_SIGMAS * std / sqrt(trials)`` (the
    Monte-Carlo standard error of the mean) at every number of tests. The 1/x
    transformation explains a bias of about +(std/k)^2 (Jensen, second order);
    what is left is the estimator's own bias (for ols/wls: the linear model
    fitted to data from the nonlinear equilibrium).
    """
    import numpy as np

    notes = []
    for j, s in summary.groupby("joint"):
        good = s[s["trials"] - s["trials_rejected"] > 1]
        if good.empty:
            continue
        rel = good["mean_Nm_per_rad"] / good["k_true_Nm_per_rad"] - 1.0
        se = good["std_Nm_per_rad"] / np.sqrt(good["trials"] - good["trials_rejected"]) \
            / good["k_true_Nm_per_rad"]
        if not np.all(np.abs(rel) > BIAS_SIGMAS * se):
            continue
        jensen = float(np.median(good["relative_std"] ** 2))
        lo, hi = 100 * float(rel.min()), 100 * float(rel.max())
        cause = ("the linear model (eqs. 16-21) fitted to displacements from the nonlinear "
                 "equilibrium; --method exact removes it" if method in ("ols", "wls")
                 else "the nonlinear estimator at this noise (finite-sample bias)")
        span = f"{lo:+.2f} %" if f"{lo:+.2f}" == f"{hi:+.2f}" else f"{lo:+.2f} to {hi:+.2f} %"
        notes.append(
            f"k{j}: the mean is {span} from the true value at every number "
            f"of tests, beyond {BIAS_SIGMAS:g} Monte-Carlo standard errors; the 1/x "
            f"transformation explains about {100 * jensen:+.3f} % ((std/k)^2), the rest is "
            f"the bias of {cause}.")
    return notes


def method_note(method: str) -> str:
    """Which estimator the study uses, and whether that is the default of ``analyze``."""
    if method == "exact":
        return ("method: exact (Gauss-Newton on the nonlinear equilibrium), the default, as "
                "in campaign analyze")
    return (f"method: {method} (the linear model of the paper's eqs. 16-21"
            + (", its Fig. 7 study" if method == "ols" else "")
            + "), raw: without the linearisation-bias correction campaign analyze makes; "
            f"the default is {DEFAULT_METHOD}")


def linear_bias_note(summary, method: str) -> str | None:
    """For ols/wls: how far the mean is biased by the linear model, per joint, and why.

    The size is the median over noise-free campaigns of the study's designs
    (``linearisation_bias_relative``), the median over the numbers of tests."""
    if method not in ("ols", "wls"):
        return None
    parts = []
    for j, s in summary.groupby("joint"):
        v = s["linearisation_bias_relative"].dropna()
        if len(v):
            parts.append(f"k{j} {100 * float(np.median(v)):+.2f} %")
    return (f"{method}: the mean is biased by the linearisation, the linear model A x fitted to "
            "finite displacements of the nonlinear equilibrium at this wrench (noise-free "
            f"campaigns of the same designs: {', '.join(parts)}); campaign analyze corrects "
            "this bias, --method exact has none")


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
        from rich.progress import BarColumn, Progress, TextColumn, TimeRemainingColumn

        from analysis.identification.robustness import W_EFF, plot_study, robustness_study
        from campaign.commands.analyze import _alias

        method = str(method)
        rotation_source = None if rotation_source is None else str(rotation_source)
        sigma_translation_um = _alias(translation_sigma_um, old_translation,
                                      "--translation-sigma-um")
        sigma_rotation_urad = _alias(rotation_sigma_urad, old_rotation, "--rotation-sigma-urad")
        r = robot_option(robot, tip, tool_xyz_mm, tool_rpy_deg)
        k = stiffness_option(r, joint_stiffness)
        w = wrench_option(wrench, W_EFF)
        counts = parse_tests(tests)
        if trials < 2:
            raise InputError("need at least 2 trials", where="--trials")
        if method not in ("ols", "wls", "exact"):
            raise InputError(f"expected ols, wls or exact, got {method!r}", where="--method")
        if pool_size < 10:
            raise InputError("need at least 10 poses", where="--pool-size")
        noise = noise_from_options(sigma_translation_um, sigma_rotation_urad, rotation_source,
                                   reflector_radius_mm, tracker_distance_m, force_sigma_n,
                                   moment_sigma_nm, encoder_resolution_deg)
        console = Console(stderr=as_json)
        from analysis.report.formatting import k_kNm
        from campaign.cli_common import print_wrapped
        from campaign.commands.stiffness import vector_text

        w_source = "--wrench" if wrench else ("default: the paper's w_eff (eq. 22); --wrench "
                                              "to choose another")
        print_wrapped(console, f"wrench w = {vector_text(w[:3], 6, False)} N, "
                      f"{vector_text(w[3:], 6, False)} N m at P, base frame ({w_source})")
        print_wrapped(console, f"true joint stiffness [{', '.join(k_kNm(v) for v in k)}] kN "
                      "m/rad (" + ("--joint-stiffness" if joint_stiffness else
                                   "the robot model's") + ")")
        with Progress(TextColumn("{task.description}"), BarColumn(),
                      TextColumn("{task.completed}/{task.total} identifications"),
                      TimeRemainingColumn(), console=console, transient=True) as progress:
            task = progress.add_task("Monte-Carlo", total=trials * len(counts))
            summary = robustness_study(
                r, k, w, counts, trials, noise, method=method, seed=seed, pool_size=pool_size,
                min_inverse_condition=min_dexterity,
                progress=lambda t: progress.advance(task, t))
        if not as_json:
            _print(console, summary,
                   f"{r.name}: relative spread of k ({method}, {trials} trials)")
        print_wrapped(console, method_note(method))
        notes = bias_notes(summary, method)
        lin = linear_bias_note(summary, method)
        if lin is not None:
            notes.insert(0, lin)
        for note in notes:
            print_wrapped(console, f"note: {note}")
        settings = {
            "robot": r.name, "joint_stiffness_Nm_per_rad": k.tolist(),
            "wrench_N_Nm": w.tolist(), "wrench_source": w_source, "tests": counts,
            "trials": trials, "method": method, "method_note": method_note(method),
            "seed": seed, "pool_size": pool_size,
            "min_inverse_condition": min_dexterity, "noise": noise.describe(),
            "notes": notes,
        }
        written = []
        if out is not None:
            from analysis.output_files import make_dir, replacing, write_text

            make_dir(out)
            with replacing(out / "robustness.csv") as tmp:
                summary.to_csv(tmp, index=False)
            nz = noise.describe()
            plot_study(summary, out / "robustness.png",
                       f"{r.name}: identified k against the number of tests ({method}, "
                       f"{trials} trials per point)",
                       f"noise per component: translation {nz['translation_sigma_um']:.3g} "
                       f"\u00b5m, rotation {nz['rotation_sigma_urad']:.3g} \u00b5rad, force "
                       f"{nz['force_sigma_N']:.3g} N, moment {nz['moment_sigma_Nm']:.3g} N m; "
                       "x at the top: not identifiable")
            write_text(out / "robustness.json", json.dumps(settings, indent=2) + "\n")
            written = [out / "robustness.csv", out / "robustness.png", out / "robustness.json"]
            for path in written:
                print_wrapped(console, f"wrote {path}")
        if as_json:
            print_json({**settings, "results": summary.to_dict(orient="records"),
                        "files": [str(p) for p in written]})
