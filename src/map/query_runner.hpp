// The query runner: OctoMap's search() and castRay over a batch (staged, ordered, run in one
// submission, decoded), the same on a caller's device buffers (interop), and the leaves in a box.
// The caller takes the results of the scans in flight first (OccupancyMap::Impl does).
#pragma once

#include <cstddef>
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

  /// search() and castRay over any number of queries: split into batches that fit one binding
  /// (and the castRay dispatch limit), each answered as OctoMap would answer it alone. A device's
  /// refusal of memory says how many queries asked and what to change.
  QueryResults run(const QueryRequest& queries);
  /// Whether so many queries fit one batch (one submission; insert-with-queries needs that).
  bool fitsOneBatch(std::size_t rays, std::size_t lookups) const;
  /// A castRay (rays) or lookup batch between ranges of the caller's buffers (interop).
  void onDevice(bool rays, VkBuffer in, VkDeviceSize in_offset, VkDeviceSize in_size, VkBuffer out,
                VkDeviceSize out_offset, VkDeviceSize out_size, std::uint32_t count);
  std::vector<OccupancyMap::LeafBoxHost> leavesInBox(const Eigen::Vector3f& min,
                                                     const Eigen::Vector3f& max,
                                                     bool occupied_only);

 private:
  /// The most queries of one kind (castRay when `rays`, else search) in one batch.
  std::size_t batchLimit(bool rays) const;
  /// run() without its wording of a device's refusal.
  QueryResults runSplit(const QueryRequest& queries);
  QueryResults runBatch(const QueryRequest& queries);
  /// Appends the leaves in `box` (keys) to `out`, in parts of the box where they are more than
  /// `capacity`; true when it asked in parts (a leaf in several parts is then in `out` twice).
  bool leavesInKeyBox(const gpu::BoxQuery& box, std::size_t capacity,
                      std::vector<OccupancyMap::LeafBoxHost>& out);
  static constexpr std::size_t kMaxBatch = std::size_t{1} << 20;

  MapCore& core_;
  RaySceneCache& scenes_;
};

}  // namespace octovk
