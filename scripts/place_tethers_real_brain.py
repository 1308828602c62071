#!/usr/bin/env python3
"""Places the vessels and arachnoid bands of the two real-brain scenes from the
meshes themselves, and writes the scenes' trajectories.

Every tether point is found on the mesh's boundary (the faces of exactly one
tetrahedron, as the simulator extracts it) by casting a ray to the first
boundary triangle it meets, so each point lies on the surface at rest;
`fissure check` snaps each to the nearest boundary triangle and refuses one
more than 2 mm away (or an anchor inside the tissue). Coordinates are
fsaverage RAS millimetres (x right, y anterior, z up).

config/real_brain/sylvian_tethers.ron (fine mesh, brain_pial_q15.msh.gz), after
Yasargil's microneurosurgical description of the Sylvian fissure: arachnoid
trabeculae bridge the frontal and temporal opercula across the cleft; the
superficial Sylvian (middle cerebral) vein runs along the fissure's lip on the
lateral surface; MCA M3/M4 branches cross from the depth (the insula) to the
opercula and out over their lips. The blades enter the stem at y = 15 mm,
z = -6 mm (their width spans y = 11..19 mm), tips 14 mm past x = -56 mm.
- Bands: vertical rays from the blades' plane (z = -6 mm) up to the frontal
  operculum's underside and down to the temporal operculum's upper surface, at
  the depths the frontal tip passes (BAND_DEPTHS) and across the blades'
  centre line (BAND_ACROSS). The frontal tip runs along y = 15 mm, and its
  microscissors reach 2 mm (src/sim/tethers.rs measures the distance from the
  tip to the band's segment), so every band lies within 2 mm of that line:
  bands farther out could not be cut on the way in and would tear in the
  spread.
- The superficial Sylvian vein: on the temporal operculum's lateral surface
  1 mm below the fissure's lower lip (the lip found by rays along +x: where the
  lateral surface falls more than 6 mm into the fissure), from the posterior
  ramus (y = -24 mm) forward to 3 mm behind the blades (y = 8 mm): the
  temporal blade presses that lip down where it spans it, and a vein carried
  on under it (to y = 16 mm) tore in the careful opening (stretch 1.51), so
  the opening is made in front of the vein, as surgeons open the fissure
  beside the vein to spare it.
- MCA branches: from the insula at the fissure's floor to the inside of an
  operculum, over its lip and up (or down) its lateral surface, beside the
  blades' path (ARTERIES: y = 4 and 7 mm, 7 and 4 mm behind the blades, and
  y = 22 mm, 3 mm in front).

config/real_brain/interhemispheric_tethers.ron (coarse mesh, brain_pial_coarse.msh.gz):
bridging veins, each a superior cerebral vein on the convexity running
medially over the crests of the gyri (each point the highest within 2.5 mm,
not a sulcus' floor) to the crest beside the midline (6-9 mm off it), where it
leaves the cortex and crosses the subdural space to the superior sagittal
sinus, a fixed anchor on the midline 3 mm above the brain's top. Three a
hemisphere (BRIDGING): one leaving the cortex 1 mm behind the blades (which
span y = -34..-26 mm) and entering the sinus there, two further forward that
enter the sinus 6 mm in front of where they leave the cortex (running
forwards, against the sinus' flow, as the superior cerebral veins do); none
under the blades. fsaverage has no sutures: where real bridging veins cluster
(mostly in front of the coronal suture) is not placed from the mesh; the veins
stand around the scene's opening at y = -30 mm, 12-16 mm apart along the
sinus. The model's tissue gives way within a few millimetres of a blade (soft,
E = 3 kPa, held 30 mm off the midline), so a retraction stretches only a vein
at the blades' edge or one whose course on the convexity passes beside them:
the careful one (5 mm a blade) stretches every vein under 1 %, the rough one
(15 mm) tears the right vein at the blades' edge (y = -35 mm) and the left one
that leaves the cortex at y = -21 mm (its course starts at y = -32.5 mm,
beside the blades).

Writes the `tethers` field between the `// tethers: begin` / `// tethers: end`
markers of each scene, and the real brain's trajectories (this script is
their only writer):
- assets/trajectories/real_brain_sylvian.csv: the careful opening. Both blades
  in at 1 s, the frontal blade's microscissors cutting the bands as its tip
  reaches each (the `cut` column), then the spread (frontal up 10.5 mm,
  temporal down 13.5 mm) until 3.5 s, held to 4 s.
- assets/trajectories/real_brain_sylvian_wide.csv: the same pressing wider for
  the frame-time bar (temporal down 16.5 mm, spread until 4.0 s, held to
  4.5 s; replay with --set duration_s=4.5), with the same cuts (uncut, the
  spread tears 12 of the 18 bands).
- assets/trajectories/real_brain_sylvian_rough.csv: a rough opening: no cut,
  the blades spread wider (frontal 12 mm, temporal 16.5 mm) in 1 s.
- assets/trajectories/real_brain_interhemispheric.csv: the careful retraction
  (5 mm each, 1 to 3 s).
- assets/trajectories/real_brain_interhemispheric_rough.csv: a rough one
  (15 mm each, 1 to 1.8 s).
`python3 scripts/place_tethers_real_brain.py [sylvian] [interhemispheric]`
does the named scenes (both when none is named).
Run from the repository root (numpy needed); output is deterministic.
"""
import gzip
import re
import sys

