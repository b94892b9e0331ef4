"""The report's plots, as PNG bytes drawn at 300 px per inch (:data:`DPI`), shown at
:data:`WIDTH` x :data:`HEIGHT` CSS px (6.4 x 4 in; 325 px per inch at the PDF's 150 mm).

Texts inside the figures use mathtext for symbols (θ₂, κ_F as $\\kappa_F$): no
literal underscore is drawn.

Each function takes data in SI (angles in rad where arrays of poses are
given) and labels its axes in the report's units (deg, kN m/rad, mm).
"""

from __future__ import annotations

import io

import numpy as np
import pandas as pd

# Figures built directly (no pyplot): no GUI backend is chosen or imported, no global
# figure list to close; savefig renders with Agg.
from matplotlib.figure import Figure as MplFigure

from analysis.report.document import Figure
from analysis.report.formatting import level

SIZE_IN = (6.4, 4.0)
#: px per inch of the PNG: 1920 x 1200 px, 2.4 px per CSS px in the HTML and 325 px per inch
#: at the PDF's 150 mm, the print resolution of a report that is signed and filed; 200 would
#: save 16 % of a figure's drawing (0.232 against 0.277 s CPU). The rendered-page tests read
#: the PDF at 40 px per inch.
DPI = 300
DISPLAY_DPI = 125  # CSS px per inch in the HTML: shown at 800 x 500
WIDTH, HEIGHT = int(SIZE_IN[0] * DISPLAY_DPI), int(SIZE_IN[1] * DISPLAY_DPI)
PIXELS = (int(SIZE_IN[0] * DPI), int(SIZE_IN[1] * DPI))
COMPONENT_MARKERS = {"dx": "o", "dy": "s", "dz": "^", "rx": "v", "ry": "D", "rz": "P"}


def _legend_below(ax) -> None:
    """Legend under the axes: inside, it would hide poses tested near a corner."""
    ax.legend(loc="upper center", bbox_to_anchor=(0.5, -0.13), fontsize=8, frameon=False)


POSE_STYLE = {"marker": "o", "mfc": "white", "mec": "black", "mew": 1.5, "ms": 8,
              "linestyle": "none"}  # visible on grey and on viridis alike
LABEL_BOX = {"boxstyle": "round,pad=0.15", "fc": "white", "ec": "none", "alpha": 0.85}


#: label offsets tried around a pose, in points from its centre (nearest first); the far
#: ones get a leader line back to the pose
NEAR_OFFSETS = [(6, 5), (6, -5), (-6, 5), (-6, -5), (0, 9), (0, -9)]
FAR_RADII = (16.0, 26.0, 38.0, 52.0)
#: poses closer than this (points on the map) are listed as nearly coinciding
COINCIDE_PT = 6.0


def _candidates():
    """(dx, dy, ha, va, leader) label placements, nearest first."""
    out = []
    for dx, dy in NEAR_OFFSETS:
        out.append((dx, dy, "left" if dx > 0 else "right" if dx < 0 else "center",
                    "bottom" if dy > 0 else "top", False))
    for r in FAR_RADII:
        for ang in np.radians(np.arange(30, 390, 30)):
            dx, dy = r * np.cos(ang), r * np.sin(ang)
            out.append((dx, dy, "left" if dx > 1 else "right" if dx < -1 else "center",
                        "bottom" if dy > 1 else "top" if dy < -1 else "center", True))
    return out


def _box(x, y, dx, dy, ha, va, w, h, s):
    """Pixel box of a label of w x h points anchored (ha, va) at (x, y) + (dx, dy) pt."""
    x0 = x + dx * s - {"left": 0.0, "center": w / 2, "right": w}[ha] * s
    y0 = y + dy * s - {"bottom": 0.0, "center": h / 2, "top": h}[va] * s
    return (x0, y0, x0 + w * s, y0 + h * s)


def _overlaps(a, b) -> bool:
    return a[0] < b[2] and b[0] < a[2] and a[1] < b[3] and b[1] < a[3]


def draw_poses(ax, t2_deg: np.ndarray, t3_deg: np.ndarray, labels: list[str]) -> None:
    """Tested poses as white dots with a black edge, each numbered with its plan label.

    Markers and labels are not clipped (a pose on a joint limit sits on the
    axes' edge) and the labels sit on a white box (readable on any colour map),
    placed by :func:`place_labels`.
    """
    ax.plot(t2_deg, t3_deg, clip_on=False, zorder=5, label="tested poses (plan labels)",
            **POSE_STYLE)
    place_labels(ax, t2_deg, t3_deg, labels, POSE_STYLE["ms"] / 2 + 1)


