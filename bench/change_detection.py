#!/usr/bin/env python3
"""What change detection costs per scan (issue 19): the same scan graph integrated with change
detection off and on, scan by scan (blocking inserts, so each scan's time is its own), the median
and total per mode, several alternating rounds. Usage (from the build tree's module):
  PYTHONPATH=build/python python3 bench/change_detection.py GRAPH RESOLUTION [ROUNDS]"""
import statistics
import sys
import time

import octovk


def run(scans, resolution, detect):
    m = octovk.Map(resolution)
    m.enable_change_detection(detect)
    times = []
    for points, pose in scans:
        origin = octovk.graph2tree_sensor_origin(pose)
        t0 = time.perf_counter()
        m.insert_point_cloud(points, origin, pose=pose)
        times.append(time.perf_counter() - t0)
    return times, (m.num_changes_detected() if detect else 0), m.device_bytes_by_use().changes


def main():
    graph, resolution = sys.argv[1], float(sys.argv[2])
    rounds = int(sys.argv[3]) if len(sys.argv) > 3 else 3
    scans = octovk.read_scan_graph(graph)
    run(scans[:2], resolution, True)  # pipelines built once, outside the figures
    results = {False: [], True: []}
    for _ in range(rounds):
        for detect in (False, True):
            results[detect].append(run(scans, resolution, detect))
    for detect in (False, True):
        per_scan = [t for times, _, _ in results[detect] for t in times]
        totals = [sum(times) for times, _, _ in results[detect]]
        _, changes, nbytes = results[detect][-1]
        print(f"change detection {'on ' if detect else 'off'}: {len(scans)} scans, "
              f"median {statistics.median(per_scan) * 1e3:.2f} ms/scan, total min "
              f"{min(totals):.3f} s median {statistics.median(totals):.3f} s; "
              f"{changes} changed keys, change set {nbytes} bytes")


if __name__ == "__main__":
    main()
