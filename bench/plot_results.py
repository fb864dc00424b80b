#!/usr/bin/env python3
"""Draws octovk_bench's results (its --json file) as one PNG with gnuplot (Debian: gnuplot-nox).

    bench/plot_results.py RESULTS.json OUT.png [MORE.json ...]

Panels, each only when the JSON has the workload:
  scaling with rays per scan, scaling with maximum range (both systems, log-log / lin-log),
  FR-079 time per scan against map size, and octovk's device time per stage on the paper views.
FR-079 runs of MORE.json files (e.g. a --lazy-leaf-boxes run) are added to the FR-079 panel.
Python (standard library only) writes the data and the gnuplot script; gnuplot draws.
"""
import json
import os
import shutil
import subprocess
import sys
import tempfile


def write(path, rows):
    with open(path, "w") as f:
        for row in rows:
            f.write(" ".join(str(v) for v in row) + "\n")


def scan_row(x, s):
    dev = s["octovk_device"]["total_ms"]
    return [x, s["octomap_insert_ms"], s.get("octomap_compute_update_ms", "NaN"),
            s["octovk_wall_ms"], dev]


SCAN_SERIES = (
    "'{f}' u 1:2 w lp pt 7 lc rgb '#c0392b' t 'OctoMap insertPointCloud', "
    "'{f}' u 1:3 w lp pt 6 lc rgb '#e67e22' dt 2 t 'OctoMap computeUpdate', "
    "'{f}' u 1:4 w lp pt 5 lc rgb '#2471a3' t 'octovk wall', "
    "'{f}' u 1:5 w lp pt 4 lc rgb '#5dade2' dt 2 t 'octovk device total'")