def place_labels(ax, x_data: np.ndarray, y_data: np.ndarray, labels: list[str],
                 marker_radius_pt: float, fontsize: float = 8.0) -> list:
    """Number poses so that no label covers another label or a pose marker.

    Each label takes the nearest of :func:`_candidates` that stays inside the axes and
    overlaps nothing placed before (a leader line back to its pose when it had to move
    away). Call it once the figure's layout is final (the placement is in pixels). The
    labels are returned and kept on ``ax.figure.pose_labels`` for the overlap check.
    """
    fig = ax.figure
    ax.autoscale_view()
    xy = ax.transData.transform(np.column_stack([x_data, y_data]))
    s = fig.dpi / 72.0  # px per point
    frame = ax.get_window_extent()
    pad = 2 * s
    limits = (frame.x0 - pad, frame.y0 - pad, frame.x1 + pad, frame.y1 + pad)
    r = marker_radius_pt
    markers = [(x - r * s, y - r * s, x + r * s, y + r * s) for x, y in xy]
    placed: list = []
    texts = []
    for (x, y), text in zip(xy, labels, strict=True):
        w, h = 0.62 * fontsize * len(text) + 4, fontsize * 1.2 + 3  # points, with the box
        choice = None
        for dx, dy, ha, va, leader in _candidates():
            box = _box(x, y, dx, dy, ha, va, w, h, s)
            inside = (box[0] >= limits[0] and box[1] >= limits[1] and box[2] <= limits[2]
                      and box[3] <= limits[3])
            if inside and not any(_overlaps(box, o) for o in placed + markers):
                choice = (dx, dy, ha, va, leader, box)
                break
        if choice is None:  # crowded beyond every place tried: the nearest one
            dx, dy, ha, va, leader = _candidates()[0]
            choice = (dx, dy, ha, va, leader, _box(x, y, dx, dy, ha, va, w, h, s))
        dx, dy, ha, va, leader, box = choice
        placed.append(box)
        texts.append(ax.annotate(
            text, ax.transData.inverted().transform((x, y)), xytext=(dx, dy),
            textcoords="offset points", fontsize=fontsize, fontweight="bold", color="black",
            ha=ha, va=va, bbox=LABEL_BOX, zorder=6, annotation_clip=False,
            arrowprops={"arrowstyle": "-", "lw": 0.8, "color": "black", "shrinkA": 0,
                        "shrinkB": r} if leader else None))
    fig.pose_labels = getattr(fig, "pose_labels", []) + texts
    return texts


def coinciding(t2_deg: np.ndarray, t3_deg: np.ndarray, labels: list[str],
               tol_deg: float) -> list[list[str]]:
    """Groups of poses whose (theta_2, theta_3) lie within ``tol_deg`` of each other."""
    groups: list[list[int]] = []
    for i in range(len(labels)):
        for g in groups:
            if any(np.hypot(t2_deg[i] - t2_deg[j], t3_deg[i] - t3_deg[j]) <= tol_deg
                   for j in g):
                g.append(i)
                break
        else:
            groups.append([i])
    return [[labels[i] for i in g] for g in groups if len(g) > 1]


def coinciding_on(ax, x_deg: np.ndarray, y_deg: np.ndarray,
                  labels: list[str]) -> tuple[float, list[list[str]]]:
    """(tolerance in deg, groups of labels): poses within :data:`COINCIDE_PT` points of
    each other on ``ax`` (its x scale, at the figure's size) -- their markers overlap."""
    x0, x1 = ax.get_xlim()
    width_in = ax.get_position().width * ax.figure.get_figwidth()
    tol = COINCIDE_PT / 72.0 * abs(x1 - x0) / width_in
    return tol, coinciding(np.asarray(x_deg), np.asarray(y_deg), labels, tol)


def coinciding_words(tol: float, groups: list[list[str]]) -> str:
    """'Nearly coinciding on this map (within 1.2 deg; ...): 4, 5.' ('' if no group)."""
    if not groups:
        return ""
    return ("Nearly coinciding on this map (within " + f"{tol:.2g} deg; labels set apart "
            "with leader lines): " + "; ".join(", ".join(g) for g in groups) + ".")


