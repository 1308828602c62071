#!/usr/bin/env python3
"""Writes the paper's scenes as recorded trajectories (assets/trajectories/paper_*.csv).

The real brain's trajectories (assets/trajectories/real_brain_*.csv) are
written by scripts/place_tethers_real_brain.py with the tethers they cut or
spare; the phantom's tethered scene's by scripts/place_tethers.py.

The numbers come from the phantom's landmarks (`fissure mesh phantom`): the
paper-12k Sylvian fissure (entry (-68.09, 10, -11.65) mm, inward +x, fissure
normal (0, 0.3429, 0.9394), width 8.4 mm, depth 22 mm); the paper-12k
inter-hemispheric fissure (entry (0, 0, 23.25) mm, inward -z, normal +x,
width 8.4 mm); the v-valley / u-shape blocks (entry (0, 0, 30) mm, inward -z,
valley along y). Run from the repository root; output is deterministic.
Format: see src/scenario/trajectory.rs (time_s,spatula,x_mm,y_mm,z_mm,qw,qx,qy,qz).
"""
import math

from trajectory_lib import add, blade_pose, cross, quat_from_axes, row, unit, write

# Fig. 14: two spatulas enter the left Sylvian fissure together, then spread apart.
entry, inward, normal = (-68.09, 10.0, -11.65), (1.0, 0.0, 0.0), unit((0.0, 0.3429, 0.9394))
L, SPREAD = 60.0, 7.0
rows = []
for k, side in ((0, 1.0), (1, -1.0)):
    for t, depth, off in ((0.0, -5.0, 1.2), (1.5, 18.0, 1.2), (4.0, 18.0, 1.2 + SPREAD), (5.0, 18.0, 1.2 + SPREAD)):
        p, q = blade_pose(entry, inward, normal, L, depth, side * off)
        rows.append(row(t, k, p, q))
write("assets/trajectories/paper_fig14_sylvian.csv",
      "Paper Fig. 14: two spatulas (60 x 8 x 1 mm) enter the left Sylvian fissure of paper-12k\n"
      f"side by side (centres 1.2 mm either side of the fissure plane), the tips 18 mm deep at 1.5 s,\n"
      f"then spread {SPREAD} mm each along the fissure normal until 4.0 s and hold.", rows)

# Fig. 11 (paper-9k, the paper's model for this comparison): one spatula in the
# inter-hemispheric fissure (entry (0, 0, 24.91) mm, width 9.4 mm: walls at x = +-4.69 mm);
# it presses the right wall, then jumps 5 thicknesses sideways in ONE frame (0.01 s).
entry, inward, normal = (0.0, 0.0, 24.91), (0.0, 0.0, -1.0), (1.0, 0.0, 0.0)
rows = []
for t, depth, off in ((0.0, -5.0, 0.0), (1.0, 15.0, 0.0), (1.5, 15.0, 4.5), (2.0, 15.0, 4.5), (2.01, 15.0, 9.5), (3.0, 15.0, 9.5)):
    p, q = blade_pose(entry, inward, normal, L, depth, off)
    rows.append(row(t, 0, p, q))
write("assets/trajectories/paper_fig11_interhemispheric.csv",
      "Paper Fig. 11: a 60 x 10 x 1 mm spatula enters the inter-hemispheric fissure of paper-9k\n"
      "(tip 15 mm deep at 1 s), presses the right wall (centre x = 4.5 mm at 1.5 s), then at 2.0 s\n"
      "moves 5 mm (5 thicknesses) to the right in a single 10 ms frame and holds.", rows)

# Fig. 12a-b: V-valley, the blade goes down the valley until both faces press the walls.
entry, inward, normal = (0.0, 0.0, 30.0), (0.0, 0.0, -1.0), (1.0, 0.0, 0.0)
rows = [row(t, 0, *blade_pose(entry, inward, normal, 40.0, d, 0.0)) for t, d in ((0.0, -3.0), (2.0, 15.5), (3.0, 15.5))]
write("assets/trajectories/paper_fig12_v_valley.csv",
      "Paper Fig. 12a-b: a 40 x 10 x 1 mm spatula goes down the V valley (24 mm wide at the top,\n"
      "16 mm deep) until its tip is 15.5 mm below the rim, wedging both faces against the walls.", rows)

# Fig. 12c-d: U-shape, the blade goes down the channel, then rotates about the y axis
# (the channel's axis) about a point 7 mm above its tip, so it lies across the channel.
rows = []
PIVOT_FROM_TIP, TIP_Z = 7.0, 16.0
for t, z_tip, ang in ((0.0, 33.0, 0.0), (1.0, TIP_Z, 0.0), (2.5, TIP_Z, 50.0), (3.0, TIP_Z, 50.0)):
    a = math.radians(ang)
    inw = (math.sin(a), 0.0, -math.cos(a))      # the tip swings towards +x
    nrm = (math.cos(a), 0.0, math.sin(a))
    pivot = (0.0, 0.0, z_tip + PIVOT_FROM_TIP)
    origin = add(pivot, inw, -(40.0 - PIVOT_FROM_TIP))
    q = quat_from_axes(inw, cross(nrm, inw), nrm)
    rows.append(row(t, 0, origin, q))
write("assets/trajectories/paper_fig12_u_shape.csv",
      "Paper Fig. 12c-d: a 40 x 10 x 1 mm spatula goes down the U channel (16 mm wide, 16 mm deep)\n"
      "until its tip is 14 mm below the rim, then rotates 50 degrees about the point 7 mm above its\n"
      "tip, so its tip presses one wall with one face and its upper part the other wall with the other face.", rows)
