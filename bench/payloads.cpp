// The payloads workload: what a colour or a time stamp per node costs. The first FR-079 scans
// into OctoMap's OcTree, ColorOcTree (insertPointCloud, then averageNodeColor per point) and
// OcTreeStamped, and into octovk's OccupancyMap, ColorMap and StampedMap, scan by scan in turn.
#include <octomap/ColorOcTree.h>
#include <octomap/OcTree.h>
#include <octomap/OcTreeStamped.h>

#include <algorithm>
#include <cstdio>
#include <string>
#include <vector>

#include "octovk/octomap_io.hpp"
#include "workload_common.hpp"
#include "workloads.hpp"

namespace octovk::bench {

namespace {

// A colour per point, a function of the scan and the point's index (as the oracle tests').
Rgb pointColor(std::size_t scan, std::size_t i) {
  return Rgb{static_cast<std::uint8_t>((i * 37 + scan * 11) & 0xFF),
             static_cast<std::uint8_t>((i * 101 + scan * 53 + 7) & 0xFF),
             static_cast<std::uint8_t>((i * 13 + scan * 29 + 200) & 0xFF)};
}

template <class Tree>
void setModel(Tree& tree, const MapParams& p) {
  tree.setProbHit(p.prob_hit);
  tree.setProbMiss(p.prob_miss);
  tree.setClampingThresMin(p.clamping_min);
  tree.setClampingThresMax(p.clamping_max);
  tree.setOccupancyThres(p.occupancy_threshold);
}

double msOf(Clock::time_point start) { return secondsSince(start) * 1e3; }

// Sums over the scans of one mapper.
struct Totals {
  double wall_ms = 0;    // the call(s) of one scan, as the user sees them (host clock)
  double device_ms = 0;  // octovk: the scan's device stages (StageTimes::total_ms)
  std::size_t nodes = 0;
};

}  // namespace

void runPayloads(Context& context, const BenchOptions& o, JsonWriter& json) {
  const std::vector<double> resolutions = resolutionsFor(o, {0.1, 0.05}, {0.1});
  std::vector<GraphScan> graph = readScanGraph(o.fr079_path);
  const std::size_t limit = o.fr079_scans ? o.fr079_scans : (o.quick ? 100 : 500);
  if (graph.size() > limit) graph.resize(limit);
  // World points and origins as graph2tree places them (Pose::transform is Pose6D's).
  std::vector<std::vector<Eigen::Vector3f>> points(graph.size());
  std::vector<Eigen::Vector3f> origins(graph.size());
  std::vector<std::vector<Rgb>> colors(graph.size());
  std::size_t total_points = 0;
  for (std::size_t s = 0; s < graph.size(); ++s) {
    const Pose& pose = graph[s].T_world_sensor;
    for (const auto& p : graph[s].points_sensor) points[s].push_back(pose.transform(p));
    origins[s] = pose.transform(graph2treeSensorOrigin(pose));
    for (std::size_t i = 0; i < points[s].size(); ++i) colors[s].push_back(pointColor(s, i));
    total_points += points[s].size();
  }
  std::printf(
      "\n## payloads: colour and time stamp per node, the first %zu FR-079 scans (%zu points)\n",
      graph.size(), total_points);
  std::printf(
      "\nThe six mappers take each scan in turn (world points, graph2tree's placement, no max "
      "range). ColorOcTree: insertPointCloud then averageNodeColor per point (inner colours "
      "not updated: updateInnerOccupancy is for before a write); ColorMap: the same in one "
      "call. OcTreeStamped stamps time(NULL); StampedMap the scan's index. Leaf boxes rebuilt "
      "every scan: %s. Wall times per scan on the host's clock, each mapper's turn rotating "
      "from scan to scan; octovk's device time is the sum of its scan stages (the colour "
      "fold's pass is only in the wall time).\n",
      o.leaf_boxes_every_scan ? "yes" : "no");
  json.key("payloads").beginObject();
  json.field("file", o.fr079_path).field("scans", graph.size()).field("points", total_points);
  json.key("runs").beginArray();
  for (const double res : resolutions) {
    const MapParams params = [&] {
      MapParams p;
      p.resolution = res;
      return p;
    }();
    octomap::OcTree om_plain(res);
    octomap::ColorOcTree om_color(res);
    octomap::OcTreeStamped om_stamped(res);
    setModel(om_plain, params);
    setModel(om_color, params);
    setModel(om_stamped, params);
    OccupancyMap vk_plain(context, params);
    ColorMap vk_color(context, params);
    StampedMap vk_stamped(context, params);
    for (OccupancyMap* m : {&vk_plain, static_cast<OccupancyMap*>(&vk_color),
                            static_cast<OccupancyMap*>(&vk_stamped)})
      m->setLeafBoxesEveryScan(o.leaf_boxes_every_scan);
    {
      // The colour fold's and stamps' pipelines are built on first use: not in the figures.
      ColorMap warm_color(context, params);
      StampedMap warm_stamped(context, params);
      (void)warm_color.insertPointCloud(points[0], origins[0], colors[0]);
      (void)warm_stamped.insertPointCloud(points[0], origins[0], 1u);
    }
    Totals t[6];
    std::vector<double> per_scan[6];
    std::size_t mismatches = 0;
    progress("payloads: %zu scans at %.3f m\n", graph.size(), res);
    for (std::size_t s = 0; s < graph.size(); ++s) {
      octomap::Pointcloud pc;
      for (const auto& p : points[s]) pc.push_back(p.x(), p.y(), p.z());
      const octomap::point3d origin(origins[s].x(), origins[s].y(), origins[s].z());
      const auto stamp = static_cast<std::uint32_t>(s + 1);
      ScanStats vk[3];
      // Each mapper's turn rotates from scan to scan, so that no one always runs first (after
      // the host's other work) or last.
      for (std::size_t turn = 0; turn < 6; ++turn) {
        const std::size_t k = (turn + s) % 6;
        const auto start = Clock::now();
        switch (k) {
          case 0:
            om_plain.insertPointCloud(pc, origin);
            break;
          case 1:
            om_color.insertPointCloud(pc, origin);
            for (std::size_t i = 0; i < points[s].size(); ++i)
              om_color.averageNodeColor(points[s][i].x(), points[s][i].y(), points[s][i].z(),
                                        colors[s][i].r, colors[s][i].g, colors[s][i].b);
            break;
          case 2:
            om_stamped.insertPointCloud(pc, origin);
            break;
          case 3:
            vk[0] = vk_plain.insertPointCloud(points[s], origins[s]);
            break;
          case 4:
            vk[1] = vk_color.insertPointCloud(points[s], origins[s], colors[s]);
            break;
          default:
            vk[2] = vk_stamped.insertPointCloud(points[s], origins[s], stamp);
        }
        const double ms = msOf(start);
        t[k].wall_ms += ms;
        per_scan[k].push_back(ms);
      }
      for (int k = 0; k < 3; ++k) t[3 + k].device_ms += vk[k].device.total_ms();
      const ScanStats& a = vk[0];
      const ScanStats& b = vk[1];
      // Node parity per scan (OcTreeStamped's time(NULL) stamps may merge differently from the
      // scan indices when two scans share a second: counted, not asserted).
      mismatches += a.nodes != om_plain.size();
      mismatches += b.nodes != om_color.size();
    }
    t[0].nodes = om_plain.size();
    t[1].nodes = om_color.size();
    t[2].nodes = om_stamped.size();
    t[3].nodes = vk_plain.nodeCount();
    t[4].nodes = vk_color.nodeCount();
    t[5].nodes = vk_stamped.nodeCount();
    const double n = static_cast<double>(graph.size());
    const char* names[6] = {"OctoMap OcTree",      "OctoMap ColorOcTree", "OctoMap OcTreeStamped",
                            "octovk OccupancyMap", "octovk ColorMap",     "octovk StampedMap"};
    std::printf("\n### %.3f m\n\n", res);
    std::printf(
        "| mapper | ms/scan (mean) | vs plain | ms/scan (median) | device ms/scan | nodes at "
        "end |\n");
    std::printf("|---|---:|---:|---:|---:|---:|\n");
    for (int k = 0; k < 6; ++k) {
      const double plain = k < 3 ? t[0].wall_ms : t[3].wall_ms;
      std::printf("| %s | %.2f | %.2fx | %.2f | %s | %zu |\n", names[k], t[k].wall_ms / n,
                  t[k].wall_ms / plain, median(per_scan[k]),
                  k < 3 ? "-" : fmt("%.2f", t[k].device_ms / n).c_str(), t[k].nodes);
    }
    std::printf("\nNode-count mismatches (OcTree / ColorOcTree against octovk, per scan): %zu\n",
                mismatches);
    json.beginObject().field("resolution", res).field("node_mismatches", mismatches);
    json.key("mappers").beginArray();
    for (int k = 0; k < 6; ++k)
      json.beginObject()
          .field("name", names[k])
          .field("ms_per_scan", t[k].wall_ms / n)
          .field("median_ms_per_scan", median(per_scan[k]))
          .field("device_ms_per_scan", k < 3 ? 0.0 : t[k].device_ms / n)
          .field("nodes", t[k].nodes)
          .endObject();
    json.endArray().endObject();
  }
  json.endArray().endObject();
}

}  // namespace octovk::bench