import numpy as np

from trajectory_lib import blade_pose, row, write

FINE = "assets/brain/brain_pial_q15.msh.gz"
COARSE = "assets/brain/brain_pial_coarse.msh.gz"


class Surface:
    """The boundary of a gmsh 2.2 ASCII tetrahedral mesh: the faces of exactly one tetrahedron."""

    def __init__(self, path):
        with gzip.open(path, "rt") as f:
            lines = f.read().split("\n")
        i = lines.index("$Nodes")
        count = int(lines[i + 1])
        self.nodes = np.array([line.split()[1:4] for line in lines[i + 2:i + 2 + count]], float)
        j = lines.index("$Elements")
        tets = []
        for line in lines[j + 2:j + 2 + int(lines[j + 1])]:
            s = line.split()
            if s[1] == "4":
                tags = int(s[2])
                tets.append([int(x) - 1 for x in s[3 + tags:7 + tags]])
        tets = np.array(tets)
        faces = np.concatenate([tets[:, [1, 2, 3]], tets[:, [0, 3, 2]], tets[:, [0, 1, 3]], tets[:, [0, 2, 1]]])
        _, first, counts = np.unique(np.sort(faces, axis=1), axis=0, return_index=True, return_counts=True)
        p = self.nodes[faces[np.sort(first[counts == 1])]]
        self.v0, self.e1, self.e2 = p[:, 0], p[:, 1] - p[:, 0], p[:, 2] - p[:, 0]

    def hits(self, origin, direction):
        """Distances along the ray (unit direction) to every boundary triangle it crosses, ascending."""
        o, d = np.asarray(origin, float), np.asarray(direction, float)
        pv = np.cross(d, self.e2)
        det = np.einsum("ij,ij->i", self.e1, pv)
        ok = np.abs(det) > 1e-12
        inv = np.where(ok, 1.0 / np.where(ok, det, 1.0), 0.0)
        s = o - self.v0
        u = np.einsum("ij,ij->i", s, pv) * inv
        qv = np.cross(s, self.e1)
        v = (qv @ d) * inv
        t = np.einsum("ij,ij->i", qv, self.e2) * inv
        return np.sort(t[ok & (u >= 0) & (v >= 0) & (u + v <= 1) & (t > 1e-9)])

    def first(self, origin, direction):
        """The first boundary point the ray meets, or None."""
        t = self.hits(origin, direction)
        return None if len(t) == 0 else tuple(float(o + t[0] * d) for o, d in zip(origin, direction))

    def outside(self, p):
        """Whether p lies outside the tissue (an even number of crossings up to +z)."""
        return len(self.hits(p, (0.0, 0.0, 1.0))) % 2 == 0


def fmt(p):
    return f"({p[0]:.2f}, {p[1]:.2f}, {p[2]:.2f})"


