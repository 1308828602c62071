#!/usr/bin/env python3
"""Third-party OpenIGTLink client for tests/window/igtl.rs: streams one pose.

Usage: stream_pose.py PORT DEVICE X_MM Y_MM Z_MM SECONDS
Connects with pyigtl to 127.0.0.1:PORT (retrying while the window starts),
then sends a TRANSFORM (identity rotation, translation in millimetres) for
DEVICE at 50 Hz for SECONDS or until the server goes away.
Exit codes: 0 sent at least one message, 3 pyigtl missing, 1 never connected.
"""
import sys
import time

try:
    import numpy as np
    import pyigtl
except ImportError as e:
    print(f"pyigtl not importable: {e}", file=sys.stderr)
    sys.exit(3)


def main():
    port, device = int(sys.argv[1]), sys.argv[2]
    x, y, z, seconds = (float(v) for v in sys.argv[3:7])
    client = pyigtl.OpenIGTLinkClient(host="127.0.0.1", port=port, start_now=True)
    deadline = time.time() + 60
    while not client.is_connected() and time.time() < deadline:
        time.sleep(0.05)
    if not client.is_connected():
        print("could not connect", file=sys.stderr)
        return 1
    m = np.eye(4)
    m[:3, 3] = [x, y, z]
    sent = 0
    end = time.time() + seconds
    while time.time() < end and client.is_connected():
        client.send_message(pyigtl.TransformMessage(m, device_name=device), wait=True)
        sent += 1
        time.sleep(0.02)
    client.stop()
    print(f"sent {sent}")
    return 0 if sent > 0 else 1


if __name__ == "__main__":
    sys.exit(main())
