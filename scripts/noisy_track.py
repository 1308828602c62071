#!/usr/bin/env python3
"""Writes a trajectory as a jittery tracker would send it.

Samples INPUT (a fissure trajectory CSV) every 1/RATE s for each spatula,
positions linearly and rotations by slerp (as fissure samples a track), and
adds independent uniform noise of +-AMPLITUDE mm to each coordinate of each
pose: what an optical tracker streaming at 100 Hz sends for a hand that
follows the track. The noise comes from a seeded generator, so the same
arguments write the same bytes.

    python3 scripts/noisy_track.py assets/trajectories/paper_fig14_sylvian.csv \
        assets/trajectories/paper_fig14_sylvian_noisy.csv --amplitude-mm 0.5 --rate-hz 100 --seed 1
"""

import argparse
import math
import random


def read_track(path):
    comments, rows = [], {}
    with open(path) as f:
        for line in f:
            line = line.strip()
            if not line:
                continue
            if line.startswith("#"):
                comments.append(line)
                continue
            if line.startswith("time_s"):
                continue
            t, k, x, y, z, qw, qx, qy, qz = line.split(",")
            rows.setdefault(int(k), []).append((float(t), [float(x), float(y), float(z)], [float(qw), float(qx), float(qy), float(qz)]))
    for k in rows:
        rows[k].sort(key=lambda r: r[0])
    return comments, rows


def slerp(a, b, u):
    dot = sum(p * q for p, q in zip(a, b))
    if dot < 0.0:
        b, dot = [-q for q in b], -dot
    if dot > 0.9995:
        q = [p + (r - p) * u for p, r in zip(a, b)]
    else:
        theta = math.acos(max(-1.0, min(1.0, dot)))
        s = math.sin(theta)
        q = [p * math.sin((1 - u) * theta) / s + r * math.sin(u * theta) / s for p, r in zip(a, b)]
    n = math.sqrt(sum(c * c for c in q))
    return [c / n for c in q]


def sample(track, t):
    if t <= track[0][0]:
        return track[0][1], track[0][2]
    for (t0, p0, q0), (t1, p1, q1) in zip(track, track[1:]):
        if t <= t1:
            u = (t - t0) / (t1 - t0) if t1 > t0 else 1.0
            return [a + (b - a) * u for a, b in zip(p0, p1)], slerp(q0, q1, u)
    return track[-1][1], track[-1][2]


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("input")
    ap.add_argument("output")
    ap.add_argument("--amplitude-mm", type=float, default=0.5)
    ap.add_argument("--rate-hz", type=float, default=100.0)
    ap.add_argument("--seed", type=int, default=1)
    args = ap.parse_args()
    comments, rows = read_track(args.input)
    rng = random.Random(args.seed)
    end = max(track[-1][0] for track in rows.values())
    steps = int(round(end * args.rate_hz))
    out = [
        f"# {args.input} as a tracker would send it: sampled at {args.rate_hz:g} Hz, each coordinate",
        f"# jittered by uniform noise of +-{args.amplitude_mm:g} mm (scripts/noisy_track.py, seed {args.seed}).",
    ]
    out += comments
    out.append("time_s,spatula,x_mm,y_mm,z_mm,qw,qx,qy,qz")
    for k in sorted(rows):
        for i in range(steps + 1):
            t = i / args.rate_hz
            p, q = sample(rows[k], t)
            p = [c + rng.uniform(-args.amplitude_mm, args.amplitude_mm) for c in p]
            out.append(f"{t:.2f},{k},{p[0]:.4f},{p[1]:.4f},{p[2]:.4f},{q[0]:.9f},{q[1]:.9f},{q[2]:.9f},{q[3]:.9f}")
    with open(args.output, "w") as f:
        f.write("\n".join(out) + "\n")


if __name__ == "__main__":
    main()
