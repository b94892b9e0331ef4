"""Writes milling_path.csv: a milling-like path for the KR240-2 example of docs/place.md.

A 300 x 200 mm pocket outline (25 mm corner radii) on the top face z = 0 with the
tool axis straight down into the part, a lead-in ramp that tilts the tool by
10 deg, and a 5-axis finishing pass along one side at z = -5 mm. Process wrench
on the tool, tool frame: 400 N, 250 N lateral, 300 N pushing the tool back out
of the part, 20 N m about the tool axis (spindle torque reaction).
"""

from pathlib import Path

import numpy as np

W, H, R = 150.0, 100.0, 25.0


def contour() -> list[tuple[float, float]]:
    pts: list[tuple[float, float]] = []

    def arc(cx, cy, a0, a1, n):
        pts.extend((cx + R * np.cos(a), cy + R * np.sin(a))
                   for a in np.linspace(a0, a1, n, endpoint=False))

    def line(x0, y0, x1, y1, n):
        pts.extend((x0 + (x1 - x0) * t, y0 + (y1 - y0) * t)
                   for t in np.linspace(0, 1, n, endpoint=False))

    line(-W + R, -H, W - R, -H, 10)
    arc(W - R, -H + R, -np.pi / 2, 0, 4)
    line(W, -H + R, W, H - R, 7)
    arc(W - R, H - R, 0, np.pi / 2, 4)
    line(W - R, H, -W + R, H, 10)
    arc(-W + R, H - R, np.pi / 2, np.pi, 4)
    line(-W, H - R, -W, -H + R, 7)
    arc(-W + R, -H + R, np.pi, 1.5 * np.pi, 4)
    return pts


def main() -> None:
    rows = [(x, y, 0.0, 0.0) for x, y in contour()]
    x0, y0 = rows[-1][:2]
    for t in np.linspace(0, 1, 8)[1:]:  # lead-in: move and tilt together
        rows.append((x0 + (-100 - x0) * t, y0 + (-60 - y0) * t, -5.0 * t, 10.0 * t))
    rows += [(x, -60.0, -5.0, 10.0) for x in np.linspace(-100, 100, 9)[1:]]
    out = Path(__file__).with_name("milling_path.csv")
    with out.open("w") as fh:
        fh.write("x_mm,y_mm,z_mm,ax,ay,az,fx_N,fy_N,fz_N,mx_Nm,my_Nm,mz_Nm\n")
        for x, y, z, tilt in rows:
            a = np.radians(tilt)
            fh.write(f"{x:.3f},{y:.3f},{z:.3f},0,{np.sin(a):.6f},{-np.cos(a):.6f},"
                     "400,250,-300,0,0,20\n")
    print(f"wrote {len(rows)} points to {out}")


if __name__ == "__main__":
    main()
