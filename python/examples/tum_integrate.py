"""Integrates a TUM RGB-D folder (depth.txt, groundtruth.txt, 16-bit PNG depth images) into an
octovk map with numpy, asks it a few questions, writes an OctoMap .bt file and saves a top-down
picture of the occupied cells.

    PYTHONPATH=build/python python3 python/examples/tum_integrate.py DIR -o map.bt \\
        [--resolution 0.05] [--max-range 4] [--picture top.png]

The .bt is byte for byte what `build/octovk integrate DIR -o map.bt` writes with the same
options (python/tests/test_example.py checks it)."""

import argparse
import struct
import zlib

import numpy as np

import octovk


def write_png(path, image):
    """A grayscale PNG of a uint8 or uint16 array (H, W), without other libraries."""
    image = np.ascontiguousarray(image)
    depth = {np.dtype(np.uint8): 8, np.dtype(np.uint16): 16}[image.dtype]
    rows = image.astype(image.dtype.newbyteorder(">"))  # PNG samples are big-endian
    raw = b"".join(b"\0" + rows[v].tobytes() for v in range(rows.shape[0]))

    def chunk(kind, data):
        return (struct.pack(">I", len(data)) + kind + data +
                struct.pack(">I", zlib.crc32(kind + data) & 0xFFFFFFFF))

    header = struct.pack(">IIBBBBB", image.shape[1], image.shape[0], depth, 0, 0, 0, 0)
    with open(path, "wb") as f:
        f.write(b"\x89PNG\r\n\x1a\n" + chunk(b"IHDR", header) +
                chunk(b"IDAT", zlib.compress(raw)) + chunk(b"IEND", b""))


def top_view(m, pixel_m):
    """The highest occupied cell above each spot, from black (lowest) to white (highest)."""
    centers, sizes, _ = m.leaves_in_box((-1e3, -1e3, -1e3), (1e3, 1e3, 1e3), occupied_only=True)
    if len(centers) == 0:
        return np.zeros((1, 1), np.uint8)
    lo = (centers - sizes[:, None] / 2).min(axis=0)
    hi = (centers + sizes[:, None] / 2).max(axis=0)
    cols, rows = np.ceil((hi - lo)[:2] / pixel_m).astype(int) + 1
    height = np.full((rows, cols), -np.inf, np.float32)
    for size in np.unique(sizes):  # each leaf covers its whole footprint
        at = sizes == size
        k = max(1, int(round(size / pixel_m)))
        corner = centers[at, :2] - size / 2
        du, dv = np.meshgrid(np.arange(k), np.arange(k))
        u = (np.round((corner[:, 0] - lo[0]) / pixel_m).astype(int)[:, None] + du.ravel())
        v = rows - 1 - (np.round((corner[:, 1] - lo[1]) / pixel_m).astype(int)[:, None]
                        + dv.ravel())  # north up
        z = np.repeat(centers[at, 2], k * k).reshape(u.shape)
        np.maximum.at(height, (v.ravel(), u.ravel()), z.ravel())
    seen = np.isfinite(height)
    z_lo, z_hi = float(height[seen].min()), float(height[seen].max())
    picture = np.zeros(height.shape, np.uint8)
    picture[seen] = (40 + 215 * (height[seen] - z_lo) / max(z_hi - z_lo, 1e-6)).astype(np.uint8)
    return picture


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("dir")
    parser.add_argument("-o", "--output", required=True, help=".bt or .ot file to write")
    parser.add_argument("--resolution", type=float, default=0.05)
    parser.add_argument("--max-range", type=float, default=-1.0)
    parser.add_argument("--intrinsics", type=float, nargs=4, default=(525.0, 525.0, 319.5, 239.5),
                        metavar=("FX", "FY", "CX", "CY"))
    parser.add_argument("--depth-scale", type=float, default=5000.0)
    parser.add_argument("--picture", help="a top-down PNG of the occupied cells (one pixel per "
                        "finest cell, brighter is higher)")
    args = parser.parse_args()

    frames = octovk.read_tum_sequence(args.dir)
    m = octovk.Map(args.resolution)
    print(f"device: {m.context.device.name}; {len(frames)} images with a pose")
    for timestamp, image_path, T_world_camera in frames:
        depth = octovk.read_depth_png(image_path)  # uint16 (H, W), handed over in place
        m.submit_depth_image(depth, *args.intrinsics, args.depth_scale, T_world_camera,
                             max_range=args.max_range)
    m.flush()
    print(f"map: {m.node_count()} nodes, {m.leaf_count()} leaves, "
          f"{m.device_bytes().total / 2**20:.1f} MiB on the device")

    # Questions: what lies at each camera position, and what each camera sees straight ahead.
    cameras = np.array([pose.translation for _, _, pose in frames], np.float32)
    state, _, _ = m.search(cameras)
    ahead = np.array([pose.transform((0, 0, 1)) - pose.translation for _, _, pose in frames],
                     np.float32)
    hit, end = m.cast_rays(cameras, ahead, max_range=10.0)
    names = {int(s): s.name.lower() for s in (octovk.CellState.UNKNOWN, octovk.CellState.FREE,
                                              octovk.CellState.OCCUPIED)}
    print("camera cells: " + ", ".join(f"{n} {names[k]}" for k, n in
                                       zip(*np.unique(state, return_counts=True))))
    if hit.any():
        dist = np.linalg.norm(end[hit == 1] - cameras[hit == 1], axis=1)
        print(f"straight ahead: {int(hit.sum())} of {len(hit)} cameras see an occupied cell, "
              f"median {np.median(dist):.2f} m away")

    m.write(args.output)
    print(f"wrote {args.output}")
    if args.picture:
        write_png(args.picture, top_view(m, args.resolution))
        print(f"wrote {args.picture}")


if __name__ == "__main__":
    main()
