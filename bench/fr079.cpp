// The fr079 workload: 4,934 real 2D scans with odometry poses (FR-079), in sequence and
// streamed, with windows of the sequence compared.
#include <octomap/OcTree.h>

#include <algorithm>
#include <chrono>
#include <cstdio>
#include <memory>
#include <string>
#include <utility>
#include <vector>

#include "building.hpp"
#include "measure.hpp"
#include "octovk/octomap_io.hpp"
#include "workload_common.hpp"
#include "workloads.hpp"

namespace octovk::bench {

namespace {

struct Window {
  double om_ms_per_scan = 0, vk_ms_per_scan = 0;
  double om_us_per_point = 0, vk_us_per_point = 0;
  double vk_device_ms_per_scan = 0, vk_leaf_boxes_ms_per_scan = 0;
  std::size_t nodes_at_end = 0;
};

Window window(const std::vector<ScanTiming>& scans, std::size_t begin, std::size_t end) {
  Window w;
  double points = 0;
  for (std::size_t i = begin; i < end; ++i) {
    const ScanTiming& t = scans[i];
    points += static_cast<double>(t.rays);
    w.om_ms_per_scan += t.om_insert_ms;
    w.vk_ms_per_scan += t.vk.wall_ms;
    w.vk_device_ms_per_scan += t.vk.device.total_ms();
    w.vk_leaf_boxes_ms_per_scan += t.vk.device.leaf_boxes_ms;
  }
  w.om_us_per_point = w.om_ms_per_scan * 1e3 / points;
  w.vk_us_per_point = w.vk_ms_per_scan * 1e3 / points;
  const double n = static_cast<double>(end - begin);
  w.om_ms_per_scan /= n;
  w.vk_ms_per_scan /= n;
  w.vk_device_ms_per_scan /= n;
  w.vk_leaf_boxes_ms_per_scan /= n;
  w.nodes_at_end = scans[end - 1].vk.nodes;
  return w;
}

void writeJson(JsonWriter& json, const Window& w) {
  json.beginObject()
      .field("octomap_insert_ms_per_scan", w.om_ms_per_scan)
      .field("octovk_wall_ms_per_scan", w.vk_ms_per_scan)
      .field("octomap_insert_us_per_point", w.om_us_per_point)
      .field("octovk_wall_us_per_point", w.vk_us_per_point)
      .field("octovk_device_ms_per_scan", w.vk_device_ms_per_scan)
      .field("octovk_leaf_boxes_ms_per_scan", w.vk_leaf_boxes_ms_per_scan)
      .field("octovk_nodes_at_end", w.nodes_at_end)
      .endObject();
}

}  // namespace

namespace {

struct Stream {
  std::unique_ptr<OccupancyMap> map;
  double wall_s = 0, submit_ms = 0;
  double boxes_ms = 0, build_ms = 0, trace_ms = 0, device_ms = 0;  // sums over the scans
  std::uint64_t submissions = 0, waits = 0;
  std::size_t reruns = 0;
};

// Every scan of `graph` submitted back to back into a fresh map, then one flush: the wall time
// of the whole, the host's time in submit, and the map's submissions and host waits.
Stream streamGraph(Context& context, const BenchOptions& o, double res,
                   const std::vector<GraphScan>& graph, ScanRays rays = ScanRays::kWalk) {
  Stream s;
  s.map = std::make_unique<OccupancyMap>(makeMap(context, o, res, rays));
  const OccupancyMap::SyncCounts before = s.map->syncCounts();
  const auto start = Clock::now();
  auto take = [&] {
    for (const ScanStats& st : s.map->takeScanStats()) {
      s.submit_ms += st.wall_ms;
      s.reruns += st.cell_set_attempts > 1;
      s.boxes_ms += st.device.scan_boxes_ms;
      s.build_ms += st.device.scan_build_ms;
      s.trace_ms += st.device.scan_trace_ms;
      s.device_ms += st.device.total_ms();
    }
  };
  for (std::size_t i = 0; i < graph.size(); ++i) {
    const GraphScan& scan = graph[i];
    s.map->submitPointCloud(scan.points_sensor, graph2treeSensorOrigin(scan.T_world_sensor),
                            scan.T_world_sensor);
    if (i % 1024 == 1023) take();  // the map keeps the newest 4096
  }
  s.map->flush();
  s.wall_s = secondsSince(start);
  take();
  const OccupancyMap::SyncCounts after = s.map->syncCounts();
  s.submissions = after.submissions - before.submissions;
  s.waits = after.host_waits - before.host_waits;
  return s;
}

}  // namespace

void runFr079(Context& context, const BenchOptions& o, JsonWriter& json) {
  const std::vector<double> resolutions = resolutionsFor(o, {0.1, 0.05}, {0.1});
  const auto read_start = Clock::now();
  std::vector<GraphScan> graph = readScanGraph(o.fr079_path);
  const std::size_t limit = o.fr079_scans ? o.fr079_scans : (o.quick ? 600 : 0);
  if (limit && graph.size() > limit) graph.resize(limit);
  std::size_t total_points = 0;
  for (const GraphScan& s : graph) total_points += s.points_sensor.size();
  progress("fr079: read %zu scans in %.1f s\n", graph.size(), secondsSince(read_start));

  // First and last windows of 500 scans (a tenth of the run each when it is shorter).
  const std::size_t win = std::min<std::size_t>(500, std::max<std::size_t>(graph.size() / 10, 1));
  std::printf(
      "\n## fr079: FR-079 corridor, %zu real 2D scans, %zu points, graph2tree's placement\n",
      graph.size(), total_points);
  std::printf(
      "\nOne pass over the sequence per resolution, fresh maps. Max range: unlimited. "
      "Leaf boxes rebuilt every scan: %s. Flatness: the last %zu scans against the "
      "first %zu, per scan and per point.\n",
      o.leaf_boxes_every_scan ? "yes" : "no (on demand, the library default)", win, win);
  json.key("fr079").beginObject();
  json.field("file", o.fr079_path).field("scans", graph.size()).field("points", total_points);
  json.field("window", win).field("leaf_boxes_every_scan", o.leaf_boxes_every_scan);
  json.key("runs").beginArray();

  std::vector<std::string> labels;
  std::vector<ScanTiming> means;
  std::vector<MemoryReport> memories;
  std::vector<std::pair<Window, Window>> windows;
  for (double res : resolutions) {
    octomap::OcTree tree(res);
    OccupancyMap map = makeMap(context, o, res);
    std::vector<ScanTiming> scans;
    scans.reserve(graph.size());
    const auto start = Clock::now();
    double last_report = 0;
    for (std::size_t i = 0; i < graph.size(); ++i) {
      scans.push_back(measureGraphScan(tree, map, graph[i].points_sensor, graph[i].T_world_sensor,
                                       -1.0, o.compute_update));
      const double elapsed = secondsSince(start);
      if (elapsed - last_report > 10.0 || i + 1 == graph.size()) {
        last_report = elapsed;
        progress("fr079 %g m: scan %zu/%zu, %.0f s\n", res, i + 1, graph.size(), elapsed);
      }
    }
    const MemoryReport memory = memoryReport(tree, map);
    const ScanTiming mean = meanOf(scans);
    const Window first = window(scans, 0, win);
    const Window last = window(scans, graph.size() - win, graph.size());
    labels.push_back(fmt("%g m", res));
    means.push_back(mean);
    memories.push_back(memory);
    windows.emplace_back(first, last);

    double om_total = 0, om_cu_total = 0, vk_total = 0;
    for (const ScanTiming& t : scans) {
      om_total += t.om_insert_ms;
      om_cu_total += std::max(0.0, t.om_compute_update_ms);
      vk_total += t.vk.wall_ms;
    }
    int node_mismatches = 0;
    for (const ScanTiming& t : scans) node_mismatches += t.om_nodes != t.vk.nodes;

    json.beginObject().field("resolution", res);
    json.field("octomap_insert_total_s", om_total * 1e-3);
    json.field("octomap_compute_update_total_s", om_cu_total * 1e-3);
    json.field("octovk_wall_total_s", vk_total * 1e-3);
    json.field("scans_with_node_count_mismatch", node_mismatches);
    json.field("cell_set_mismatches", cellMismatches(scans));
    json.key("mean_per_scan");
    writeJson(json, mean);
    json.key("first_window");
    writeJson(json, first);
    json.key("last_window");
    writeJson(json, last);
    json.key("memory");
    writeJson(json, memory);
    // Per scan, as columns, to keep the file small.
    json.key("columns").beginArray();
    for (const char* c :
         {"points", "octomap_compute_update_ms", "octomap_insert_ms", "octovk_wall_ms", "upload_ms",
          "ray_keys_ms", "classify_ms", "tree_update_ms", "prune_ms", "leaf_boxes_ms",
          "octomap_nodes", "octovk_nodes"})
      json.value(c);
    json.endArray();
    json.key("per_scan").beginArray();
    for (const ScanTiming& t : scans) {
      const StageTimes& d = t.vk.device;
      json.newline().beginArray();
      json.value(t.rays).value(t.om_compute_update_ms).value(t.om_insert_ms).value(t.vk.wall_ms);
      json.value(d.upload_ms).value(d.ray_keys_ms).value(d.classify_ms).value(d.tree_update_ms);
      json.value(d.prune_ms).value(d.leaf_boxes_ms).value(t.om_nodes).value(t.vk.nodes);
      json.endArray();
    }
    json.endArray();

    std::printf(
        "\n### fr079, resolution %g m: %zu scans, OctoMap insertPointCloud %.2f s "
        "(computeUpdate alone %.2f s), octovk %.2f s: %.2fx\n",
        res, scans.size(), om_total * 1e-3, om_cu_total * 1e-3, vk_total * 1e-3,
        om_total / vk_total);
    std::printf(
        "\n%s at the end; per scan: node counts differ in %d of %zu scans, cell sets in "
        "%d.\n",
        parityLine(memory.om_nodes, memory.vk_nodes).c_str(), node_mismatches, scans.size(),
        cellMismatches(scans));

    // The same scans submitted back to back into a fresh map (OccupancyMap::submitPointCloud),
    // as `octovk integrate` does: no host wait per scan but for a free frame.
    const Stream stream = streamGraph(context, o, res, graph);
    const bool same = stream.map && *toOcTree(*stream.map) == tree;
    const double scan_count = static_cast<double>(graph.size());
    json.key("streamed").beginObject();
    json.field("wall_total_s", stream.wall_s).field("scans_per_s", scan_count / stream.wall_s);
    json.field("rays_per_s", static_cast<double>(total_points) / stream.wall_s);
    json.field("host_submit_ms_per_scan", stream.submit_ms / scan_count);
    json.field("submissions_per_scan", static_cast<double>(stream.submissions) / scan_count);
    json.field("host_waits_per_scan", static_cast<double>(stream.waits) / scan_count);
    json.field("scans_run_again", stream.reruns);
    json.field("equals_octomap", same);
    json.endObject();
    std::printf(
        "\nStreamed (submitted back to back, fresh map): %.2f s, %.0f scans/s, %.2f M rays/s; "
        "host %.3f ms per submit; %.2f submissions and %.2f host waits per scan; %zu scans run "
        "again; map %s OctoMap's. OctoMap insertPointCloud %.2f s: %.2fx.\n",
        stream.wall_s, scan_count / stream.wall_s,
        static_cast<double>(total_points) / stream.wall_s * 1e-6, stream.submit_ms / scan_count,
        static_cast<double>(stream.submissions) / scan_count,
        static_cast<double>(stream.waits) / scan_count, stream.reruns,
        same ? "equals" : "DIFFERS FROM", om_total * 1e-3, om_total * 1e-3 / stream.wall_s);
    for (const TracePath& path : tracePaths(context)) {
      // The same stream through ray tracing, on each path the device runs: per scan, the
      // structure (boxes and build) and the rays traced through it, in the scan's own submission.
      const Stream rt = streamGraph(context, o, res, graph, path.scan_rays);
      const bool rt_same = rt.map && *toOcTree(*rt.map) == tree;
      const double n = static_cast<double>(graph.size());
      // Ray queries keep the key they had before the pipeline.
      json.key(path.scan_rays == ScanRays::kRayQuery ? std::string("streamed_rt")
                                                     : "streamed_" + std::string(path.key))
          .beginObject();
      json.field("wall_total_s", rt.wall_s).field("scans_per_s", n / rt.wall_s);
      json.field("boxes_ms_per_scan", rt.boxes_ms / n).field("build_ms_per_scan", rt.build_ms / n);
      json.field("trace_ms_per_scan", rt.trace_ms / n);
      json.field("rest_ms_per_scan", (rt.device_ms - rt.boxes_ms - rt.build_ms - rt.trace_ms) / n);
      json.field("equals_octomap", rt_same);
      json.endObject();
      std::printf(
          "\nStreamed through ray tracing (%s, fresh map): %.2f s, %.0f scans/s; per scan "
          "%.2f ms boxes, %.2f ms structure build, %.2f ms ray shooting, %.2f ms the rest "
          "(device); map %s OctoMap's. Walk streamed: %.2f s; OctoMap insertPointCloud %.2f s.\n",
          path.label, rt.wall_s, n / rt.wall_s, rt.boxes_ms / n, rt.build_ms / n, rt.trace_ms / n,
          (rt.device_ms - rt.boxes_ms - rt.build_ms - rt.trace_ms) / n,
          rt_same ? "equals" : "DIFFERS FROM", stream.wall_s, om_total * 1e-3);
    }
    json.endObject();
  }
  json.endArray().endObject();

  std::printf("\n### fr079: mean per scan\n");
  printScanTable("resolution", labels, means);
  printStageTable("resolution (octovk device ms)", labels, means);
  std::vector<std::string> memory_labels;
  for (const std::string& l : labels) memory_labels.push_back("FR-079, " + l);
  printMemoryTable(memory_labels, memories);

  std::printf("\n### fr079: time per scan against map size (first %zu scans vs last %zu)\n", win,
              win);
  std::printf(
      "\n| resolution | system | first: ms/scan | last: ms/scan | last / first | "
      "first: us/point | last: us/point | last / first (per point) | nodes after first "
      "/ at end |\n| --- | --- | --: | --: | --: | --: | --: | --: | --: |\n");
  for (std::size_t i = 0; i < labels.size(); ++i) {
    const auto& [first, last] = windows[i];
    std::printf(
        "| %s | OctoMap insertPointCloud | %.3f | %.3f | %.2f | %.3f | %.3f | %.2f | "
        "%zu / %zu |\n",
        labels[i].c_str(), first.om_ms_per_scan, last.om_ms_per_scan,
        last.om_ms_per_scan / first.om_ms_per_scan, first.om_us_per_point, last.om_us_per_point,
        last.om_us_per_point / first.om_us_per_point, first.nodes_at_end, last.nodes_at_end);
    std::printf("| %s | octovk wall | %.3f | %.3f | %.2f | %.3f | %.3f | %.2f | %zu / %zu |\n",
                labels[i].c_str(), first.vk_ms_per_scan, last.vk_ms_per_scan,
                last.vk_ms_per_scan / first.vk_ms_per_scan, first.vk_us_per_point,
                last.vk_us_per_point, last.vk_us_per_point / first.vk_us_per_point,
                first.nodes_at_end, last.nodes_at_end);
    std::printf(
        "| %s | octovk device (of which leaf boxes) | %.3f (%.3f) | %.3f (%.3f) | %.2f | "
        "| | | |\n",
        labels[i].c_str(), first.vk_device_ms_per_scan, first.vk_leaf_boxes_ms_per_scan,
        last.vk_device_ms_per_scan, last.vk_leaf_boxes_ms_per_scan,
        last.vk_device_ms_per_scan / first.vk_device_ms_per_scan);
  }
  std::fflush(stdout);
}

}  // namespace octovk::bench
