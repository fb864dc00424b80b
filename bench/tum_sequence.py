#!/usr/bin/env python3
"""Writes a synthetic sequence in the TUM RGB-D layout (depth.txt, groundtruth.txt, 16-bit PNG
depth images, depth scale 5000, the default 525/525/319.5/239.5 camera) for measuring
`octovk integrate DIR` against graph2tree on the graph `octovk convert DIR` writes.

The camera moves along a 6 m corridor-like box room (x: 0..6 m, y: -1.5..1.5 m, z: -1..1.5 m in
the camera's world), looking down +x with a slow yaw; each pixel's depth is the distance along
the optical axis to the first wall it sees. Deterministic (no randomness); pure Python.

Usage: bench/tum_sequence.py DIR [FRAMES] [WIDTH HEIGHT]   (default 40 frames, 640x480)
"""
import math
import os
import struct
import sys
import zlib


def png16(path, width, height, rows):
    def chunk(kind, data):
        body = kind + data
        return struct.pack(">I", len(data)) + body + struct.pack(">I", zlib.crc32(body) & 0xFFFFFFFF)

    raw = b"".join(b"\x00" + struct.pack(">%dH" % width, *row) for row in rows)
    ihdr = struct.pack(">IIBBBBB", width, height, 16, 0, 0, 0, 0)
    with open(path, "wb") as f:
        f.write(b"\x89PNG\r\n\x1a\n" + chunk(b"IHDR", ihdr) + chunk(b"IDAT", zlib.compress(raw, 6))
                + chunk(b"IEND", b""))


def main():
    out = sys.argv[1]
    frames = int(sys.argv[2]) if len(sys.argv) > 2 else 40
    width = int(sys.argv[3]) if len(sys.argv) > 3 else 640
    height = int(sys.argv[4]) if len(sys.argv) > 4 else 480
    fx = fy = 525.0 * width / 640.0
    cx, cy = (width - 1) / 2.0, (height - 1) / 2.0
    os.makedirs(os.path.join(out, "depth"), exist_ok=True)
    room = ((-0.5, 6.0), (-1.5, 1.5), (-1.0, 1.5))  # x, y, z bounds of the box
    depth_lines, pose_lines = [], []
    for i in range(frames):
        t = 1.0 + i / 30.0
        px, py, pz = 0.02 * i, 0.3 * math.sin(i / 15.0), 0.1
        yaw = 0.25 * math.sin(i / 10.0)
        # Camera frame (x right, y down, z forward) -> world (x forward, y left, z up), then yaw.
        cyaw, syaw = math.cos(yaw), math.sin(yaw)
        rows = []
        for v in range(height):
            row = []
            for u in range(width):
                dx, dy, dz = (u - cx) / fx, (v - cy) / fy, 1.0  # camera ray with z = 1
                wx, wy, wz = dz, -dx, -dy
                wx, wy = cyaw * wx - syaw * wy, syaw * wx + cyaw * wy
                s = math.inf
                for axis, (lo, hi) in enumerate(room):
                    d = (wx, wy, wz)[axis]
                    p = (px, py, pz)[axis]
                    if d > 1e-9:
                        s = min(s, (hi - p) / d)
                    elif d < -1e-9:
                        s = min(s, (lo - p) / d)
                depth = int(round(s * 5000.0)) if s < 13.0 else 0
                if (u * 7 + v * 13 + i) % 97 == 0:
                    depth = 0  # sensor dropouts
                row.append(min(depth, 65535))
            rows.append(row)
        name = "depth/%.6f.png" % t
        png16(os.path.join(out, name), width, height, rows)
        depth_lines.append("%.6f %s" % (t, name))
        # groundtruth: camera pose in the world as tx ty tz qx qy qz qw (camera-frame axes).
        # R = Rz(yaw) * C, C maps camera axes to world (x_w = z_c, y_w = -x_c, z_w = -y_c).
        c = [[0, 0, 1], [-1, 0, 0], [0, -1, 0]]
        rz = [[cyaw, -syaw, 0], [syaw, cyaw, 0], [0, 0, 1]]
        r = [[sum(rz[a][k] * c[k][b] for k in range(3)) for b in range(3)] for a in range(3)]
        tr = r[0][0] + r[1][1] + r[2][2]
        qw = math.sqrt(max(0.0, 1 + tr)) / 2
        qx = math.copysign(math.sqrt(max(0.0, 1 + r[0][0] - r[1][1] - r[2][2])) / 2, r[2][1] - r[1][2])
        qy = math.copysign(math.sqrt(max(0.0, 1 - r[0][0] + r[1][1] - r[2][2])) / 2, r[0][2] - r[2][0])
        qz = math.copysign(math.sqrt(max(0.0, 1 - r[0][0] - r[1][1] + r[2][2])) / 2, r[1][0] - r[0][1])
        pose_lines.append("%.6f %.6f %.6f %.6f %.6f %.6f %.6f %.6f" % (t, px, py, pz, qx, qy, qz, qw))
    with open(os.path.join(out, "depth.txt"), "w") as f:
        f.write("# synthetic depth images (bench/tum_sequence.py)\n" + "\n".join(depth_lines) + "\n")
    with open(os.path.join(out, "groundtruth.txt"), "w") as f:
        f.write("# timestamp tx ty tz qx qy qz qw\n" + "\n".join(pose_lines) + "\n")


if __name__ == "__main__":
    main()