def _coincide_text(deg: np.ndarray, labels: list[str], ax) -> str:
    """Caption words for poses that nearly coincide on the map ('' if none)."""
    words = coinciding_words(*coinciding_on(ax, deg[:, 1], deg[:, 2], labels))
    return f" {words}" if words else ""


def grey_or_rgb(rgb: np.ndarray) -> np.ndarray:
    """``rgb`` (h, w, 3) uint8 as it is, or as its (h, w) grey levels when every pixel has
    R = G = B (a figure drawn in greys only, such as the 1/kappa_F map): the same pixels in
    a third of the bytes, for the PNG encoder, the HTML and the PDF's image stream alike.

    Every 16th row is compared first: a colour figure is told apart there (a colour pixel
    found is proof) without comparing all its pixels; only a grey sample is checked whole.
    """
    grey = rgb[..., 0]
    sample = slice(None, None, 16)
    for c in (1, 2):
        if not np.array_equal(grey[sample], rgb[sample, :, c]):
            return rgb
    if np.array_equal(grey, rgb[..., 1]) and np.array_equal(grey, rgb[..., 2]):
        return np.ascontiguousarray(grey)
    return rgb


def _png(fig, name: str, caption: str) -> Figure:
    """The figure drawn once on an Agg canvas, as an RGB PNG, or an 8-bit grey one when it
    has no colour (:func:`grey_or_rgb`); opaque white background: no alpha channel, which
    the PDF would otherwise split into a soft mask."""
    from matplotlib import rc_context
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from PIL import Image

    canvas = FigureCanvasAgg(fig)
    # glyphs without the font's hinting: at this resolution the text looks the same, and
    # hinting is most of the cost of laying out and rasterizing each tick label
    with rc_context({"text.hinting": "no_hinting"}):
        canvas.draw()
    rgba = canvas.buffer_rgba()
    pixels = grey_or_rgb(np.asarray(rgba)[..., :3])
    if pixels.ndim == 3:
        # colour: PIL drops the alpha channel in C from the canvas's own buffer, where
        # Image.fromarray copied the strided RGB view through numpy's tobytes first (9 of
        # 50 ms per 1920 x 1200 figure; pixels identical)
        image = Image.frombuffer("RGBA", (pixels.shape[1], pixels.shape[0]), rgba, "raw",
                                 "RGBA", 0, 1).convert("RGB")
    else:
        image = Image.fromarray(pixels)
    buf = io.BytesIO()
    # zlib level 3: files 2 % larger than at the default 6, written in two thirds of the time
    image.save(buf, format="PNG", dpi=(DPI, DPI), compress_level=3)
    from matplotlib.text import Text

    texts = [t.get_text() for t in fig.findobj(match=Text) if t.get_visible()
             and t.get_text().strip()]
    renderer = canvas.get_renderer()
    boxes = [tuple(float(v) for v in t.get_window_extent(renderer).extents)
             for t in getattr(fig, "pose_labels", [])]
    return Figure(name=name, png=buf.getvalue(), width=WIDTH, height=HEIGHT, caption=caption,
                  texts=texts, label_boxes=boxes)


#: fixed margins (fractions of the canvas) for the report's one layout: title above,
#: axis labels and a legend row below, colour bar on the right. A fixed layout draws each
#: figure once; constrained layout measured every text first (about half the drawing cost).
MARGINS = {"left": 0.115, "right": 0.97, "bottom": 0.13, "top": 0.92}
LEGEND_BELOW_BOTTOM = 0.225  # room for the x label and one legend row under the axes
COLORBAR_RIGHT = 0.84  # axes end here; the colour bar and its label take the rest
POSES_TOP = 0.87  # room between the title and the axes for the label of a pose on the top edge
POSE_TITLE_PAD = 16.0  # points: the title above such a label


SUBSCRIPT_DIGITS = str.maketrans("0123456789", "\u2080\u2081\u2082\u2083\u2084\u2085\u2086"
                                 "\u2087\u2088\u2089")


def _joint_subscripts(text: str) -> str:
    """'θ1 = 0' -> 'θ₁ = 0': joint indices as subscripts in a figure's text."""
    import re

    return re.sub("\u03b8(\\d)", lambda m: "\u03b8" + m.group(1).translate(SUBSCRIPT_DIGITS),
                  text)


