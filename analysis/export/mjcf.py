"""MuJoCo's MJCF of a :class:`~analysis.export.sim_model.SimModel`: nested bodies, hinge joints
with ``stiffness``/``springref``, the flange and the tool point P as sites.

Each body's frame is its joint's frame (``pos``/``quat`` in the parent body, the hinge at
the body origin); angles in radians (``<compiler angle="radian">``). A joint's spring
pulls it toward ``springref`` (MuJoCo's ``qpos_spring``): 0 is written, and a simulation
sets it to the commanded pose, where the controller holds the motor (the joint stiffness
is the compliance between the motor's commanded angle and the link).
"""

from __future__ import annotations

from analysis.export.sim_model import Inertial, SimModel
from analysis.export.xml_text import attr, comment, left_out_lines, num, nums, quat_wxyz


def _frame(T) -> str:
    return f'pos="{nums(T[:3, 3])}" quat="{nums(quat_wxyz(T[:3, :3]))}"'


def _inertial(inertial: Inertial) -> str:
    I = inertial.inertia_kg_m2
    full = [I[0, 0], I[1, 1], I[2, 2], I[0, 1], I[0, 2], I[1, 2]]
    return (f'<inertial pos="{nums(inertial.com_m)}" mass="{num(inertial.mass_kg)}" '
            f'fullinertia="{nums(full)}"/>')


def mjcf_text(model: SimModel) -> str:
    """The MJCF document (text) of ``model``."""
    notes = list(model.header) + [
        "MuJoCo MJCF. Units: m, rad, kg, N m/rad (joint stiffness). Joint values are the",
        "model's joint angles. Springs: stiffness = the joint stiffness, springref = 0;",
        "set model.qpos_spring to the commanded pose before simulating a load.",
    ] + left_out_lines(model)
    lines = [f"<mujoco model={attr(model.name)}>", comment(notes, "  "),
             '  <compiler angle="radian" autolimits="true"/>', "  <worldbody>"]
    indent = "    "
    for j in model.joints:
        lines.append(f"{indent}<body name={attr(j.link)} {_frame(j.placement)}>")
        inner = indent + "  "
        if j.inertial.placeholder:
            lines.append(f"{inner}<!-- placeholder inertial: no mass properties in the "
                         "robot model -->")
        lines.append(inner + _inertial(j.inertial))
        spring = ("" if j.stiffness_Nm_per_rad is None else
                  f' stiffness="{num(j.stiffness_Nm_per_rad)}" springref="0"')
        lines.append(f'{inner}<joint name={attr(j.name)} type="hinge" axis="{nums(j.axis)}" '
                     f'range="{num(j.lower_rad)} {num(j.upper_rad)}"{spring}/>')
        indent = inner
    if model.flange is not None:
        lines.append(f'{indent}<site name="flange" {_frame(model.flange)}/>')
    lines.append(f'{indent}<site name="tool" {_frame(model.tool)}/>')
    for _ in model.joints:
        indent = indent[:-2]
        lines.append(f"{indent}</body>")
    lines += ["  </worldbody>", "</mujoco>", ""]
    return "\n".join(lines)