def vessel_line(name, kind, diameter, points):
    pts = ", ".join(f"{w}{fmt(p)}" for w, p in points)
    return f'            (name: "{name}", kind: {kind}, diameter_mm: {diameter}, points_mm: [{pts}]),'


def write_tethers(path, comment, vessels, bands):
    """Replaces what lies between the scene's `// tethers: begin` and `// tethers: end` lines."""
    lines = [f"    // {c}" if c else "    //" for c in comment.splitlines()]
    lines += ["    tethers: (", "        vessels: ["] + vessels + ["        ],"]
    if bands:
        lines += ["        bands: ["]
        lines += [f'            (name: "{n}", from_mm: {fmt(a)}, to_mm: {fmt(b)}),' for n, a, b in bands]
        lines += ["        ],"]
    else:
        lines += ["        bands: [],"]
    lines += ["    ),"]
    markers = re.compile(r"(    // tethers: begin\n).*?(    // tethers: end\n)", flags=re.S)
    text = open(path).read()
    if not markers.search(text):
        sys.exit(f"{path}: no `// tethers: begin` / `// tethers: end` lines")
    open(path, "w").write(markers.sub(lambda m: m.group(1) + "\n".join(lines) + "\n" + m.group(2), text))


# ---------------------------------------------------------------- Sylvian fissure (fine mesh)

# The blades' frame (as the scene): entry at the stem's lateral surface, inward +x, faces up / down.
S_ENTRY, S_INWARD, S_NORMAL, S_LENGTH = (-56.0, 15.0, -6.0), (1.0, 0.0, 0.0), (0.0, 0.0, 1.0), 60.0
# The real brain's left Sylvian fissure: at its anterior stem (y = 15 mm) the
# lateral surface has a cleft about 10 mm tall (z = -11 .. -1 mm) and 12-15 mm
# deep (lateral surface x = -54 mm, floor x = -40 mm). Two 60 x 8 x 0.5 mm
# blades, faces up and down, go into it side by side (tips 14 mm past
# x = -56 mm at 1 s), then spread apart, the upper blade lifting the frontal
# operculum SPREAD_FRONTAL mm and the lower one pressing the temporal one
# SPREAD_TEMPORAL mm, until 3.5 s, and hold. The temporal operculum's upper
# surface falls away inwards (z = -10 .. -13 mm at the lip, -16 .. -20 mm under
# the tips), so its blade travels further to hold a patch as wide as the
# frontal one's: 10.5 mm gave 0.068 N on 18 vertices, 13.5 mm gives 0.11 N on
# 33. The spread is slow enough (under 1/8 of the blade's thickness a 10 ms
# frame) that no frame needs sub-steps.
SPREAD_FRONTAL, SPREAD_TEMPORAL = 10.5, 13.5
# The same scene pressing wider, for the fem frame bar (>= 50 constrained
# vertices a blade): the lower blade down 16.5 mm, both spreads until 4.0 s
# (slow enough for one step a frame), held to 4.5 s; replay it with
# `--set duration_s=4.5`. 52 / 54 contact vertices at the end without the
# tethers, 48 / 56 with them.
SPREAD_TEMPORAL_WIDE = 16.5
# The rough opening: both blades spread wider (the temporal one as the wide
# press, the frontal one 1.5 mm more) in 1 s, from 1 s, without cutting.
ROUGH_FRONTAL, ROUGH_TEMPORAL, ROUGH_END = 12.0, 16.5, 2.0
# The tips' depth (mm past the entry along +x): -5 at 0 s, 14 at 1 s.
TIP_START, TIP_END, TIP_IN = -5.0, 14.0, 1.0
# Bands: at these tip depths (x = -52 .. -42.5 mm), on the blades' centre line
# (y = 15 mm) and 1.6 mm either side of it.
BAND_DEPTHS = (4.0, 6.0, 8.0, 10.0, 12.0, 13.5)
BAND_ACROSS = (-1.6, 0.0, 1.6)
# The vein's points along the fissure (y, mm), posterior to anterior.
VEIN_Y = (-24.0, -19.0, -14.0, -9.0, -4.0, 0.0, 4.0, 8.0)
# MCA branches: (name, y, the operculum it runs to).
ARTERIES = (
    ("MCA M4 branch to the frontal operculum, behind the blades", 7.0, "frontal"),
    ("MCA M4 branch to the temporal operculum, behind the blades", 4.0, "temporal"),
    ("MCA M4 branch to the frontal operculum, in front of the blades", 22.0, "frontal"),
)


