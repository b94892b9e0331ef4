"""URDF of a :class:`~analysis.export.sim_model.SimModel`, with the springs in Gazebo's extension.

Links ``base``, ``link1..n``, ``flange`` (when the model has one) and ``tool`` (the tool
point P, on a fixed joint). Each revolute joint's ``origin`` places its link in the parent
link at zero angle; its ``axis`` is in the link's frame. URDF has no joint spring: each
joint's stiffness goes in a ``<gazebo reference="jointN">`` block (``springStiffness``,
``springReference``), which Gazebo's URDF-to-SDF conversion reads and plain URDF readers
(Pinocchio, MoveIt, yourdfpy...) drop, as the file's header says.
"""

from __future__ import annotations

from analysis.export.sim_model import Inertial, SimModel
from analysis.export.xml_text import attr, comment, left_out_lines, num, nums, rpy


def _origin(T, indent: str) -> str:
    return f'{indent}<origin xyz="{nums(T[:3, 3])}" rpy="{nums(rpy(T[:3, :3]))}"/>'


def _inertial(inertial: Inertial, indent: str) -> list[str]:
    I = inertial.inertia_kg_m2
    lines = [f"{indent}<inertial>"]
    if inertial.placeholder:
        lines.append(f"{indent}  <!-- placeholder: no mass properties in the robot model -->")
    lines += [f'{indent}  <origin xyz="{nums(inertial.com_m)}" rpy="0 0 0"/>',
              f'{indent}  <mass value="{num(inertial.mass_kg)}"/>',
              f'{indent}  <inertia ixx="{num(I[0, 0])}" ixy="{num(I[0, 1])}" '
              f'ixz="{num(I[0, 2])}" iyy="{num(I[1, 1])}" iyz="{num(I[1, 2])}" '
              f'izz="{num(I[2, 2])}"/>',
              f"{indent}</inertial>"]
    return lines


def _fixed(name: str, parent: str, child: str, T) -> list[str]:
    return [f'  <link name={attr(child)}/>',
            f'  <joint name={attr(name)} type="fixed">', f"    <parent link={attr(parent)}/>",
            f"    <child link={attr(child)}/>", _origin(T, "    "), "  </joint>"]


def urdf_text(model: SimModel) -> str:
    """The URDF document (text) of ``model``."""
    notes = list(model.header) + [
        "URDF. Units: m, rad, kg; joint values are the model's joint angles.",
        "effort and velocity limits are not in the robot model: 0 is written (unknown).",
    ]
    if model.springs:
        notes += [
            "Joint stiffness (N m/rad): URDF has no spring element; it is in the",
            "<gazebo reference=\"jointN\"> blocks at the end (springStiffness, springReference),",
            "Gazebo's URDF extension. Plain URDF readers (Pinocchio, MoveIt, yourdfpy, ...)",
            "drop them: this file read by those is the rigid robot.",
        ]
    notes += left_out_lines(model)
    lines = ['<?xml version="1.0"?>', comment(notes), f"<robot name={attr(model.name)}>",
             f"  <link name={attr(model.base_link)}/>"]
    parent = model.base_link
    for j in model.joints:
        lines += [f"  <link name={attr(j.link)}>", *_inertial(j.inertial, "    "), "  </link>",
                  f'  <joint name={attr(j.name)} type="revolute">',
                  f"    <parent link={attr(parent)}/>", f"    <child link={attr(j.link)}/>",
                  _origin(j.placement, "    "), f'    <axis xyz="{nums(j.axis)}"/>',
                  f'    <limit lower="{num(j.lower_rad)}" upper="{num(j.upper_rad)}" '
                  'effort="0" velocity="0"/>', "  </joint>"]
        parent = j.link
    if model.flange is not None:
        lines += _fixed("flange_joint", parent, "flange", model.flange)
    lines += _fixed("tool_joint", parent, "tool", model.tool)
    if model.springs:
        lines.append("  <!-- Gazebo extension: dropped by plain URDF readers -->")
        for j in model.joints:
            lines += [f"  <gazebo reference={attr(j.name)}>",
                      f"    <springStiffness>{num(j.stiffness_Nm_per_rad)}</springStiffness>",
                      "    <springReference>0</springReference>", "  </gazebo>"]
    lines += ["</robot>", ""]
    return "\n".join(lines)
