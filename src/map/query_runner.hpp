// The query runner: OctoMap's search() and castRay over a batch (staged, ordered, run in one
// submission, decoded), the same on a caller's device buffers (interop), and the leaves in a box.
// The caller takes the results of the scans in flight first (OccupancyMap::Impl does).
#pragma once

#include <cstdint>
#include <vector>

#include "map/map_core.hpp"
#include "map/ray_scene_cache.hpp"
#include "octovk/octovk.hpp"

namespace octovk {

/// The key range of a box as OctoMap's leaf_bbx_iterator computes it (coordToKeyChecked on each
/// corner) into `box` (occupied_only untouched); false when a corner lies outside the map, where
/// the iterator visits nothing.
bool boxKeys(double resolution, const Eigen::Vector3f& min, const Eigen::Vector3f& max,
             gpu::BoxQuery& box);

class QueryRunner {
 public:
  QueryRunner(MapCore& core, RaySceneCache& scenes) : core_(core), scenes_(scenes) {}

  QueryResults run(const QueryRequest& queries);
  /// A castRay (rays) or lookup batch between ranges of the caller's buffers (interop).
  void onDevice(bool rays, VkBuffer in, VkDeviceSize in_offset, VkDeviceSize in_size, VkBuffer out,
                VkDeviceSize out_offset, VkDeviceSize out_size, std::uint32_t count);
  std::vector<OccupancyMap::LeafBoxHost> leavesInBox(const Eigen::Vector3f& min,
                                                     const Eigen::Vector3f& max,
                                                     bool occupied_only);

 private:
  MapCore& core_;
  RaySceneCache& scenes_;
};

}  // namespace octovk