def fissure_lip(surf, y, z_expected):
    """Where the lateral surface at `y` falls into the fissure near `z_expected`: (top, bottom) z of the run of
    rays along +x that go more than 6 mm deeper than the lateral surface above the fissure (the median depth
    of the window's top 3 mm, 14 mm above `z_expected`); the run that holds `z_expected`, else the nearest."""
    zs = np.arange(z_expected + 14.0, z_expected - 20.0, -0.25)
    xs = []
    for z in zs:
        p = surf.first((-100.0, y, z), (1.0, 0.0, 0.0))
        xs.append(np.inf if p is None else p[0])
    xs = np.array(xs)
    deep = xs > np.median(xs[:12]) + 6.0
    runs, k = [], 0
    while k < len(zs):
        if deep[k]:
            e = k
            while e + 1 < len(zs) and deep[e + 1]:
                e += 1
            runs.append((k, e))
            k = e + 1
        else:
            k += 1
    assert runs, f"no fissure at y = {y}"
    k, e = min(runs, key=lambda r: max(zs[r[1]] - z_expected, z_expected - zs[r[0]], 0.0))
    return float(zs[k]), float(zs[e])


def fissure_z(y):
    """The fissure's line on the lateral surface, roughly (the posterior ramus falls forward to the stem)."""
    return 13.5 - 0.53 * (y + 26.0) if y < 10.0 else -6.0


def sylvian():
    surf = Surface(FINE)
    bands = []
    for d in BAND_DEPTHS:
        x = S_ENTRY[0] + d
        for a in BAND_ACROSS:
            y = S_ENTRY[1] + a
            o = (x, y, S_ENTRY[2])
            assert surf.outside(o), f"band origin {o} inside the tissue"
            up, down = surf.first(o, (0.0, 0.0, 1.0)), surf.first(o, (0.0, 0.0, -1.0))
            assert up and down and up[2] < 12.0 and down[2] > -26.0, f"no banks at {o}: {up} {down}"
            bands.append((f"trabecula {len(bands) + 1}", up, down))

    vein = []
    for y in VEIN_Y:
        top, bottom = fissure_lip(surf, y, fissure_z(y))
        p = surf.first((-100.0, y, bottom - 1.0), (1.0, 0.0, 0.0))
        vein.append(("Surface", p))
    vessels = [vessel_line("superficial Sylvian vein", "Vein", 2.0, vein)]

    for name, y, side in ARTERIES:
        top, bottom = fissure_lip(surf, y, fissure_z(y))
        # The branch comes out of the fissure's floor in the cleft's middle, at most 4 mm inside its lip.
        mid = max(0.5 * (top + bottom), top - 4.0) if side == "frontal" else min(0.5 * (top + bottom), bottom + 4.0)
        floor = surf.first((-100.0, y, mid), (1.0, 0.0, 0.0))
        # Inside the operculum: a ray from the cleft's middle, 4 mm out from the floor, up or down to the wall.
        sign = 1.0 if side == "frontal" else -1.0
        inner = surf.first((floor[0] - 4.0, y, mid), (0.0, 0.0, sign))
        lip_z = top + 1.5 if side == "frontal" else bottom - 1.5
        lip = surf.first((-100.0, y, lip_z), (1.0, 0.0, 0.0))
        out = surf.first((-100.0, y, lip_z + sign * 7.0), (1.0, 0.0, 0.0))
        pts = [("Surface", floor), ("Surface", inner), ("Surface", lip), ("Surface", out)]
        vessels.append(vessel_line(name, "Artery", 1.0, pts))

    comment = (
        "What opening the Sylvian fissure risks, after Yasargil's microneurosurgical description:\n"
        "arachnoid trabeculae bridge the frontal and temporal opercula; the superficial Sylvian\n"
        "(middle cerebral) vein runs along the fissure's lip; MCA M3/M4 branches cross from the\n"
        "depth to the opercula. Placed by scripts/place_tethers_real_brain.py from the mesh (each\n"
        "point a ray's first hit on the surface; the blades span y = 11..19 mm):\n"
        "- the superficial Sylvian vein on the temporal operculum's lateral surface 1 mm below the\n"
        f"  fissure's lower lip, from the posterior ramus (y = {VEIN_Y[0]:g} mm) forward to "
        f"{11.0 - VEIN_Y[-1]:g} mm behind the\n"
        "  blades (y = 8 mm): the opening is made in front of it, sparing it;\n"
        "- three MCA M4 branches from the insula over the inside and the lip of an operculum onto\n"
        "  its lateral surface, beside the blades' path: to the frontal operculum 4 mm behind the\n"
        "  blades and 3 mm in front of them, to the temporal one 7 mm behind;\n"
        "- arachnoid bands from the frontal operculum's underside to the temporal operculum's\n"
        f"  upper surface, at {len(BAND_DEPTHS)} depths the blades' tips pass (x = {S_ENTRY[0] + BAND_DEPTHS[0]:g} .. "
        f"{S_ENTRY[0] + BAND_DEPTHS[-1]:g} mm), each on the\n"
        "  blades' centre line and 1.6 mm either side (y = 13.4, 15, 16.6 mm): within the 2 mm reach\n"
        "  of the microscissors at the frontal blade's tip, which runs along y = 15 mm.\n"
        "The scene's trajectory cuts every band on the way in, then spreads; nothing tears.\n"
        "assets/trajectories/real_brain_sylvian_rough.csv spreads wider and faster uncut."
    )
    write_tethers("config/real_brain/sylvian_tethers.ron", comment, vessels, bands)
    return len(vein) - 1 + 3 * len(ARTERIES), len(bands)


