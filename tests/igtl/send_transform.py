#!/usr/bin/env python3
"""Third-party OpenIGTLink client for tests/suite/input_igtl.rs.

Connects with pyigtl to the fissure server on 127.0.0.1:PORT, sends a few
TRANSFORM messages for two devices (header versions 1 and 2), then waits for
the server's force message (a SENSOR named Force_Left, read raw because
pyigtl has no SENSOR decoder) and prints its three values.

Exit codes: 0 ok, 3 pyigtl missing (the Rust test skips), 1 any failure.
"""
import socket
import struct
import sys
import time

try:
    import numpy as np
    import pyigtl
except ImportError as e:  # the Rust test skips on exit code 3
    print(f"pyigtl not importable: {e}", file=sys.stderr)
    sys.exit(3)


def rotation_z(angle):
    c, s = np.cos(angle), np.sin(angle)
    return np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])


def main():
    port = int(sys.argv[1])
    client = pyigtl.OpenIGTLinkClient(host="127.0.0.1", port=port, start_now=True)
    deadline = time.time() + 10
    while not client.is_connected() and time.time() < deadline:
        time.sleep(0.02)
    if not client.is_connected():
        print("could not connect", file=sys.stderr)
        return 1

    # Left: rotation 30 deg about z, translation (10, -20, 35.5) mm; sent twice (moving).
    for k, tx in enumerate([5.0, 10.0]):
        m = np.eye(4)
        m[:3, :3] = rotation_z(np.radians(30.0))
        m[:3, 3] = [tx, -20.0, 35.5]
        msg = pyigtl.TransformMessage(m, device_name="Left")
        client.send_message(msg, wait=True)
    # Right: header version 2 with metadata; rotation 90 deg about x.
    m = np.eye(4)
    m[:3, :3] = np.array([[1.0, 0.0, 0.0], [0.0, 0.0, -1.0], [0.0, 1.0, 0.0]])
    m[:3, 3] = [-7.25, 3.0, 120.0]
    msg = pyigtl.TransformMessage(m, device_name="Right")
    msg.header_version = 2
    msg.metadata = {"source": "pyigtl-test"}
    client.send_message(msg, wait=True)
    client.stop()

    # Read the server's force messages on a raw socket of our own.
    sock = socket.create_connection(("127.0.0.1", port), timeout=10)
    sock.sendall(pyigtl.TransformMessage(np.eye(4), device_name="Probe").pack())
    data = b""
    while len(data) < 58 + 34:
        chunk = sock.recv(4096)
        if not chunk:
            print("server closed before sending a force", file=sys.stderr)
            return 1
        data += chunk
    mtype = data[2:14].rstrip(b"\0").decode()
    device = data[14:34].rstrip(b"\0").decode()
    larray, status, unit = struct.unpack(">BBQ", data[58:68])
    values = struct.unpack(">3d", data[68:92])
    print(f"FORCE {mtype} {device} {larray} {unit:#018x} {values[0]} {values[1]} {values[2]}")
    sock.close()
    return 0


if __name__ == "__main__":
    sys.exit(main())
