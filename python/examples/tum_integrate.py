"""Integrates a TUM RGB-D folder (depth.txt, groundtruth.txt, 16-bit PNG depth images) into an
octovk map with numpy, asks it a few questions, writes an OctoMap .bt file and saves a top-down
picture of the occupied cells (drawn with pycairo: axes, heights and a scale bar in metres).

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
    """The height of the highest occupied cell above each spot of a grid of pixel_m metres, NaN
    where there is none, and the grid's lower-left corner (x, y) in metres."""
    centers, sizes, _ = m.leaves_in_box((-1e3, -1e3, -1e3), (1e3, 1e3, 1e3), occupied_only=True)
    if len(centers) == 0:
        return np.full((1, 1), np.nan, np.float32), (0.0, 0.0)
    lo = (centers - sizes[:, None] / 2).min(axis=0)
    hi = (centers + sizes[:, None] / 2).max(axis=0)
    cols, rows = np.ceil((hi - lo)[:2] / pixel_m - 1e-6).astype(int)
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
    height[~np.isfinite(height)] = np.nan
    return height, (float(lo[0]), float(lo[1]))


# Colours of heights, low to high: blue, cyan, green, yellow, red.
HEIGHT_COLOURS = np.array([[48, 18, 160], [40, 150, 230], [60, 200, 90], [240, 210, 40],
                           [200, 30, 20]], np.float64) / 255


def height_colour(t):
    """RGB in [0, 1] for t in [0, 1] (an array), between the anchors above."""
    x = np.clip(t, 0, 1) * (len(HEIGHT_COLOURS) - 1)
    i = np.minimum(x.astype(int), len(HEIGHT_COLOURS) - 2)
    f = (x - i)[..., None]
    return HEIGHT_COLOURS[i] * (1 - f) + HEIGHT_COLOURS[i + 1] * f


def round_ticks(lo, hi, most):
    """Round values (1, 2 or 5 times a power of ten apart) from lo to hi, at most `most`."""
    if not hi > lo:
        return [lo], 1.0
    step = 10 ** np.floor(np.log10((hi - lo) / most))
    while True:
        for m in (1, 2, 5):
            ticks = np.arange(np.ceil(lo / (m * step) - 1e-6), np.floor(hi / (m * step) + 1e-6) + 1)
            if len(ticks) <= most:
                return list(ticks * m * step), m * step
        step *= 10


def label(value, step, unit=""):
    decimals = max(0, int(np.ceil(-np.log10(step) - 1e-9)))
    text = f"{value:.{decimals}f}"
    return (text if text.strip("-0.") else text.lstrip("-")) + (f" {unit}" if unit else "")


