#!/usr/bin/env python3
"""Writes the paper's scenes as recorded trajectories (assets/trajectories/paper_*.csv).

The numbers come from the phantom's landmarks (`fissure mesh phantom`): the
paper-12k Sylvian fissure (entry (-68.09, 10, -11.65) mm, inward +x, fissure
normal (0, 0.3429, 0.9394), width 8.4 mm, depth 22 mm); the paper-12k
inter-hemispheric fissure (entry (0, 0, 23.25) mm, inward -z, normal +x,
width 8.4 mm); the v-valley / u-shape blocks (entry (0, 0, 30) mm, inward -z,
valley along y). Run from the repository root; output is deterministic.
Format: see src/scenario/trajectory.rs (time_s,spatula,x_mm,y_mm,z_mm,qw,qx,qy,qz).
"""
import math

def quat_from_axes(x, y, z):
    # rotation matrix with columns x, y, z -> unit quaternion (w, x, y, z)
    m = [[x[0], y[0], z[0]], [x[1], y[1], z[1]], [x[2], y[2], z[2]]]
    tr = m[0][0] + m[1][1] + m[2][2]
    if tr > 0:
        s = math.sqrt(tr + 1.0) * 2
        q = (0.25 * s, (m[2][1] - m[1][2]) / s, (m[0][2] - m[2][0]) / s, (m[1][0] - m[0][1]) / s)
    elif m[0][0] > m[1][1] and m[0][0] > m[2][2]:
        s = math.sqrt(1.0 + m[0][0] - m[1][1] - m[2][2]) * 2
        q = ((m[2][1] - m[1][2]) / s, 0.25 * s, (m[0][1] + m[1][0]) / s, (m[0][2] + m[2][0]) / s)
    elif m[1][1] > m[2][2]:
        s = math.sqrt(1.0 + m[1][1] - m[0][0] - m[2][2]) * 2
        q = ((m[0][2] - m[2][0]) / s, (m[0][1] + m[1][0]) / s, 0.25 * s, (m[1][2] + m[2][1]) / s)
    else:
        s = math.sqrt(1.0 + m[2][2] - m[0][0] - m[1][1]) * 2
        q = ((m[1][0] - m[0][1]) / s, (m[0][2] + m[2][0]) / s, (m[1][2] + m[2][1]) / s, 0.25 * s)
    n = math.sqrt(sum(c * c for c in q))
    return tuple(c / n for c in q)

def cross(a, b):
    return (a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0])

def add(a, b, s=1.0):
    return tuple(ai + s * bi for ai, bi in zip(a, b))

def unit(a):
    n = math.sqrt(sum(c * c for c in a))
    return tuple(c / n for c in a)

def blade_pose(entry, inward, normal, length, tip_depth, offset):
    """Origin (handle end) such that the tip is `tip_depth` mm past `entry` along
    `inward`, shifted `offset` mm along `normal`; blade x = inward, face z = normal."""
    origin = add(add(entry, inward, tip_depth - length), normal, offset)
    q = quat_from_axes(inward, cross(normal, inward), normal)
    return origin, q

def row(t, k, p, q):
    return f"{t:.2f},{k},{p[0]:.4f},{p[1]:.4f},{p[2]:.4f},{q[0]:.9f},{q[1]:.9f},{q[2]:.9f},{q[3]:.9f}"

def write(path, comment, rows):
    with open(path, "w") as f:
        f.write("".join(f"# {line}\n" for line in comment.splitlines()))
        f.write("time_s,spatula,x_mm,y_mm,z_mm,qw,qx,qy,qz\n")
        f.write("\n".join(rows) + "\n")

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

# The real brain (assets/brain/brain_pial_coarse.msh.gz, fsaverage5 RAS millimetres):
# two 0.5 mm blades go down the inter-hemispheric gap at y = -30 mm side by side, the
# tips 25 mm below the top of the brain (z = 75 -> 50 mm), then spread 5 mm apart each,
# retracting the two hemispheres.
entry, inward, normal = (0.0, -30.0, 75.0), (0.0, 0.0, -1.0), (1.0, 0.0, 0.0)
rows = []
for k, side in ((0, -1.0), (1, 1.0)):
    for t, depth, off in ((0.0, -5.0, 0.4), (1.0, 25.0, 0.4), (3.0, 25.0, 5.4), (4.0, 25.0, 5.4)):
        p, q = blade_pose(entry, inward, normal, 60.0, depth, side * off)
        rows.append(row(t, k, p, q))
