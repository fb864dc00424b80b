// OccupancyMap::Impl: the map's state (params, buffers, what the last scan left in the sets) and
// the host-side decisions of each operation. The passes it records are in map/passes/.
#pragma once

#include <cstdint>
#include <memory>
#include <span>
#include <vector>

#include "map/map_buffers.hpp"
#include "map/passes/passes.hpp"
#include "map/ray_scene.hpp"
#include "map/reference.hpp"
#include "octovk/octovk.hpp"
#include "vk/device.hpp"

namespace octovk {

class OccupancyMap::Impl {
 public:
  using DeviceBytes = OccupancyMap::DeviceBytes;
  Impl(Context& context, const MapParams& params);

  /// What a scan inserts: points, or a depth image (unprojected on the device), from the host
  /// or from a caller's device buffer (`device`, read once `wait` is signalled).
  struct ScanSource {
    std::span<const Eigen::Vector3f> points;
    const DepthImage* depth = nullptr;  ///< its pixels are ignored when `device` is given
    std::size_t device_points = 0;      ///< points in `device` (when no depth image)
    VkBuffer device = VK_NULL_HANDLE;
    VkDeviceSize device_offset = 0;
    VkSemaphore wait = VK_NULL_HANDLE;
    std::uint64_t wait_value = 0;
    std::size_t count() const {
      if (depth) return std::size_t{depth->width} * depth->height;
      return device != VK_NULL_HANDLE ? device_points : points.size();
    }
  };
  /// One scan, then the queries if any.
  ScanStats insert(const ScanSource& source, const Eigen::Vector3f& origin,
                   const Pose* pose, double max_range, bool discretize,
                   const QueryRequest* queries = nullptr, QueryResults* results = nullptr);
  QueryResults runQueries(const QueryRequest& queries);
  /// A castRay (rays) or lookup batch between ranges of the caller's buffers (interop).
  void queryOnDevice(bool rays, VkBuffer in, VkDeviceSize in_offset, VkDeviceSize in_size,
                     VkBuffer out, VkDeviceSize out_offset, VkDeviceSize out_size,
                     std::uint32_t count);
  std::vector<LeafBoxHost> leavesInBox(const Eigen::Vector3f& min, const Eigen::Vector3f& max,
                                       bool occupied_only);
  HostTree download();
  void upload(const HostTree& tree);
  std::vector<LeafBoxHost> downloadLeafBoxes();
  gpu::PoolState readPool();
  std::size_t deviceBytes() const {
    return buffers_.deviceBytes() + (ray_scene_ ? ray_scene_->deviceBytes() : 0);
  }
  std::size_t poolBytes() const { return buffers_.poolBytes(); }
  DeviceBytes deviceBytesByUse() const;
  /// Releases the per-scan scratch and the query buffers (OccupancyMap::trim).
  void trim();

  const MapParams& params() const { return params_; }
  void setLeafBoxesEveryScan(bool every_scan) { leaf_boxes_every_scan_ = every_scan; }
  /// Rebuilds the leaf boxes if scans were inserted without rebuilding them.
  void refreshLeafBoxes();

  vk::Device& device() { return device_; }

  /// castRay's backend on this map (kWalk or kRayTracing) and its build statistics.
  OccupancyMap::CastRayInfo castRayInfo() const;

 private:
  // ---- castRay's ray-tracing backend (map/ray_scene.cpp) ----
  /// Resolves MapParams::cast_ray_backend on this device; throws when kRayTracing cannot run.
  static CastRayBackend chooseCastRayBackend(const vk::Device& device, const MapParams& params);
  /// Brings the acceleration structure up to the tree (lazily: when the tree changed since it
  /// was built) and returns the address of its boxes buffer for cast_ray_rt; 0 with the walk.
  VkDeviceAddress rayScene();
  CastRayBackend cast_ray_backend_ = CastRayBackend::kWalk;
  std::unique_ptr<RayScene> ray_scene_;
  /// Counts the changes of the tree (scans that updated cells, uploads), for the ray scene.
  std::uint64_t tree_version_ = 0;

 private:
  /// Where the ray pass reads the scan's input: the upload buffer, after writing the host's
  /// points or pixels into it, or the caller's buffer.
  passes::RayKeysInput stage(const ScanSource& source);
  /// Throws kInvalidArgument naming the first bad input of a scan of `count` points.
  void checkScan(std::size_t count, const Eigen::Vector3f& origin, const Pose* pose,
                 double max_range) const;
  gpu::ScanParams scanParams(const Eigen::Vector3f& origin, const Pose* pose, double max_range,
                             std::size_t count) const;
  /// The parameters of a pass that is not a scan (queries, uploads): the map's, no scan.
  gpu::ScanParams queryParams() const {
    return scanParams(Eigen::Vector3f::Zero(), nullptr, -1.0, 0);
  }
  /// Grows what a scan the device did not apply found short; throws (map unchanged) where it
  /// may not grow.
  void growForRetry(const gpu::ScanCounters& counters, const gpu::PoolState& pool);
  /// Room in the pool for `blocks` more blocks; `ahead`: for later scans, never an error.
  void reservePool(std::uint64_t blocks, const gpu::PoolState& pool, bool ahead);

  vk::Device& device_;
  MapParams params_;
  ref::LogOddsParams logs_;
  vk::CommandStream stream_;
  MapBuffers buffers_;
  passes::Recorder rec_;
  // The slots the last successful scan filled in the two sets (cleared by the next scan).
  std::uint32_t filled_bricks_ = 0, filled_endpoints_ = 0;
  bool leaf_boxes_every_scan_ = false;
  bool leaf_boxes_dirty_ = false;
};

}  // namespace octovk