def _title(ax, text: str, fontsize: float, pad: float = 6.0) -> None:
    """Title at a fixed height above the axes (``y`` given): matplotlib's automatic title
    placement measures every tick label of the axes again on each draw. Joint indices
    (θ1) are drawn as subscripts (θ₁)."""
    ax.set_title(_joint_subscripts(text), fontsize=fontsize, pad=pad, y=1.0)


def _new(legend_below: bool = False, colorbar: bool = False, poses: bool = False):
    fig = MplFigure(figsize=SIZE_IN, dpi=DPI)
    margins = dict(MARGINS)
    if legend_below:
        margins["bottom"] = LEGEND_BELOW_BOTTOM
    if colorbar:
        margins["right"] = COLORBAR_RIGHT
    if poses:
        margins["top"] = POSES_TOP
    fig.subplots_adjust(**margins)
    ax = fig.subplots()
    _fixed_xlabel(fig, ax)
    return fig, ax


def _fixed_xlabel(fig, ax) -> None:
    """The x label at a fixed distance under the axes: below the tick marks, one line of
    tick labels and the label pad, where matplotlib would put it after measuring every tick
    label of the axis once more on each draw (tick labels at the bottom are one line high)."""
    from matplotlib import rcParams
    from matplotlib.font_manager import FontProperties
    from matplotlib.transforms import ScaledTranslation

    tick_label_pt = FontProperties(size=rcParams["xtick.labelsize"]).get_size_in_points()
    below_pt = (rcParams["xtick.major.size"] + rcParams["xtick.major.pad"] + tick_label_pt
                + rcParams["axes.labelpad"])
    ax.xaxis.set_label_coords(
        0.5, 0.0, transform=ax.transAxes + ScaledTranslation(0.0, -below_pt / 72,
                                                             fig.dpi_scale_trans))


def _colorbar(fig, ax, mappable, label: str) -> None:
    """Colour bar in a fixed axes right of ``ax`` (same height), labelled."""
    box = ax.get_position()
    cax = fig.add_axes((box.x1 + 0.02, box.y0, 0.025, box.height))
    fig.colorbar(mappable, cax=cax, label=label)


def _grid(table: pd.DataFrame, column: str):
    """The map's axes (theta_2, theta_3 values, deg) and ``column`` on that grid (rows:
    theta_3), NaN where the table has no row; repeated grid points are averaged."""
    t2, i2 = np.unique(table["theta2_deg"].to_numpy(), return_inverse=True)
    t3, i3 = np.unique(table["theta3_deg"].to_numpy(), return_inverse=True)
    values = table[column].to_numpy(dtype=float)
    ok = ~np.isnan(values)
    total = np.zeros((len(t3), len(t2)))
    count = np.zeros((len(t3), len(t2)))
    np.add.at(total, (i3[ok], i2[ok]), values[ok])
    np.add.at(count, (i3[ok], i2[ok]), 1.0)
    with np.errstate(invalid="ignore", divide="ignore"):
        return t2, t3, total / count


def poses_on_kappa_map(table: pd.DataFrame, q_tests: np.ndarray, labels: list[str],
                       fixed_text: str, rule: str = "") -> Figure:
    """1/kappa_F over (theta_2, theta_3) with the tested poses; q_tests (m, 6) rad."""
    fig, ax = _new(legend_below=True, colorbar=True, poses=True)
    t2, t3, z = _grid(table, "inv_kappa_F")
    cs = ax.contourf(t2, t3, z, levels=20, cmap="gray")
    _colorbar(fig, ax, cs, r"$1/\kappa_F$ of $J_N$")
    deg = np.degrees(q_tests)
    draw_poses(ax, deg[:, 1], deg[:, 2], labels)
    ax.set_xlabel("\u03b8\u2082 (deg, model convention)")
    ax.set_ylabel("\u03b8\u2083 (deg, model convention)")
    _title(ax, f"Dexterity map, {fixed_text}", fontsize=9, pad=POSE_TITLE_PAD)
    _legend_below(ax)
    return _png(fig, "poses_kappa_map", f"Tested poses {_pose_list(labels)} on the "
                f"1/\u03ba_F map ({fixed_text}{_rule(rule)}; the poses' own \u03b8\u2081, "
                "\u03b8\u2084..\u03b8\u2086 may differ)." + _coincide_text(deg, labels, ax))


def _rule(rule: str) -> str:
    return f": {rule}" if rule else ""


def _pose_list(labels: list[str]) -> str:
    """'(labels 1, 2, 3)' for a caption: the figures' pose numbers in text form."""
    return f"(labels {', '.join(labels)})" if labels else ""