def draw_top_view(path, height, corner, pixel_m):
    """Writes the top view as a PNG that carries its numbers: axes in metres, a colour bar of the
    heights in metres and a scale bar, drawn with cairo (pycairo: Debian's python3-cairo)."""
    try:
        import cairo
    except ImportError:
        raise SystemExit("--picture needs pycairo: apt-get install python3-cairo (or pip install "
                         "pycairo)")
    rows, cols = height.shape
    cell = max(1, 560 // max(rows, cols))  # pixels per grid cell: the view about 560 px wide
    left, top, bar_w = 64, 28, 150
    width, full_height = left + cols * cell + bar_w, top + rows * cell + 84
    surface = cairo.ImageSurface(cairo.FORMAT_RGB24, width, full_height)
    ink = cairo.Context(surface)
    ink.set_source_rgb(0.09, 0.10, 0.12)
    ink.paint()

    seen = np.isfinite(height)
    z_lo, z_hi = (float(height[seen].min()), float(height[seen].max())) if seen.any() else (0, 1)
    span = max(z_hi - z_lo, 1e-6)
    rgb = np.full((rows, cols, 3), 0.22)  # no occupied cell: dark grey
    rgb[seen] = height_colour((height[seen] - z_lo) / span)
    view = np.repeat(np.repeat((rgb * 255).astype(np.uint32), cell, 0), cell, 1)
    pixels = np.ndarray((full_height, surface.get_stride() // 4), np.uint32,
                        surface.get_data())
    surface.flush()
    pixels[top:top + rows * cell, left:left + cols * cell] = (
        view[..., 0] << 16 | view[..., 1] << 8 | view[..., 2])
    surface.mark_dirty()

    def text(words, x, y, align=0.0, size=12):
        ink.set_font_size(size)
        extents = ink.text_extents(words)
        ink.move_to(x - align * extents.x_advance, y + size * 0.35)
        ink.set_source_rgb(0.92, 0.92, 0.94)
        ink.show_text(words)

    def line(x0, y0, x1, y1):
        ink.set_source_rgb(0.92, 0.92, 0.94)
        ink.set_line_width(1)
        ink.move_to(x0, y0)
        ink.line_to(x1, y1)
        ink.stroke()

    # Axes in metres: x along the bottom, y (north up) on the left.
    bottom, right = top + rows * cell, left + cols * cell
    ticks, step = round_ticks(corner[0], corner[0] + cols * pixel_m, max(3, cols * cell // 70))
    for x in ticks:
        px = left + (x - corner[0]) / pixel_m * cell
        line(px, bottom, px, bottom + 5)
        text(label(x, step), px, bottom + 14, 0.5)
    text("x (m)", left + cols * cell / 2, bottom + 32, 0.5)
    ticks, step = round_ticks(corner[1], corner[1] + rows * pixel_m, max(3, rows * cell // 40))
    for y in ticks:
        py = bottom - (y - corner[1]) / pixel_m * cell
        line(left - 5, py, left, py)
        text(label(y, step), left - 8, py, 1.0)
    text("y (m)", left - 8, top - 14, 1.0)
    text("highest occupied cell, seen from above", left, top - 14)

    # The colour bar: the height of the highest occupied cell, in metres.
    bar_x, bar_top, bar_bottom = right + 24, top + 20, bottom
    text("height", bar_x, top + 4)
    steps = max(2, int(bar_bottom - bar_top))
    for i in range(steps):
        r, g, b = height_colour(np.array(1 - (i + 0.5) / steps))
        ink.set_source_rgb(r, g, b)
        ink.rectangle(bar_x, bar_top + i * (bar_bottom - bar_top) / steps, 16,
                      (bar_bottom - bar_top) / steps + 0.5)
        ink.fill()
    ticks, step = round_ticks(z_lo, z_hi, max(2, int((bar_bottom - bar_top) // 30)))
    for z in ticks:
        py = bar_bottom - (z - z_lo) / span * (bar_bottom - bar_top)
        line(bar_x + 16, py, bar_x + 21, py)
        text(label(z, step, "m"), bar_x + 25, py)

    # The scale bar: a round length of at most a third of the view.
    metres = round_ticks(0, cols * pixel_m / 3, 2)[1]
    length = metres / pixel_m * cell
    y = bottom + 58
    ink.set_source_rgb(0.92, 0.92, 0.94)
    ink.rectangle(left, y - 3, length, 6)
    ink.fill()
    text(label(metres, metres, "m"), left + length + 8, y)
    surface.write_to_png(str(path))
    return width, full_height, z_lo, z_hi


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("dir")
    parser.add_argument("-o", "--output", required=True, help=".bt or .ot file to write")
    parser.add_argument("--resolution", type=float, default=0.05)
    parser.add_argument("--max-range", type=float, default=-1.0)
    parser.add_argument("--intrinsics", type=float, nargs=4, default=(525.0, 525.0, 319.5, 239.5),
                        metavar=("FX", "FY", "CX", "CY"))
    parser.add_argument("--depth-scale", type=float, default=5000.0)
    parser.add_argument("--picture", help="a top-down PNG of the occupied cells, coloured by "
                        "height, with axes, a height colour bar and a scale bar in metres "
                        "(needs pycairo)")
    args = parser.parse_args()

    frames = octovk.read_tum_sequence(args.dir)
    m = octovk.Map(args.resolution)
    print(f"device: {m.context.device.name}; {len(frames)} images with a pose")
    for timestamp, image_path, T_world_camera in frames:
        depth = octovk.read_depth_png(image_path)  # uint16 (H, W), handed over in place
        m.submit_depth_image(depth, *args.intrinsics, args.depth_scale, T_world_camera,
                             max_range_m=args.max_range)
    m.flush()
    print(f"map: {m.node_count()} nodes, {m.leaf_count()} leaves, "
          f"{m.device_bytes() / 2**20:.1f} MiB on the device")

    # Questions: what lies at each camera position, and what each camera sees straight ahead.
    cameras = np.array([pose.translation for _, _, pose in frames], np.float32)
    state, _, _ = m.search(cameras)
    ahead = np.array([pose.transform((0, 0, 1)) - pose.translation for _, _, pose in frames],
                     np.float32)
    hit, end = m.cast_rays(cameras, ahead, max_range_m=10.0)
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
        height, corner = top_view(m, args.resolution)
        width, tall, z_lo, z_hi = draw_top_view(args.picture, height, corner, args.resolution)
        print(f"wrote {args.picture}: {width}x{tall} px, the occupied cells from above, "
              f"heights {z_lo:.2f} to {z_hi:.2f} m")


if __name__ == "__main__":
    main()
