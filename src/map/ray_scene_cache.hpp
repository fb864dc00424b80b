// The ray-scene cache: the acceleration structures a map keeps for ray tracing, castRay's (built
// lazily when the tree changed, under the memory cap or not at all) and the traced scans' (sized
// for the pool, rebuilt inside every scan), which backend each uses, and the bytes they hold in
// the map's cap accounting.
#pragma once

#include <cstdint>
#include <memory>
#include <string>

#include "gpu/gpu_types.h"
#include "map/map_core.hpp"
#include "map/passes/passes.hpp"
#include "octovk/octovk.hpp"
#include "vk/accel.hpp"
#include "vk/device.hpp"

namespace octovk {

/// One scene: the boxes buffer (an AccelHeader, then the boxes accel_boxes.comp writes), the
/// acceleration structure built over them, and which state of the tree they describe.
struct RayScene {
  explicit RayScene(vk::Device& device)
      : accel(device), readback(device, sizeof(gpu::AccelHeader), /*host_visible=*/true) {}

  vk::Buffer boxes;     ///< AccelHeader, then the boxes (sorted, unsorted), then the sort's
  vk::BoxScene accel;   ///< built over `boxes`
  vk::Buffer readback;  ///< the header after accel_boxes: the box count
  /// MapCore::tree_version the structure was built from; none yet: ~0.
  std::uint64_t version = ~std::uint64_t{0};
  OccupancyMap::CastRayInfo info;

  std::size_t deviceBytes() const { return boxes.size() + accel.deviceBytes() + readback.size(); }
};

class RaySceneCache {
 public:
  /// Resolves MapParams::cast_ray_backend and MapParams::scan_rays on the device (kWalk,
  /// kRayQuery or kRayTracingPipeline); throws when a ray-tracing value is asked for and cannot
  /// run.
  explicit RaySceneCache(MapCore& core);

  /// castRay's scene brought up to the tree (lazily: when the tree changed since it was built;
  /// stale leaf boxes are rebuilt in the same submission), and the way cast_ray_rt traces
  /// through it; none with the walk. Under MapParams::max_device_bytes a structure that would
  /// not fit is not built: with kAuto the scene is dropped and none returned (the walk answers,
  /// CastRayInfo::cap_fallbacks counts it); with a ray-tracing backend BudgetError, the map
  /// unchanged.
  passes::TraceScene castRayScene();
  /// Whether scans trace their rays (ScanRays' ray-tracing values) instead of walking them.
  bool traceScans() const noexcept { return scan_rays_ != ScanRays::kWalk; }
  /// The scans' scene (scanScene()) and the way scan_rays_rt traces through it.
  passes::TraceScene scanTrace() const;
  /// The scans' scene with its boxes buffer sized for the pool as it is now; when that changes
  /// (the pool grew), waits for the device first (the scans in flight use the scene).
  RayScene& scanScene();
  /// The capacities the scans' scene is built for (scanScene()).
  const gpu::AccelHeader& scanHeader() const noexcept { return scan_header_; }
  /// Tells the buffers' cap accounting what the two scenes hold (after either changes).
  void noteSceneBytes();
  /// Under a cap, drops castRay's scene (no castRay uses it after its call returns), so that a
  /// scan's or an upload's growth never loses room to a structure the change makes stale anyway.
  void releaseUnderCap();
  /// Drops both scenes (OccupancyMap::trim).
  void release();
  /// castRay's backend on this map and its scene's build statistics.
  OccupancyMap::CastRayInfo castRayInfo() const;

 private:
  /// Whether castRay's scene may hold `bytes` in place of what it holds now under the cap; if
  /// not, drops the scene, then with a ray-tracing backend throws BudgetError naming `what`, with
  /// kAuto counts a fallback and returns false.
  bool castRaySceneFits(std::size_t bytes, const std::string& what);

  MapCore& core_;
  CastRayBackend cast_ray_backend_ = CastRayBackend::kWalk;  ///< kWalk, kRayQuery or pipeline
  std::unique_ptr<RayScene> ray_scene_;                      ///< castRay's
  /// castRays calls the walk answered because the structure did not fit under the cap (kAuto).
  std::size_t cap_fallbacks_ = 0;
  ScanRays scan_rays_ = ScanRays::kWalk;
  std::unique_ptr<RayScene> scan_scene_;  ///< the scans', not castRay's: other boxes
  gpu::AccelHeader scan_header_{};        ///< the capacities scan_scene_ is built for
};

}  // namespace octovk
