#!/usr/bin/env python3
"""Places the tethers of the phantom Sylvian scene and writes its two trajectories.

From the paper-12k phantom's landmarks (as scripts/make_trajectories.py): the
left Sylvian fissure's entry (-68.09, 10, -11.65) mm, inward +x, fissure normal
(0, 0.3429, 0.9394), walls 4.2 mm either side of the mid-plane, 22 mm deep.
`across` is the direction along the fissure (normal x inward), the blades'
width. Every point is given on a wall or on the lateral surface; `fissure
check config/sylvian_tethers.ron` snaps each to the nearest boundary triangle
and refuses one more than 2 mm away.

Anatomy (after Yasargil's description of the Sylvian fissure's arachnoid, the
paper's ref. 3): arachnoid trabeculae bridge the frontal and temporal opercula
across the fissure; the superficial Sylvian vein runs along the fissure on the
opercula's lip; MCA branches (M3/M4) cross the fissure from its depth to the
opercula.

Writes, between the `// tethers:` markers of config/sylvian_tethers.ron, the
`tethers` field, and:
- assets/trajectories/sylvian_tethers.csv: the careful surgeon. The frontal
  blade goes in as in paper_fig14_sylvian.csv and cuts the bands (microscissors
  at its tip, the `cut` column) as its tip reaches each band's depth, then both
  blades spread 7 mm each until 4 s.
- assets/trajectories/sylvian_tethers_rough.csv: the rough one: no cut, the
  blades spread 10 mm each in 1 s.
Run from the repository root; output is deterministic.
"""
import math
import re

from trajectory_lib import add, blade_pose, cross, row, write

ENTRY, INWARD = (-68.09, 10.0, -11.65), (1.0, 0.0, 0.0)
NORMAL = tuple(c / math.hypot(0.3429, 0.9394) for c in (0.0, 0.3429, 0.9394))
HALF_WIDTH, L = 4.2, 60.0
ACROSS = cross(NORMAL, INWARD)


def at(depth, side, across):
    """The point `depth` mm in, `side` mm along the normal from the mid-plane, `across` mm along the fissure."""
    return add(add(add(ENTRY, INWARD, depth), NORMAL, side), ACROSS, across)


def fmt(p):
    return f"({p[0]:.2f}, {p[1]:.2f}, {p[2]:.2f})"


# Bands: two rows of four across the gap, at 1.5 mm either side of the blades' centre line.
BAND_DEPTHS, BAND_ACROSS = (3.0, 7.0, 11.0, 15.0), (-1.5, 1.5)
bands = []
for d in BAND_DEPTHS:
    for a in BAND_ACROSS:
        bands.append((f"trabecula {len(bands) + 1}", at(d, HALF_WIDTH, a), at(d, -HALF_WIDTH, a)))

# The superficial Sylvian vein on the frontal lip, along the fissure; an MCA branch crossing from the
# temporal wall to the frontal wall 12 mm beside the blades.
vein = [at(0.02 * a * a, HALF_WIDTH + 1.0, a) for a in (-12.0, -6.0, 0.0, 6.0, 12.0)]  # the lateral surface curves inward along the fissure
artery = [at(14.0, -HALF_WIDTH, 12.0), at(14.0, HALF_WIDTH, 12.0)]

lines = ["    tethers: (", "        vessels: ["]
lines.append(f'            (name: "superficial Sylvian vein", kind: Vein, diameter_mm: 2.0, points_mm: [{", ".join("Surface" + fmt(p) for p in vein)}]),')
lines.append(f'            (name: "MCA M3 branch", kind: Artery, diameter_mm: 1.0, points_mm: [{", ".join("Surface" + fmt(p) for p in artery)}]),')
lines.append("        ],")
lines.append("        bands: [")
for name, a, b in bands:
    lines.append(f'            (name: "{name}", from_mm: {fmt(a)}, to_mm: {fmt(b)}),')
lines.append("        ],")
lines.append("    ),")
block = "\n".join(lines)

path = "config/sylvian_tethers.ron"
text = open(path).read()
new = re.sub(r"(    // tethers: begin\n).*?(    // tethers: end\n)", lambda m: m.group(1) + block + "\n" + m.group(2), text, flags=re.S)
open(path, "w").write(new)


def trajectory(spread, spread_end, cuts):
    rows = []
    for k, side in ((0, 1.0), (1, -1.0)):
        keys = [(0.0, -5.0, 1.2, 0), (1.5, 18.0, 1.2, 0), (spread_end, 18.0, 1.2 + spread, 0), (5.0, 18.0, 1.2 + spread, 0)]
        if cuts and k == 0:
            # The tip reaches depth d at t = 1.5 (d + 5) / 23 s on its way in.
            keys += [(1.5 * (d + 5.0) / 23.0, d, 1.2, 1) for d in BAND_DEPTHS]
        for t, depth, off, cut in sorted(keys):
            p, q = blade_pose(ENTRY, INWARD, NORMAL, L, depth, side * off)
            rows.append((t, k, row(t, k, p, q, cut, time_digits=4)))
    return [r for _, _, r in sorted(rows)]


write("assets/trajectories/sylvian_tethers.csv",
      "The careful surgeon on the phantom's left Sylvian fissure (config/sylvian_tethers.ron; scripts/place_tethers.py):\n"
      "the blades go in as in paper_fig14_sylvian.csv, the frontal blade's microscissors cutting the arachnoid\n"
      "bands as its tip reaches each (cut = 1), then both spread 7 mm along the fissure normal until 4 s and hold.",
      trajectory(7.0, 4.0, True), cut=True)
write("assets/trajectories/sylvian_tethers_rough.csv",
      "A rough opening of the same fissure: no sharp dissection, the blades spread 10 mm each in 1 s\n"
      "(1.5 -> 2.5 s) through the uncut arachnoid, and hold.",
      trajectory(10.0, 2.5, False), cut=True)