def stiffness_bars(k: np.ndarray, ci: np.ndarray, nominal: np.ndarray | None,
                   nominal_label: str, confidence: float) -> Figure:
    """Identified k (N m/rad) with its interval as error bars.

    With reference values, k / reference - 1 (%) is drawn (the intervals of
    well-identified joints are too narrow to see on an absolute scale);
    without, k in kN m/rad. An interval unbounded above is drawn to the top
    of the axes with an arrow.
    """
    fig, ax = _new()
    joints = np.arange(1, 7)
    ok = np.isfinite(k)
    ref = nominal if nominal is not None else np.full(6, 1e3)
    relative = nominal is not None
    with np.errstate(invalid="ignore", divide="ignore"):
        y = (k / ref - 1) * 100 if relative else k / ref
        lo = (ci[:, 0] / ref - 1) * 100 if relative else ci[:, 0] / ref
        hi = (ci[:, 1] / ref - 1) * 100 if relative else ci[:, 1] / ref
    finite_hi = np.isfinite(hi)
    span = np.concatenate([y[ok], lo[ok], hi[ok & finite_hi], [0.0]])
    top = np.nanmax(span) + 0.2 * (np.nanmax(span) - np.nanmin(span) + 1e-9)
    hi_drawn = np.where(finite_hi, hi, top)
    yerr = np.vstack([y - lo, hi_drawn - y])[:, ok]
    ax.errorbar(joints[ok], y[ok], yerr=yerr, fmt="o", capsize=6, color="tab:blue",
                label=f"identified, {level(confidence)} interval")
    unbounded = ok & ~finite_hi
    if unbounded.any():
        ax.plot(joints[unbounded], hi_drawn[unbounded], "^", color="tab:blue",
                label="interval unbounded above")
    if relative:
        ax.axhline(0.0, color="k", lw=1.2, label=nominal_label)
        ax.set_ylabel(f"k / {nominal_label.split(' (')[0]} \u2212 1 (%)")
    else:
        ax.set_ylabel("joint stiffness (kN m/rad)")
    for j in joints[~ok]:
        ax.annotate("not identified", (j, 0), ha="center", fontsize=7, color="0.4")
    ax.set_xticks(joints, [f"k{j}" for j in joints])
    ax.set_xlim(0.5, 6.5)
    ax.grid(alpha=0.3)
    ax.legend(fontsize=8)
    _title(ax, "Identified joint stiffness" + (f", relative to the {nominal_label}"
                                                  if relative else ""), fontsize=9)
    short = nominal_label.split(" (")[0]
    what = (f"as k / {short} \u2212 1 in % (the {nominal_label} is the 0 line)" if relative
            else "in kN m/rad")
    return _png(fig, "stiffness", f"Identified k with {level(confidence)} intervals, {what}.")


