#!/usr/bin/env python3
"""Whole-process start-up of the README's default job against graph2tree, and what any Vulkan
program pays on the same machine before its first command (issue 18, item 6).

Runs, interleaved N times each (so that load drifts hit all alike), after one untimed run of each
(the "second run on" of the target: octovk's kept probe verdict, Mesa's shader cache):
  octovk      build/octovk integrate spherical_scan.graph -o X.bt --resolution RES
  graph2tree  graph2tree -i spherical_scan.graph -o X.bt -res RES
  devices     build/octovk devices (instance, device, the probe's kept verdict; no scan)
  floor       bench/vulkan_floor (compiled here with cc): dlopen of the driver, then
              vkCreateInstance, vkEnumeratePhysicalDevices, vkCreateDevice; no octovk
and prints min and median of each, the floor's steps, and the load average before and after.
It measures; it asserts nothing about time.

Usage: bench/startup.py [--resolution 0.05] [--runs 9] [--octovk build/octovk]
"""
import argparse
import os
import statistics
import subprocess
import sys
import tempfile
import time

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
GRAPH = "/usr/share/doc/liboctomap-dev/examples/data/spherical_scan.graph"


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--resolution", default="0.05")
    ap.add_argument("--runs", type=int, default=9)
    ap.add_argument("--octovk", default=os.path.join(ROOT, "build", "octovk"))
    a = ap.parse_args()
    tmp = tempfile.mkdtemp(prefix="octovk-startup-")
    floor = os.path.join(tmp, "vulkan_floor")
    subprocess.run(["cc", "-O2", "-o", floor, os.path.join(ROOT, "bench", "vulkan_floor.c"),
                    "-lvulkan", "-ldl"], check=True)
    cmds = {
        "octovk": [a.octovk, "integrate", GRAPH, "-o", os.path.join(tmp, "a.bt"),
                   "--resolution", a.resolution],
        "graph2tree": ["graph2tree", "-i", GRAPH, "-o", os.path.join(tmp, "b.bt"),
                       "-res", a.resolution],
        "devices": [a.octovk, "devices"],
        "floor": [floor],
    }
    times = {k: [] for k in cmds}
    steps = []
    load_before = open("/proc/loadavg").read().split()[:3]
    for c in cmds.values():
        subprocess.run(c, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL, check=True)
    for _ in range(a.runs):
        for k, c in cmds.items():
            start = time.perf_counter()
            out = subprocess.run(c, stdout=subprocess.PIPE, stderr=subprocess.DEVNULL, check=True)
            times[k].append(time.perf_counter() - start)
            if k == "floor":
                steps.append(out.stdout.decode().strip())
    load_after = open("/proc/loadavg").read().split()[:3]
    print(f"resolution {a.resolution} m, {a.runs} runs each, load {' '.join(load_before)} -> "
          f"{' '.join(load_after)}")
    for k, v in times.items():
        print(f"{k:10s} whole process: min {min(v) * 1e3:7.1f} ms, median "
              f"{statistics.median(v) * 1e3:7.1f} ms")
    print("floor steps (each run):")
    for s in steps:
        print("  " + s)
    return 0


if __name__ == "__main__":
    sys.exit(main())
