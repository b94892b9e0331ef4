"""SDFormat 1.9 of a :class:`~analysis.export.sim_model.SimModel`: links, revolute joints with
``<dynamics><spring_stiffness>``/``<spring_reference>``, the flange and P as ``<frame>``s.

Each link's ``<pose relative_to>`` its parent link is its placement at zero joint angle;
a joint's pose is the child link's frame (SDFormat's default) and its ``<xyz>`` axis is in
that frame. The base link is welded to ``world`` by a fixed joint.
"""

from __future__ import annotations

from analysis.export.sim_model import Inertial, SimModel
from analysis.export.xml_text import attr, comment, left_out_lines, num, nums, rpy


def _pose(T, relative_to: str, indent: str) -> str:
    values = nums([*T[:3, 3], *rpy(T[:3, :3])])
    return f"{indent}<pose relative_to={attr(relative_to)}>{values}</pose>"


def _inertial(inertial: Inertial, indent: str) -> list[str]:
    I = inertial.inertia_kg_m2
    lines = [f"{indent}<inertial>"]
    if inertial.placeholder:
        lines.append(f"{indent}  <!-- placeholder: no mass properties in the robot model -->")
    lines += [f"{indent}  <pose>{nums(inertial.com_m)} 0 0 0</pose>",
              f"{indent}  <mass>{num(inertial.mass_kg)}</mass>", f"{indent}  <inertia>"]
    for name, (a, b) in (("ixx", (0, 0)), ("ixy", (0, 1)), ("ixz", (0, 2)),
                         ("iyy", (1, 1)), ("iyz", (1, 2)), ("izz", (2, 2))):
        lines.append(f"{indent}    <{name}>{num(I[a, b])}</{name}>")
    return lines + [f"{indent}  </inertia>", f"{indent}</inertial>"]


def sdf_text(model: SimModel) -> str:
    """The SDFormat 1.9 document (text) of ``model``."""
    notes = list(model.header) + [
        "SDFormat 1.9. Units: m, rad, kg, N m/rad (spring_stiffness); joint values are the",
        "model's joint angles. spring_reference = 0: set it to the commanded pose.",
    ] + left_out_lines(model)
    lines = ['<?xml version="1.0"?>', comment(notes), '<sdf version="1.9">',
             f"  <model name={attr(model.name)}>", f"    <link name={attr(model.base_link)}/>",
             '    <joint name="base_fixed" type="fixed">', "      <parent>world</parent>",
             f"      <child>{model.base_link}</child>", "    </joint>"]
    parent = model.base_link
    for j in model.joints:
        lines += [f"    <link name={attr(j.link)}>", _pose(j.placement, parent, "      "),
                  *_inertial(j.inertial, "      "), "    </link>",
                  f'    <joint name={attr(j.name)} type="revolute">',
                  f"      <parent>{parent}</parent>", f"      <child>{j.link}</child>",
                  "      <axis>", f"        <xyz>{nums(j.axis)}</xyz>",
                  "        <limit>", f"          <lower>{num(j.lower_rad)}</lower>",
                  f"          <upper>{num(j.upper_rad)}</upper>", "        </limit>"]
        if j.stiffness_Nm_per_rad is not None:
            lines += ["        <dynamics>",
                      "          <spring_reference>0</spring_reference>",
                      f"          <spring_stiffness>{num(j.stiffness_Nm_per_rad)}"
                      "</spring_stiffness>", "        </dynamics>"]
        lines += ["      </axis>", "    </joint>"]
        parent = j.link
    frames = ([("flange", model.flange)] if model.flange is not None else [])
    for name, T in frames + [("tool", model.tool)]:
        lines += [f"    <frame name={attr(name)} attached_to={attr(parent)}>",
                  _pose(T, parent, "      "), "    </frame>"]
    lines += ["  </model>", "</sdf>", ""]
    return "\n".join(lines)
