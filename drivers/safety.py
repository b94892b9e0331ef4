"""Safety helpers used before any motion of a real robot.

* :func:`check_joint_targets` — targets inside the model's limits minus margins.
* :func:`cap_motion` — speed and acceleration capped.
* :func:`format_motion_list` — the dry-run listing shown to the operator (degrees).
* :func:`require_confirmation` — explicit "yes" from the operator, or ``assume_yes``.
* :func:`check_force` — a measured force above the limit raises :class:`SafetyRefusal`.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence

import numpy as np

from drivers.errors import DeviceFault, SafetyRefusal


def check_joint_targets(
    targets: np.ndarray,
    lower: np.ndarray,
    upper: np.ndarray,
    margin: float | np.ndarray = np.deg2rad(5.0),
) -> np.ndarray:
    """Refuse joint targets outside ``[lower + margin, upper - margin]``.

    Parameters
    ----------
    targets : array_like, shape (m, n) or (n,)
        Joint targets (rad), same convention as the limits.
    lower, upper : array_like, shape (n,)
        Joint limits (rad).
    margin : float or array_like, shape (n,)
        Margin kept from each limit (rad), >= 0.

    Returns
    -------
    ndarray, shape (m, n)
        The targets as a float array.

    Raises
    ------
    SafetyRefusal
        Naming the first pose and joint out of range, in degrees.
    """
    q = np.atleast_2d(np.asarray(targets, dtype=float))
    lo = np.asarray(lower, dtype=float) + margin
    hi = np.asarray(upper, dtype=float) - margin
    if q.shape[1] != lo.shape[0]:
        raise SafetyRefusal(f"targets have {q.shape[1]} joints, limits have {lo.shape[0]}")
    if np.any(lo > hi):
        raise SafetyRefusal("joint margins leave no admissible range")
    if not np.all(np.isfinite(q)):
        raise SafetyRefusal("joint targets contain NaN or infinity")
    bad = (q < lo) | (q > hi)
    if np.any(bad):
        i, j = map(int, np.argwhere(bad)[0])
        raise SafetyRefusal(
            f"pose {i + 1}, joint {j + 1}: target {np.rad2deg(q[i, j]):.2f} deg outside "
            f"[{np.rad2deg(lo[j]):.2f}, {np.rad2deg(hi[j]):.2f}] deg (limits minus margin)"
        )
    return q


def cap_motion(speed: float, acceleration: float, max_speed: float,
               max_acceleration: float) -> tuple[float, float]:
    """Return ``(speed, acceleration)`` capped to the maxima (rad/s, rad/s^2)."""
    if speed <= 0 or acceleration <= 0:
        raise SafetyRefusal("speed and acceleration must be positive")
    return min(float(speed), float(max_speed)), min(float(acceleration), float(max_acceleration))


def format_motion_list(targets: np.ndarray, labels: Sequence[str] | None = None,
                       speed: float | None = None) -> str:
    """Dry-run listing of the joint targets in degrees, one line per pose."""
    q = np.atleast_2d(np.asarray(targets, dtype=float))
    lines = []
    if speed is not None:
        lines.append(f"speed limit {np.rad2deg(speed):.1f} deg/s")
    head = "pose  " + " ".join(f"{'J' + str(j + 1) + ' (deg)':>10}" for j in range(q.shape[1]))
    lines.append(head)
    for i, row in enumerate(q):
        label = labels[i] if labels is not None else str(i + 1)
        # rounded first, then + 0.0: a target of -1e-9 deg reads 0.000, not -0.000
        shown = np.round(np.rad2deg(row), 3) + 0.0
        lines.append(f"{label:<5} " + " ".join(f"{v:>10.3f}" for v in shown))
    return "\n".join(lines)


def require_confirmation(summary: str, *, assume_yes: bool = False,
                         ask: Callable[[str], str] = input,
                         say: Callable[[str], None] = print) -> None:
    """Show ``summary`` and require the operator to type ``yes``.

    Raises
    ------
    SafetyRefusal
        If the answer is anything but ``yes`` (case-insensitive).
    """
    say(summary)
    if assume_yes:
        say("confirmed by --yes")
        return
    answer = ask("Type 'yes' to move the robot: ").strip().lower()
    if answer != "yes":
        raise SafetyRefusal("motion not confirmed by the operator")


def check_force(wrench: np.ndarray, max_force: float, max_moment: float | None = None) -> None:
    """Raise :class:`SafetyRefusal` if |f| > ``max_force`` (N) or |m| > ``max_moment`` (N m)."""
    w = np.asarray(wrench, dtype=float)
    f = float(np.linalg.norm(w[:3]))
    if not np.isfinite(f) or f > max_force:
        raise SafetyRefusal(f"force {f:.1f} N above the limit {max_force:.1f} N: stop")
    if max_moment is not None:
        m = float(np.linalg.norm(w[3:6]))
        if not np.isfinite(m) or m > max_moment:
            raise SafetyRefusal(f"moment {m:.1f} N m above the limit {max_moment:.1f} N m: stop")


#: how far (rad) a robot may stop from its joint target and the motion still count as done
REACHED_TOLERANCE = float(np.deg2rad(0.05))


def check_reached(reached: np.ndarray, target: np.ndarray) -> None:
    """Raise DeviceFault when the joints ``reached`` (rad) are more than REACHED_TOLERANCE
    from ``target`` (rad) on any axis: a motion the controller ended short is not a pose."""
    off = float(np.max(np.abs(np.asarray(reached, float) - np.asarray(target, float))))
    if off > REACHED_TOLERANCE:
        raise DeviceFault(f"robot stopped {np.rad2deg(off):.3f} deg away from the target")