def sylvian_rows(spread_frontal, spread_temporal, spread_end, hold_end, cuts):
    """Both blades in at 1 s (the frontal one cutting at each band depth when `cuts`), spread until spread_end,
    held to hold_end."""
    rows = []
    for k, side, spread in ((0, 1.0, spread_frontal), (1, -1.0, spread_temporal)):
        keys = [(0.0, TIP_START, 0.4, 0), (TIP_IN, TIP_END, 0.4, 0), (spread_end, TIP_END, 0.4 + spread, 0), (hold_end, TIP_END, 0.4 + spread, 0)]
        if cuts and k == 0:
            # The tip reaches depth d at t = (d - TIP_START) / (TIP_END - TIP_START) s; the row's pose is the
            # straight path's at that (rounded) time, so the motion stays the same.
            for d in BAND_DEPTHS:
                t = round(TIP_IN * (d - TIP_START) / (TIP_END - TIP_START), 4)
                keys.append((t, TIP_START + (TIP_END - TIP_START) * t / TIP_IN, 0.4, 1))
        for t, depth, off, cut in sorted(keys):
            p, q = blade_pose(S_ENTRY, S_INWARD, S_NORMAL, S_LENGTH, depth, side * off)
            rows.append((t, k, row(t, k, p, q, cut, time_digits=4)))
    return [r for _, _, r in sorted(rows)]