def main():
    if len(sys.argv) < 3:
        sys.exit("usage: plot_results.py RESULTS.json OUT.png [MORE.json ...]")
    src, out, more = sys.argv[1], sys.argv[2], sys.argv[3:]
    if shutil.which("gnuplot") is None:
        sys.exit("plot_results: gnuplot not found; install the Debian package gnuplot-nox")
    with open(src) as f:
        d = json.load(f)
    tmp = tempfile.mkdtemp(prefix="octovk_plot_")
    device = d["device"]["name"]
    panels = []

    if "scaling" in d:
        sc = d["scaling"]
        res = sc["resolution"]
        f = os.path.join(tmp, "rays.dat")
        write(f, [scan_row(p["scan"]["rays"], p["scan"]) for p in sc["rays"]["points"]])
        panels.append(
            f"set title 'Scaling with rays per scan ({res:g} m, one scan, fresh map)'\n"
            "set logscale xy\nset xrange [5000:2e6]\nset xlabel 'rays per scan'\n"
            "set ylabel 'ms per scan'\n"
            "set key top left\n"
            "plot " + SCAN_SERIES.format(f=f) + "\nunset logscale\nset xrange [*:*]\n")
        f = os.path.join(tmp, "range.dat")
        write(f, [scan_row(p["max_range_m"], p["scan"]) for p in sc["max_range"]["points"]])
        panels.append(
            f"set title 'Scaling with maximum range ({res:g} m, 76,800 rays down the corridor)'\n"
            "set logscale y\nset xlabel 'maximum range, m'\nset ylabel 'ms per scan'\n"
            "set key bottom right\n"
            "plot " + SCAN_SERIES.format(f=f) + "\nunset logscale\n")

    def leaf_label(fr079):
        every = fr079.get("leaf_boxes_every_scan", True)
        return ", leaf boxes every scan" if every else ", leaf boxes on demand"

    # (FR-079 results, label suffix, whether to draw OctoMap's line too: once, from the main run)
    fr079_sets = [(d["fr079"], leaf_label(d["fr079"]), True)] if "fr079" in d else []
    for path in more:
        with open(path) as f:
            extra = json.load(f)
        if "fr079" in extra:
            fr079_sets.append((extra["fr079"], leaf_label(extra["fr079"]), not fr079_sets))
    if fr079_sets:
        plots = []
        window = 100
        runs = [(run, suffix, main) for fr079, suffix, main in fr079_sets for run in fr079["runs"]]
        for k, (run, suffix, main) in enumerate(runs, start=1):
            cols = run["columns"]
            i_om, i_vk = cols.index("octomap_insert_ms"), cols.index("octovk_wall_ms")
            i_nodes = cols.index("octovk_nodes")
            rows = run["per_scan"]
            data = []
            for start in range(0, len(rows) - window + 1, window):
                w = rows[start:start + window]
                data.append([w[-1][i_nodes], sum(r[i_om] for r in w) / window,
                             sum(r[i_vk] for r in w) / window])
            f = os.path.join(tmp, f"fr079_{k}.dat")
            write(f, data)
            r = run["resolution"]
            dash = 1 if r >= 0.1 else 2
            if main:
                plots.append(f"'{f}' u 1:2 w l lw 2 lc rgb '#c0392b' dt {dash} "
                             f"t 'OctoMap insertPointCloud, {r:g} m'")
            colour = "#2471a3" if main else "#5dade2"
            plots.append(f"'{f}' u 1:3 w l lw 2 lc rgb '{colour}' dt {dash} "
                         f"t 'octovk wall, {r:g} m{suffix}'")
        panels.append(
            f"set title 'FR-079: time per scan against map size (means of {window} scans)'\n"
            "set logscale y\nset yrange [0.1:5000]\nset xlabel 'nodes in the map'\n"
            "set ylabel 'ms per scan'\nset key top left maxrows 6 font ',9'\n"
            "plot " + ", ".join(plots) + "\nunset logscale\nset yrange [*:*]\n"
            "set key default\n")

    if "paper" in d:
        names = ["upload_ms", "ray_keys_ms", "classify_ms", "tree_update_ms", "prune_ms",
                 "leaf_boxes_ms"]
        titles = ["upload", "ray walk + hash set", "classify / early abort", "tree update",
                  "prune", "leaf-box rebuild"]
        rows = []
        for run in d["paper"]["runs"]:
            m = run["mean_per_view"]
            dev = m["octovk_device"]
            rows.append([f"{run['resolution']:g}m"] + [dev[n] for n in names] +
                        [m["octomap_insert_ms"], m["octovk_wall_ms"]])
        f = os.path.join(tmp, "stages.dat")
        write(f, rows)
        titles += ["OctoMap insertPointCloud", "octovk wall"]
        series = ", ".join(
            f"'{f}' u {i + 2}{':xtic(1)' if i == 0 else ''} t '{t}'" for i, t in enumerate(titles))
        panels.append(
            "set title 'Paper views: octovk device time per stage, and both totals (mean per view)'\n"
            "set style data histograms\nset style histogram clustered gap 1\n"
            "set style fill solid 0.8 border -1\nset logscale y\n"
            "set xlabel 'resolution'\nset ylabel 'ms per view'\nset key top left\n"
            f"plot {series}\n"
            "unset logscale\nset style data lines\n")

    if not panels:
        sys.exit("plot_results: the JSON holds no workload to plot")
    cols = 2 if len(panels) > 1 else 1
    rows = (len(panels) + cols - 1) // cols
    script = (
        f"set terminal pngcairo size {700 * cols},{520 * rows} font 'DejaVu Sans,10'\n"
        f"set output '{out}'\n"
        "set grid\n"
        f"set multiplot layout {rows},{cols} title 'octovk vs OctoMap on {device} "
        f"({d['date']})'\n" + "".join(panels) + "unset multiplot\n")
    gp = os.path.join(tmp, "plot.gp")
    with open(gp, "w") as f:
        f.write(script)
    subprocess.run(["gnuplot", gp], check=True)
    shutil.rmtree(tmp)
    print(f"plot_results: wrote {out}")


if __name__ == "__main__":
    main()
