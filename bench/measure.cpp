#include "measure.hpp"

#include <chrono>
#include <cstdio>
#include <iostream>

#include "gpu/gpu_types.h"
#include "octovk/octomap_io.hpp"

namespace octovk::bench {

namespace {

using Clock = std::chrono::steady_clock;

double msSince(Clock::time_point start) {
  return std::chrono::duration<double, std::milli>(Clock::now() - start).count();
}

double mib(std::size_t bytes) { return static_cast<double>(bytes) / 1048576.0; }

octomap::Pointcloud toPointcloud(std::span<const Eigen::Vector3f> points) {
  octomap::Pointcloud pc;
  pc.reserve(points.size());
  for (const Eigen::Vector3f& p : points) pc.push_back(p.x(), p.y(), p.z());
  return pc;
}

octomath::Pose6D toPose6D(const Pose& pose) {
  return octomath::Pose6D(
      octomath::Vector3(pose.translation.x(), pose.translation.y(), pose.translation.z()),
      octomath::Quaternion(pose.rotation.w(), pose.rotation.x(), pose.rotation.y(),
                           pose.rotation.z()));
}

}  // namespace

ScanTiming measureWorldScan(octomap::OcTree& tree, OccupancyMap& map,
                            std::span<const Eigen::Vector3f> points_world,
                            const Eigen::Vector3f& origin_world, double max_range_m,
                            bool compute_update) {
  ScanTiming t;
  t.rays = points_world.size();
  const octomap::Pointcloud pc = toPointcloud(points_world);
  const octomap::point3d origin(origin_world.x(), origin_world.y(), origin_world.z());
  if (compute_update) {
    octomap::KeySet free_cells, occupied_cells;
    const auto start = Clock::now();
    tree.computeUpdate(pc, origin, free_cells, occupied_cells, max_range_m);
    t.om_compute_update_ms = msSince(start);
    t.om_free_cells = free_cells.size();
    t.om_occupied_cells = occupied_cells.size();
  }
  const auto start = Clock::now();
  tree.insertPointCloud(pc, origin, max_range_m, /*lazy_eval=*/false, /*discretize=*/false);
  t.om_insert_ms = msSince(start);
  t.om_nodes = tree.size();
  t.vk = map.insertPointCloud(points_world, origin_world, {.max_range_m = max_range_m});
  return t;
}

ScanTiming measureGraphScan(octomap::OcTree& tree, OccupancyMap& map,
                            std::span<const Eigen::Vector3f> points_sensor,
                            const Pose& T_world_sensor, double max_range_m, bool compute_update) {
  ScanTiming t;
  t.rays = points_sensor.size();
  const octomap::Pointcloud pc = toPointcloud(points_sensor);
  const octomath::Pose6D frame_origin = toPose6D(T_world_sensor);
  // graph2tree: the sensor origin in the sensor frame is pose.inv().transform(pose.trans()).
  const octomap::point3d sensor_origin = frame_origin.inv().transform(frame_origin.trans());
  if (compute_update) {
    octomap::Pointcloud world = pc;
    world.transform(frame_origin);
    octomap::KeySet free_cells, occupied_cells;
    const auto start = Clock::now();
    tree.computeUpdate(world, frame_origin.transform(sensor_origin), free_cells, occupied_cells,
                       max_range_m);
    t.om_compute_update_ms = msSince(start);
    t.om_free_cells = free_cells.size();
    t.om_occupied_cells = occupied_cells.size();
  }
  // graph2tree's call: copies and transforms the cloud, then insertPointCloud in the world.
  const auto start = Clock::now();
  tree.insertPointCloud(pc, sensor_origin, frame_origin, max_range_m, /*lazy_eval=*/false,
                        /*discretize=*/false);
  t.om_insert_ms = msSince(start);
  t.om_nodes = tree.size();
  t.vk = map.insertPointCloud(points_sensor, graph2treeSensorOrigin(T_world_sensor), T_world_sensor,
                              {.max_range_m = max_range_m});
  return t;
}

std::size_t poolBytesPerBlock() {
  // 8 nodes, the block's parent entry, its free-stack entry.
  return 8 * sizeof(gpu::Node) + 2 * sizeof(std::uint32_t);
}

MemoryReport memoryReport(const octomap::OcTree& tree, OccupancyMap& map) {
  MemoryReport m;
  m.om_nodes = tree.size();
  m.om_bytes = tree.memoryUsage();
  m.vk_nodes = map.nodeCount();
  m.vk_device_bytes = map.deviceBytes();
  const HostTree host = map.download();
  m.vk_used_blocks = host.nodes.size() / 8;
  if (host.root_exists) {
    // The root's block, plus one block per node with children (reachable from the root).
    std::vector<std::uint32_t> stack{gpu::kRootNode};
    m.vk_live_blocks = 1;
    while (!stack.empty()) {
      const HostTree::Node& n = host.nodes[stack.back()];
      stack.pop_back();
      if ((n.mask & gpu::kChildMask) == 0) continue;
      ++m.vk_live_blocks;
      for (std::uint32_t s = 0; s < 8; ++s)
        if (n.mask & (1u << s)) stack.push_back(n.children * 8 + s);
    }
  }
  m.vk_pool_bytes_live = m.vk_live_blocks * poolBytesPerBlock();
  return m;
}

void writeJson(JsonWriter& json, const StageTimes& s) {
  json.beginObject()
      .field("upload_ms", s.upload_ms)
      .field("ray_keys_ms", s.ray_keys_ms)
      .field("classify_ms", s.classify_ms)
      .field("tree_update_ms", s.tree_update_ms)
      .field("prune_ms", s.prune_ms)
      .field("leaf_boxes_ms", s.leaf_boxes_ms)
      .field("total_ms", s.total_ms())
      .endObject();
}

void writeJson(JsonWriter& json, const ScanTiming& t) {
  json.beginObject().field("rays", t.rays);
  if (t.om_compute_update_ms >= 0) {
    json.field("octomap_compute_update_ms", t.om_compute_update_ms)
        .field("octomap_free_cells", t.om_free_cells)
        .field("octomap_occupied_cells", t.om_occupied_cells);
  }
  json.field("octomap_insert_ms", t.om_insert_ms)
      .field("octomap_nodes", t.om_nodes)
      .field("octovk_wall_ms", t.vk.wall_ms)
      .field("octovk_free_cells", t.vk.free_cells)
      .field("octovk_occupied_cells", t.vk.occupied_cells)
      .field("octovk_aborted_cells", t.vk.aborted_cells)
      .field("octovk_skipped", t.vk.skipped_nonfinite + t.vk.skipped_outside)
      .field("octovk_cell_set_attempts", t.vk.cell_set_attempts)
      .field("octovk_nodes", t.vk.nodes)
      .key("octovk_device");
  writeJson(json, t.vk.device);
  json.endObject();
}

void writeJson(JsonWriter& json, const MemoryReport& m) {
  json.beginObject()
      .field("octomap_nodes", m.om_nodes)
      .field("octomap_bytes", m.om_bytes)
      .field("octomap_bytes_per_node", m.omBytesPerNode())
      .field("octovk_nodes", m.vk_nodes)
      .field("octovk_device_bytes", m.vk_device_bytes)
      .field("octovk_device_bytes_per_node", m.vkDeviceBytesPerNode())
      .field("octovk_live_blocks", m.vk_live_blocks)
      .field("octovk_used_blocks", m.vk_used_blocks)
      .field("octovk_pool_bytes_live", m.vk_pool_bytes_live)
      .field("octovk_pool_bytes_per_node", m.vkPoolBytesPerNode())
      .field("octovk_slot_use", m.vkSlotUse())
      .endObject();
}

void printMemoryTable(const std::vector<std::string>& labels,
                      const std::vector<MemoryReport>& reports) {
  std::printf(
      "\n| map | nodes OctoMap / octovk | OctoMap memoryUsage, B/node | octovk deviceBytes "
      "(all buffers), B/node | octovk node pool (live blocks), B/node | block slots used |\n"
      "| --- | --- | --- | --- | --- | --- |\n");
  for (std::size_t i = 0; i < reports.size(); ++i) {
    const MemoryReport& m = reports[i];
    std::printf("| %s | %zu / %zu | %.1f MiB, %.1f | %.1f MiB, %.1f | %.1f MiB, %.1f | %.0f%% |\n",
                labels[i].c_str(), m.om_nodes, m.vk_nodes, mib(m.om_bytes), m.omBytesPerNode(),
                mib(m.vk_device_bytes), m.vkDeviceBytesPerNode(), mib(m.vk_pool_bytes_live),
                m.vkPoolBytesPerNode(), 100.0 * m.vkSlotUse());
  }
  std::fflush(stdout);
}

std::string parityLine(std::size_t om_nodes, std::size_t vk_nodes) {
  char buf[160];
  std::snprintf(buf, sizeof(buf), "nodes: OctoMap %zu, octovk %zu (%s)", om_nodes, vk_nodes,
                om_nodes == vk_nodes ? "equal" : "MISMATCH: the maps differ");
  return buf;
}

}  // namespace octovk::bench