def sylvian_trajectories():
    write("assets/trajectories/real_brain_sylvian.csv",
          "Real brain (fsaverage5, assets/brain): two 60 x 8 x 0.5 mm blades enter the\n"
          "left Sylvian fissure's stem at y = 15 mm, z = -6 mm (tips 14 mm deep at 1 s), the frontal\n"
          "blade's microscissors cutting the arachnoid bands as its tip reaches each (cut = 1), then spread\n"
          f"(upper blade up {SPREAD_FRONTAL:g} mm, lower blade down {SPREAD_TEMPORAL:g} mm) until 3.5 s and hold\n"
          "(scripts/place_tethers_real_brain.py).",
          sylvian_rows(SPREAD_FRONTAL, SPREAD_TEMPORAL, 3.5, 4.0, True), cut=True)
    write("assets/trajectories/real_brain_sylvian_wide.csv",
          "Real brain (fsaverage5, assets/brain): the Sylvian scene's blades pressing wider\n"
          f"(upper blade up {SPREAD_FRONTAL:g} mm, lower blade down {SPREAD_TEMPORAL_WIDE:g} mm, tips 14 mm deep at 1 s) until 4.0 s,\n"
          "held to 4.5 s (replay with --set duration_s=4.5); the bands cut on the way in as in\n"
          "real_brain_sylvian.csv (scripts/place_tethers_real_brain.py).",
          sylvian_rows(SPREAD_FRONTAL, SPREAD_TEMPORAL_WIDE, 4.0, 4.5, True), cut=True)
    write("assets/trajectories/real_brain_sylvian_rough.csv",
          "A rough opening of the real brain's Sylvian stem (config/real_brain/sylvian_tethers.ron): the blades go in\n"
          f"as in real_brain_sylvian.csv without cutting the arachnoid, then spread wider and faster (upper blade up\n"
          f"{ROUGH_FRONTAL:g} mm, lower blade down {ROUGH_TEMPORAL:g} mm, 1 -> {ROUGH_END:g} s) and hold to 4 s "
          "(scripts/place_tethers_real_brain.py).",
          sylvian_rows(ROUGH_FRONTAL, ROUGH_TEMPORAL, ROUGH_END, 4.0, False), cut=True)


# ---------------------------------------------------------------- inter-hemispheric fissure (coarse mesh)

I_ENTRY, I_INWARD, I_NORMAL, I_LENGTH = (0.0, -30.0, 75.0), (0.0, 0.0, -1.0), (1.0, 0.0, 0.0), 60.0
# Two 0.5 mm blades go down the inter-hemispheric gap at y = -30 mm side by
# side, the tips 25 mm below the top of the brain (z = 75 -> 50 mm), then
# spread I_SPREAD mm apart each, retracting the two hemispheres (until 3 s);
# the rough one spreads I_ROUGH mm each by I_ROUGH_END s.
I_SPREAD, I_ROUGH, I_ROUGH_END = 5.0, 15.0, 1.8
# Bridging veins: (hemisphere: -1 left, +1 right; y where the vein leaves the cortex, mm; how far in front of
# that it enters the sinus, mm). Each runs on the convexity from 22 mm off the midline (10 mm behind) over
# 14 mm (5 mm behind; each of the two the highest point within 2.5 mm, a gyrus' crest rather than a sulcus'
# floor, as cortical veins run over the sulci) to where it leaves the cortex, the crest of the gyrus beside the
# midline (the highest point 6 to 9 mm off it), and crosses the subdural space medially to the sinus: an anchor
# on the midline BRIDGE_ABOVE mm above the highest point of the brain's top within 12 mm of the midline there.
# The two nearest the blades leave the cortex 1 mm behind them (y = -35 mm) and enter the sinus there; the
# others, further forward, enter it 6 mm in front of where they leave the cortex.
BRIDGING = ((-1, -35.0, 0.0), (-1, -21.0, 6.0), (-1, -9.0, 6.0), (1, -35.0, 0.0), (1, -19.0, 6.0), (1, -6.0, 6.0))
BRIDGE_ABOVE = 3.0


def top_profile(surf, side, y):
    """The top of the brain at `y` on one hemisphere: the first hits of rays down, 1 to 12 mm off the midline."""
    pts = [surf.first((side * (1.0 + 0.25 * k), y, 150.0), (0.0, 0.0, -1.0)) for k in range(45)]
    return [p for p in pts if p is not None]


def crest(surf, x, y, r=2.5):
    """The highest point of the brain's top within r mm of (x, y) (rays down every 0.5 mm)."""
    steps = np.arange(-r, r + 0.01, 0.5)
    pts = [surf.first((x + dx, y + dy, 150.0), (0.0, 0.0, -1.0)) for dx in steps for dy in steps]
    return max((p for p in pts if p is not None), key=lambda p: p[2])


def exit_point(surf, side, y):
    """Where a bridging vein leaves the cortex: the highest point of the top at `y`, 6 to 9 mm off the midline."""
    pts = [surf.first((side * (6.0 + 0.25 * k), y, 150.0), (0.0, 0.0, -1.0)) for k in range(13)]
    return max((p for p in pts if p is not None), key=lambda p: p[2])


