"""What the Python module adds to the library's own time (issue 20, item 6), without a C++ twin:
each insert or submit reports its host wall time measured inside the library (ScanStats.wall_ms,
the whole call), so the module's overhead is the time Python sees minus that, per call.

    PYTHONPATH=build/python python3 python/overhead.py [--repeat 5]

Workloads: one 320x240 depth view (76,800 rays) inserted blocking, as a float32 (H, W) image
and as points (N, 3); 1,000 small scans (300 points) submitted back to back and flushed, with
the binding's cost per call bounded by an empty scan's submit. A batch of 100,000 lookups has no library-side
time to compare with: its row gives the call with new result arrays and with out= arrays.
Reports medians."""

import argparse
import statistics
import time

import numpy as np

import octovk


def view(rng):
    """A 320x240 depth view of a room: float32 metres, and its points in the camera frame."""
    h, w = 240, 320
    depth = (2.0 + 1.5 * rng.random((h, w))).astype(np.float32)
    fx = fy = np.float32(262.5)
    cx, cy = np.float32(159.5), np.float32(119.5)
    v, u = np.meshgrid(np.arange(h, dtype=np.float32), np.arange(w, dtype=np.float32),
                       indexing="ij")
    z = depth
    points = np.stack([((u - cx) * z) / fx, ((v - cy) * z) / fy, z], axis=-1).reshape(-1, 3)
    return depth, (float(fx), float(fy), float(cx), float(cy)), np.ascontiguousarray(points)


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeat", type=int, default=5)
    args = parser.parse_args()
    rng = np.random.default_rng(0)
    print(f"device: {octovk.default_context().device.name} "
          f"({octovk.default_context().device.driver})")
    rows = []

    depth, (fx, fy, cx, cy), points = view(rng)
    for name, call in (
            ("76,800-ray view, depth image", lambda m: m.insert_depth_image(
                depth, fx, fy, cx, cy, 1.0, max_range_m=5.0)),
            ("76,800-ray view, points", lambda m: m.insert_point_cloud(
                points, (0, 0, 0), max_range_m=5.0))):
        python_ms, library_ms = [], []
        for _ in range(args.repeat):
            m = octovk.Map(0.05)
            call(m)  # the first view grows the buffers; the measured one reuses them
            start = time.perf_counter()
            stats = call(m)
            python_ms.append(1e3 * (time.perf_counter() - start))
            library_ms.append(stats.wall_ms)
        rows.append((name, statistics.median(python_ms), statistics.median(library_ms)))

    small = [np.ascontiguousarray(rng.uniform(-3, 3, (300, 3)).astype(np.float32))
             for _ in range(1000)]
    # A submit's wall_ms leaves out results it takes on its way out (and runs of refused scans),
    # so here the binding's own cost per call is bounded from above by a call whose library work
    # is nil: an empty scan (validation and a ticket).
    total_ms, call_us = [], []
    empty = np.zeros((0, 3), np.float32)
    for _ in range(args.repeat):
        m = octovk.Map(0.05)
        for s in small[:20]:
            m.insert_point_cloud(s, (0, 0, 0))
        start = time.perf_counter()
        for s in small:
            m.submit_point_cloud(s, (0, 0, 0))
        m.flush()
        total_ms.append(1e3 * (time.perf_counter() - start))
        start = time.perf_counter()
        for _ in range(1000):
            m.submit_point_cloud(empty, (0, 0, 0))
        call_us.append(1e3 * (time.perf_counter() - start))  # us per call: ms total / 1000
        m.flush()
    total, per_call = statistics.median(total_ms), statistics.median(call_us)
    small_row = (total, per_call)

    m = octovk.Map(0.05)
    m.insert_depth_image(depth, fx, fy, cx, cy, 1.0, max_range_m=5.0)
    queries = np.ascontiguousarray(rng.uniform(-4, 4, (100000, 3)).astype(np.float32))
    outs = (np.empty(100000, np.uint8), np.empty(100000, np.float32), np.empty(100000, np.uint8))
    m.search(queries, out=outs)
    new_ms, out_ms = [], []
    for _ in range(args.repeat):
        start = time.perf_counter()
        m.search(queries)
        new_ms.append(1e3 * (time.perf_counter() - start))
        start = time.perf_counter()
        m.search(queries, out=outs)
        out_ms.append(1e3 * (time.perf_counter() - start))

    print("| workload | Python (ms) | library wall time (ms) | overhead |")
    print("| --- | ---: | ---: | ---: |")
    for name, p, lib in rows:
        print(f"| {name} | {p:.2f} | {lib:.2f} | {p - lib:.3f} ms ({100 * (p - lib) / lib:.2f} %) |")
    total, per_call = small_row
    print(f"| 1,000 submits of 300 points + flush | {total:.1f} | - | at most {per_call:.1f} us "
          f"per call ({100 * per_call / (total / 1000) / 1000:.2f} % of {total / 1000:.2f} ms "
          "per scan) |")
    print(f"| 100,000 lookups, new arrays / out= arrays | {statistics.median(new_ms):.2f} / "
          f"{statistics.median(out_ms):.2f} | - | - |")

if __name__ == "__main__":
    main()