def residual_plot(residuals: pd.DataFrame, threshold: float, n_tests: int | None = None,
                  flagged: int | None = None, set_aside: int | None = None,
                  robust: bool = False) -> Figure:
    """Studentized residual per test and component; the outliers (``outlier``: |t| beyond
    ``threshold``, exactly the points outside the dashed lines) circled in red, the
    residuals the fit set aside (``set_aside``) marked with a cross.

    ``n_tests``: the campaign's number of tests when ``residuals`` holds only the rows of
    the tests with the largest residuals (the caption then says so). ``flagged``,
    ``set_aside``: counts over the whole campaign (default: those of ``residuals``);
    ``robust``: a robust fit, whose set-aside rows are its down-weighted ones."""
    fig, ax = _new(legend_below=True)
    tests = residuals["test"].to_numpy()
    for comp, marker in COMPONENT_MARKERS.items():
        sel = residuals["component"] == comp
        if sel.any():
            ax.plot(tests[sel] + 1, residuals.loc[sel, "studentized"], marker, ms=5,
                    mfc="none", label=comp, linestyle="none")
    out = residuals["outlier"].to_numpy(dtype=bool)
    t_all = residuals["studentized"].to_numpy(dtype=float)
    aside = (residuals["set_aside"].to_numpy(dtype=bool) if "set_aside" in residuals
             else out)
    what = "down-weighted" if robust else "set aside by the outlier test"
    if out.any():
        ax.plot(tests[out] + 1, t_all[out], "o", ms=11, mfc="none",
                mec="red", mew=1.5, label="outlier")
    if (aside != out).any() and aside.any():
        ax.plot(tests[aside] + 1, t_all[aside], "x", ms=9, color="darkorange", mew=1.5,
                label=what)
    for s in (-threshold, threshold):
        ax.axhline(s, color="red", ls="--", lw=1, zorder=3)
    ax.axhline(0, color="k", lw=0.8)
    # the threshold lines inside the frame, never on it
    extent = max(float(np.nanmax(np.abs(residuals["studentized"]), initial=0.0)), threshold)
    ax.set_ylim(-1.15 * extent, 1.15 * extent)
    ax.set_xlabel("test (row of the identification, 1-based)")
    ax.set_ylabel("studentized residual")
    ax.grid(alpha=0.3)
    ax.legend(fontsize=7, ncol=7, loc="upper center", bbox_to_anchor=(0.5, -0.15))
    _title(ax, "Residuals per test and component", fontsize=9)
    shown = ("" if n_tests is None else
             f" Shown: the {residuals['test'].nunique()} of {n_tests} tests holding the "
             "largest |studentized| residuals (outliers first); every test is in "
             "residuals.csv.")
    n_flag = int(out.sum()) if flagged is None else flagged
    n_aside = int(aside.sum()) if set_aside is None else set_aside
    how = (f"{n_flag} outlier(s): residuals beyond the dashed lines at "
           f"\u00b1{threshold:.2f}, circled in red (column outlier of residuals.csv)")
    if n_aside != n_flag:
        how += (f"; {n_aside} {what} (crosses, column set_aside)"
                + ("" if robust else
                   ": the test sets aside the largest |t| and refits, one at a time, within "
                   "its budget; k and its intervals are those of the fit drawn"))
    return _png(fig, "residuals", f"Studentized residuals of the fit; {how}." + shown)


def deflection_joint_map(table: pd.DataFrame, q_tests: np.ndarray, wrench_text: str,
                         fixed_text: str, labels: list[str] | None = None,
                         rule: str = "") -> Figure:
    """Norm of the predicted translational deflection (mm) over (theta_2, theta_3)."""
    fig, ax = _new(legend_below=True, colorbar=True, poses=True)
    t2, t3, z = _grid(table, "deflection_mm")
    finite = z[np.isfinite(z)]
    vmax = np.percentile(finite, 99) if finite.size else 1.0
    cs = ax.contourf(t2, t3, np.clip(z, None, vmax), levels=20, cmap="viridis")
    _colorbar(fig, ax, cs, "|\u03b4p| (mm)")
    deg = np.degrees(q_tests)
    labels = labels if labels is not None else [str(i + 1) for i in range(len(deg))]
    draw_poses(ax, deg[:, 1], deg[:, 2], labels)
    ax.set_xlabel("\u03b8\u2082 (deg, model convention)")
    ax.set_ylabel("\u03b8\u2083 (deg, model convention)")
    _title(ax, f"Predicted deflection under {wrench_text}", fontsize=8, pad=POSE_TITLE_PAD)
    _legend_below(ax)
    return _png(fig, "deflection_joint_map", "Norm of the predicted translational deflection "
                f"of P (with K_C) over (\u03b8\u2082, \u03b8\u2083), {fixed_text}"
                f"{_rule(rule)}, with the tested poses {_pose_list(labels)}; colour scale "
                "clipped at the 99th percentile." + _coincide_text(deg, labels, ax))


def deflection_cartesian_map(table: pd.DataFrame, wrench_text: str) -> Figure:
    """The same deflection over the positions of P in the arm's plane (radial distance, z)."""
    fig, ax = _new(colorbar=True)
    x, y = table["x_m"].to_numpy(), table["y_m"].to_numpy()
    radial = np.hypot(x, y) * np.where(x < 0, -1.0, 1.0)
    z = table["deflection_mm"].to_numpy()
    ok = np.isfinite(z)
    vmax = np.percentile(z[ok], 99) if ok.any() else 1.0
    # filled dots without an edge stroke (stroking each of thousands of dots doubles the
    # drawing time); 3.2 pt across, the size of a 5 pt^2 dot with its 1 pt edge
    sc = ax.scatter(radial[ok], table["z_m"].to_numpy()[ok], c=np.clip(z[ok], None, vmax),
                    s=3.2 ** 2, linewidths=0, cmap="viridis")
    _colorbar(fig, ax, sc, "|\u03b4p| (mm)")
    ax.set_xlabel("horizontal distance of P from axis 1 (m)")
    ax.set_ylabel("height of P (m)")
    ax.set_aspect("equal", adjustable="datalim")
    ax.grid(alpha=0.3)
    _title(ax, f"Predicted deflection over the workspace, under {wrench_text}", fontsize=8)
    return _png(fig, "deflection_cartesian_map", "The deflection map drawn at the positions of "
                "P in the arm's plane (same poses as the joint-space map).")