write("assets/trajectories/real_brain_interhemispheric.csv",
      "Real brain (fsaverage5, assets/brain): two 60 x 8 x 0.5 mm blades enter the\n"
      "inter-hemispheric gap at y = -30 mm (tips 25 mm deep at 1 s), then spread 5 mm each\n"
      "towards their hemisphere until 3 s and hold.", rows)

# The real brain's left Sylvian fissure (fsaverage5 RAS millimetres): at its
# anterior stem (y = 15 mm) the lateral surface has a cleft about 10 mm tall
# (z = -11 .. -1 mm) and 12-15 mm deep (lateral surface x = -54 mm, floor
# x = -40 mm). Two 60 x 8 x 0.5 mm blades, faces up and down, go into it
# side by side (tips 14 mm past x = -56 mm at 1 s), then spread apart, the
# upper blade lifting the frontal operculum SPREAD_FRONTAL mm and the lower one
# pressing the temporal one SPREAD_TEMPORAL mm, until 3.5 s, and hold. The
# temporal operculum's upper surface falls away inwards (z = -10 .. -13 mm at
# the lip, -16 .. -20 mm under the tips), so its blade travels further to hold
# a patch as wide as the frontal one's: 10.5 mm gave 0.068 N on 18 vertices,
# 13.5 mm gives 0.11 N on 33. The spread is slow enough (under 1/8 of the
# blade's thickness a 10 ms frame) that no frame needs sub-steps.
SPREAD_FRONTAL, SPREAD_TEMPORAL = 10.5, 13.5
entry, inward, normal = (-56.0, 15.0, -6.0), (1.0, 0.0, 0.0), (0.0, 0.0, 1.0)


def sylvian_rows(spread_temporal, spread_end, hold_end):
    """Both blades in at 1 s, spread (frontal SPREAD_FRONTAL up, temporal down) until spread_end, held to hold_end."""
    rows = []
    for k, side, spread in ((0, 1.0, SPREAD_FRONTAL), (1, -1.0, spread_temporal)):
        for t, depth, off in ((0.0, -5.0, 0.4), (1.0, 14.0, 0.4), (spread_end, 14.0, 0.4 + spread), (hold_end, 14.0, 0.4 + spread)):
            p, q = blade_pose(entry, inward, normal, 60.0, depth, side * off)
            rows.append(row(t, k, p, q))
    return rows


rows = sylvian_rows(SPREAD_TEMPORAL, 3.5, 4.0)
write("assets/trajectories/real_brain_sylvian.csv",
      "Real brain (fsaverage5, assets/brain): two 60 x 8 x 0.5 mm blades enter the\n"
      f"left Sylvian fissure's stem at y = 15 mm, z = -6 mm (tips 14 mm deep at 1 s), then spread\n"
      f"(upper blade up {SPREAD_FRONTAL:g} mm, lower blade down {SPREAD_TEMPORAL:g} mm) until 3.5 s and hold.", rows)
# The same scene pressing wider, for the fem frame bar (>= 50 constrained
# vertices a blade): the lower blade down 16.5 mm, both spreads until 4.0 s
# (slow enough for one step a frame), held to 4.5 s; replay it with
# `--set duration_s=4.5`. 52 / 56 contact vertices at the end.
SPREAD_TEMPORAL_WIDE = 16.5
rows = sylvian_rows(SPREAD_TEMPORAL_WIDE, 4.0, 4.5)
write("assets/trajectories/real_brain_sylvian_wide.csv",
      "Real brain (fsaverage5, assets/brain): the Sylvian scene's blades pressing wider\n"
      f"(upper blade up {SPREAD_FRONTAL:g} mm, lower blade down {SPREAD_TEMPORAL_WIDE:g} mm, tips 14 mm deep at 1 s) until 4.0 s,\n"
      "held to 4.5 s (replay with --set duration_s=4.5).", rows)
