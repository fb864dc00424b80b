// One scan measured on both mappers, and the memory of the resulting maps.
#pragma once

#include <octomap/OcTree.h>

#include <Eigen/Core>
#include <cstddef>
#include <span>
#include <string>
#include <vector>

#include "json.hpp"
#include "octovk/octovk.hpp"

namespace octovk::bench {

/// The same scan inserted by OctoMap and by octovk, with times in milliseconds.
struct ScanTiming {
  std::size_t rays = 0;
  double om_compute_update_ms = -1.0;  ///< OcTree::computeUpdate alone (negative: not measured)
  double om_insert_ms = 0.0;           ///< OcTree::insertPointCloud (computeUpdate + updates)
  std::size_t om_free_cells = 0;       ///< from computeUpdate (0 when it was not measured)
  std::size_t om_occupied_cells = 0;
  std::size_t om_nodes = 0;  ///< OcTree::size() after the scan
  ScanStats vk;              ///< octovk's statistics; vk.wall_ms is its wall time
};

/// Points in the world frame (the paper views, scan.dat, the scaling runs): OctoMap's
/// computeUpdate and insertPointCloud(pc, origin, max_range), then octovk's insertPointCloud.
ScanTiming measureWorldScan(octomap::OcTree& tree, OccupancyMap& map,
                            std::span<const Eigen::Vector3f> points_world,
                            const Eigen::Vector3f& origin_world, double max_range_m,
                            bool compute_update);

/// A scan of a scan graph, placed as OctoMap's graph2tree does: points in the sensor frame,
/// sensor origin pose.inv().transform(pose.trans()), the pose applied by each mapper.
ScanTiming measureGraphScan(octomap::OcTree& tree, OccupancyMap& map,
                            std::span<const Eigen::Vector3f> points_sensor,
                            const Pose& T_world_sensor, double max_range_m, bool compute_update);

/// Memory of the same map in both systems.
struct MemoryReport {
  std::size_t om_nodes = 0;
  std::size_t om_bytes = 0;            ///< OcTree::memoryUsage()
  std::size_t vk_nodes = 0;            ///< OccupancyMap::nodeCount()
  std::size_t vk_device_bytes = 0;     ///< OccupancyMap::deviceBytes(): every buffer of the map
  std::size_t vk_live_blocks = 0;      ///< 8-slot blocks that hang in the tree
  std::size_t vk_used_blocks = 0;      ///< blocks ever taken from the pool (its high-water mark)
  std::size_t vk_pool_bytes_live = 0;  ///< node-pool bytes of the live blocks (nodes, meta, free)

  double omBytesPerNode() const { return ratio(om_bytes, om_nodes); }
  double vkDeviceBytesPerNode() const { return ratio(vk_device_bytes, vk_nodes); }
  double vkPoolBytesPerNode() const { return ratio(vk_pool_bytes_live, vk_nodes); }
  double vkSlotUse() const { return ratio(vk_nodes, vk_live_blocks * 8); }

 private:
  static double ratio(std::size_t a, std::size_t b) {
    return b == 0 ? 0.0 : static_cast<double>(a) / static_cast<double>(b);
  }
};

/// Node-pool bytes of one 8-slot block: 8 nodes, its parent entry, its free-stack entry.
std::size_t poolBytesPerBlock();

/// Reads both maps' sizes (downloads octovk's tree to count its live blocks).
MemoryReport memoryReport(const octomap::OcTree& tree, OccupancyMap& map);

void writeJson(JsonWriter& json, const ScanTiming& t);
void writeJson(JsonWriter& json, const MemoryReport& m);
void writeJson(JsonWriter& json, const StageTimes& s);

/// Markdown table of the memory of one or more maps, one row per label.
void printMemoryTable(const std::vector<std::string>& labels,
                      const std::vector<MemoryReport>& reports);

/// "nodes OctoMap 123 = octovk 123" or a visible MISMATCH line (never an assertion).
std::string parityLine(std::size_t om_nodes, std::size_t vk_nodes);

}  // namespace octovk::bench
