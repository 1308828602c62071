#!/usr/bin/env python3
"""Writes the long retractions of the real-brain Sylvian scene from its careful opening.

From assets/trajectories/real_brain_sylvian.csv (the blades go in, the bands are cut,
the blades spread until the last keyframe that moves them), two tracks that hold
the same exposure for ten minutes:
- assets/trajectories/real_brain_sylvian_hold.csv: held continuously for 600 s after
  the spread;
- assets/trajectories/real_brain_sylvian_intermittent.csv: held 300 s, released (the
  blades back to where the spread began) for 60 s, spread again as before and held
  another 300 s: the same 600 s of exposure with one minute's rest, as intermittent
  retraction is done.
Replay them with `--set duration_s=603.5` and `--set duration_s=668` (the end of each
track). Run from the repository root; the output is deterministic.
"""
import os

SOURCE = "assets/trajectories/real_brain_sylvian.csv"
HOLD_S, REST_S, RELEASE_S = 600.0, 60.0, 2.0


def read(path):
    """Comment lines, header, and per spatula its keyframes as (time, pose fields, cut)."""
    comments, header, keys = [], None, {}
    with open(path) as f:
        for line in f:
            line = line.rstrip("\n")
            if line.startswith("#"):
                comments.append(line[1:].strip())
            elif header is None:
                header = line
            elif line:
                cols = line.split(",")
                keys.setdefault(int(cols[1]), []).append((float(cols[0]), cols[2:9], cols[9] if len(cols) > 9 else "0"))
    return comments, header, keys


def last_motion(frames):
    """The last keyframe time at which the pose changes, and the keyframe before it (where that motion began)."""
    moving = [k for k in range(1, len(frames)) if frames[k][1] != frames[k - 1][1]]
    end = moving[-1]
    return frames[end], frames[end - 1]


def track(keys, schedule):
    """Every keyframe up to the end of the spread, then `schedule`: (time after the spread, 'spread' or 'start')."""
    rows = []
    spread_end = max(last_motion(frames)[0][0] for frames in keys.values())
    for k, frames in keys.items():
        (_, spread_pose, _), (start_t, start_pose, _) = last_motion(frames)
        for t, pose, cut in frames:
            if t <= spread_end:
                rows.append((t, k, pose, cut))
        for after, which in schedule:
            rows.append((spread_end + after, k, spread_pose if which == "spread" else start_pose, "0"))
    rows.sort(key=lambda r: (r[0], r[1]))
    return spread_end, [f"{t:.4f},{k}," + ",".join(pose) + f",{cut}" for t, k, pose, cut in rows]


def write(path, comment, header, rows):
    with open(path, "w") as f:
        f.write("".join(f"# {line}\n" for line in comment.splitlines()))
        f.write(header + "\n" + "\n".join(rows) + "\n")


comments, header, keys = read(SOURCE)
# Both blades spread the same span of time: the re-spread takes as long as the first.
spread_time = max(last_motion(frames)[0][0] - last_motion(frames)[1][0] for frames in keys.values())
end, rows = track(keys, [(HOLD_S, "spread")])
write("assets/trajectories/real_brain_sylvian_hold.csv",
      f"The real-brain Sylvian scene's careful opening ({os.path.basename(SOURCE)}), its spread then held\n"
      f"for {HOLD_S:g} s, to {end + HOLD_S:g} s (replay with --set duration_s={end + HOLD_S:g}).\n"
      "Written by scripts/make_hold_trajectories.py.", header, rows)
half = HOLD_S / 2
schedule = [
    (half, "spread"),
    (half + RELEASE_S, "start"),
    (half + RELEASE_S + REST_S, "start"),
    (half + RELEASE_S + REST_S + spread_time, "spread"),
    (half + RELEASE_S + REST_S + spread_time + half, "spread"),
]
end2, rows = track(keys, schedule)
write("assets/trajectories/real_brain_sylvian_intermittent.csv",
      f"The real-brain Sylvian scene's careful opening ({os.path.basename(SOURCE)}), held intermittently:\n"
      f"{half:g} s held, released over {RELEASE_S:g} s to where the spread began and rested {REST_S:g} s, spread again\n"
      f"over {spread_time:g} s and held {half:g} s more, to {end2 + schedule[-1][0]:g} s (replay with --set duration_s={end2 + schedule[-1][0]:g}).\n"
      "Written by scripts/make_hold_trajectories.py.", header, rows)