def robustness_curve(table: pd.DataFrame, n_campaign: int, se_rel: dict[int, float],
                     method_text: str = "") -> Figure:
    """Robust spread (IQR / 1.349 of k / k_ref, %) of each k vs number of tests, with the
    campaign's size and its own standard errors; numbers of tests where the design is not
    identifiable are marked at the top instead of drawn (their spread would set the scale).
    """
    fig, ax = _new(legend_below=True)
    ident = table[table["identifiable"]]
    for j in sorted(table["joint"].unique()):
        s = ident[ident["joint"] == j]
        line, = ax.plot(s["n_tests"], 100 * s["robust_sigma"], "o-", ms=3, label=f"k{j}")
        if j in se_rel and np.isfinite(se_rel[j]):
            ax.plot([n_campaign], [100 * se_rel[j]], "*", ms=10, color=line.get_color())
    ax.axvline(n_campaign, color="k", ls=":", lw=1)
    ax.set_yscale("log")
    from matplotlib.ticker import FuncFormatter, MaxNLocator

    # plain numbers (0.1, 1, 10) rather than the default 10^x labels; within less than a
    # decade the 2 and 5 minor ticks are labelled too, so two labels at least are shown
    ax.yaxis.set_major_formatter(FuncFormatter(_plain))
    values = 100 * ident["robust_sigma"].to_numpy(dtype=float)
    stars = [100 * v for v in se_rel.values() if np.isfinite(v) and v > 0]
    values = np.concatenate([values[np.isfinite(values) & (values > 0)], stars])
    few = values.size == 0 or np.floor(np.log10(values.max())) == np.floor(
        np.log10(values.min()))
    ax.yaxis.set_minor_formatter(FuncFormatter(_plain_25 if few else _none))
    if values.size:
        ax.set_ylim(values.min() / 1.5, values.max() * 1.5)
    bad = sorted(set(table.loc[~table["identifiable"], "n_tests"].tolist()))
    if bad:
        from matplotlib.transforms import blended_transform_factory

        trans = blended_transform_factory(ax.transData, ax.transAxes)
        ax.plot(bad, [0.96] * len(bad), "x", color="0.35", ms=7, mew=1.5, transform=trans,
                clip_on=False, label="not identifiable")
    ax.xaxis.set_major_locator(MaxNLocator(integer=True))  # a number of tests
    ax.set_xlabel("number of tests drawn from this campaign's design")
    ax.set_ylabel("IQR/1.349 of k/k$_{ref}$ (%)")
    ax.grid(alpha=0.3, which="both")
    ax.legend(fontsize=7, ncol=8, loc="upper center", bbox_to_anchor=(0.5, -0.15),
              frameon=False)
    _title(ax, "Robustness to measurement noise" + (f": {method_text}" if method_text
                                                    else ""), fontsize=7.5)
    caption = ("Monte-Carlo spread of the identified k against the number of tests: "
               "interquartile range of k / k_ref over 1.349 (the standard deviation of a "
               "normal spread, not inflated by the wild draws of a nearly singular design); "
               "dotted line: this campaign's number of tests; stars: the standard errors "
               "reported for this campaign.")
    if bad:
        caption += (" Crosses at the top: numbers of tests where the design is not "
                    "identifiable (more than 10 % of the trials give no positive k, or the "
                    "spread exceeds 100 %): " + ", ".join(str(int(n)) for n in bad) + ".")
    return _png(fig, "robustness", caption)


def _plain(value: float, _pos=None) -> str:
    return f"{value:g}"


def _plain_25(value: float, _pos=None) -> str:
    """Label of a minor log tick at 2 or 5 times a power of ten, else none."""
    mantissa = value / 10 ** np.floor(np.log10(value)) if value > 0 else 0.0
    return f"{value:g}" if np.isclose(mantissa, 2) or np.isclose(mantissa, 5) else ""


def _none(_value: float, _pos=None) -> str:
    return ""
