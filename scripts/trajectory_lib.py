"""Functions shared by the scripts that write trajectories and place tethers.

scripts/make_trajectories.py, scripts/place_tethers.py and
scripts/place_tethers_real_brain.py import it (Python puts a script's own
folder on its path, so `python3 scripts/x.py` from the repository root finds it). Vectors are tuples of
floats, quaternions (w, x, y, z). The trajectory format is the one
src/scenario/trajectory.rs reads: time_s,spatula,x_mm,y_mm,z_mm,qw,qx,qy,qz
and an optional tenth column, cut.
"""
import math


def add(a, b, s=1.0):
    """a + s b."""
    return tuple(ai + s * bi for ai, bi in zip(a, b))


def cross(a, b):
    return (a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0])


def unit(a):
    n = math.sqrt(sum(c * c for c in a))
    return tuple(c / n for c in a)


def quat_from_axes(x, y, z):
    """The unit quaternion (w, x, y, z) of the rotation whose matrix has columns x, y, z."""
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


def blade_pose(entry, inward, normal, length, tip_depth, offset):
    """Origin (handle end) such that the tip is `tip_depth` mm past `entry` along
    `inward`, shifted `offset` mm along `normal`; blade x = inward, face z = normal."""
    origin = add(add(entry, inward, tip_depth - length), normal, offset)
    q = quat_from_axes(inward, cross(normal, inward), normal)
    return origin, q


def row(t, k, p, q, cut=None, time_digits=2):
    """One trajectory row: time, spatula index, position (mm), quaternion, and the cut column when `cut` is given."""
    text = f"{t:.{time_digits}f},{k},{p[0]:.4f},{p[1]:.4f},{p[2]:.4f},{q[0]:.9f},{q[1]:.9f},{q[2]:.9f},{q[3]:.9f}"
    return text if cut is None else f"{text},{cut}"


def write(path, comment, rows, cut=False):
    """Writes a trajectory: `comment` as '#' lines, the header (with the cut column when `cut`), the rows."""
    with open(path, "w") as f:
        f.write("".join(f"# {line}\n" for line in comment.splitlines()))
        f.write("time_s,spatula,x_mm,y_mm,z_mm,qw,qx,qy,qz" + (",cut" if cut else "") + "\n")
        f.write("\n".join(rows) + "\n")