def interhemispheric():
    surf = Surface(COARSE)
    vessels = []
    names = {-1: "left", 1: "right"}
    for side, y, forward in BRIDGING:
        p1 = crest(surf, side * 22.0, y - 10.0)
        p2 = crest(surf, side * 14.0, y - 5.0)
        leave = exit_point(surf, side, y)
        ya = y + forward
        z_top = max(p[2] for s in (-1, 1) for p in top_profile(surf, s, ya))
        anchor = (0.0, ya, round(z_top + BRIDGE_ABOVE, 1))
        assert surf.outside(anchor), f"anchor {anchor} inside the tissue"
        name = f"bridging vein, {names[side]}, y = {y:g} mm"
        vessels.append(vessel_line(name, "BridgingVein", 2.0, [("Surface", p1), ("Surface", p2), ("Surface", leave), ("Anchor", anchor)]))
    comment = (
        "Bridging veins, placed by scripts/place_tethers_real_brain.py from the mesh (each\n"
        "surface point a ray's first hit on the top of the brain): superior cerebral veins on the\n"
        "convexity, each running medially from 22 mm off the midline over the crests of the gyri\n"
        "to the crest beside the midline (6-9 mm off it), where it leaves the cortex and crosses\n"
        "the subdural space to the superior sagittal sinus (an anchor on the midline "
        f"{BRIDGE_ABOVE:g} mm above\n"
        "the brain's top). Three a hemisphere: one leaving the cortex 1 mm behind the blades\n"
        "(which span y = -34..-26 mm) and entering the sinus there, two further forward that enter\n"
        "it 6 mm in front of where they leave the cortex (running forwards, against the sinus'\n"
        "flow); none crosses the gap where the blades go in: the careful surgeon enters between\n"
        "them. The scene's trajectory (5 mm a blade) tears nothing;\n"
        "assets/trajectories/real_brain_interhemispheric_rough.csv (15 mm a blade in 0.8 s) tears\n"
        "bridging veins."
    )
    write_tethers("config/real_brain/interhemispheric_tethers.ron", comment, vessels, [])
    return 3 * len(BRIDGING), 0


def interhemispheric_rows(spread, spread_end):
    rows = []
    for k, side in ((0, -1.0), (1, 1.0)):
        for t, depth, off in ((0.0, -5.0, 0.4), (1.0, 25.0, 0.4), (spread_end, 25.0, 0.4 + spread), (4.0, 25.0, 0.4 + spread)):
            p, q = blade_pose(I_ENTRY, I_INWARD, I_NORMAL, I_LENGTH, depth, side * off)
            rows.append(row(t, k, p, q))
    return rows


def interhemispheric_trajectories():
    write("assets/trajectories/real_brain_interhemispheric.csv",
          "Real brain (fsaverage5, assets/brain): two 60 x 8 x 0.5 mm blades enter the\n"
          "inter-hemispheric gap at y = -30 mm (tips 25 mm deep at 1 s), then spread 5 mm each\n"
          "towards their hemisphere until 3 s and hold.", interhemispheric_rows(I_SPREAD, 3.0))
    write("assets/trajectories/real_brain_interhemispheric_rough.csv",
          "A rough retraction of the real brain's hemispheres (config/real_brain/interhemispheric_tethers.ron): the blades\n"
          f"go in as in real_brain_interhemispheric.csv, then spread {I_ROUGH:g} mm each, 1 -> {I_ROUGH_END:g} s, and hold\n"
          "(scripts/place_tethers_real_brain.py).", interhemispheric_rows(I_ROUGH, I_ROUGH_END))


if __name__ == "__main__":
    scenes = sys.argv[1:] or ["sylvian", "interhemispheric"]
    if "sylvian" in scenes:
        v, b = sylvian()
        print(f"config/real_brain/sylvian_tethers.ron: {v} vessel segments, {b} bands")
        sylvian_trajectories()
    if "interhemispheric" in scenes:
        v, b = interhemispheric()
        print(f"config/real_brain/interhemispheric_tethers.ron: {v} vessel segments, {b} bands")
        interhemispheric_trajectories()
