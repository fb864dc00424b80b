// The ray-scene cache: which backend castRay and the scans use, the lazy rebuild of castRay's
// acceleration structure after the tree changed (two submissions: the boxes and their count,
// then the build over exactly that many boxes; no box leaves the device), the scans' scene sized
// for the pool, and both under the map's memory cap.
#include "map/ray_scene_cache.hpp"

#include <algorithm>
#include <cstring>
#include <string>
#include <vector>

namespace octovk {

namespace {

// The ray-tracing passes (castRay's and the scans') need ray queries and loops without a driver
// limit (they are not resumable); the scans' also no memory cap (their structure is sized for
// the pool's capacity and built inside the scan, which a cap could not refuse cleanly; castRay's
// is checked against the cap before each build): throws naming `option` and the way out,
// `remedy`, when one of them is missing.
void requireRayTracing(const vk::Device& device, const MapParams& params, const std::string& option,
                       const std::string& remedy, bool refuse_cap) {
  const std::string name = option + " is kRayTracing, but device '" + device.info().name + "'";
  if (!device.rayQuery())
    throw Error(
        ErrorCode::kMissingFeature,
        name +
            (device.info().ray_query ? " was opened with ContextOptions::enable_ray_query = false"
                                     : " has no ray queries (VK_KHR_acceleration_structure and "
                                       "VK_KHR_ray_query; Mesa's lavapipe has them from Mesa 25)") +
            "; use " + remedy);
  if (device.loopLimit() != 0)
    throw Error(ErrorCode::kMissingFeature,
                name + " ends shader loops after " + std::to_string(device.loopLimit()) +
                    " iterations and the ray-tracing passes are not resumable; use " + remedy);
  if (refuse_cap && params.max_device_bytes != 0)
    throw Error(ErrorCode::kInvalidArgument,
                option +
                    " is kRayTracing together with max_device_bytes: the acceleration "
                    "structure is not held under the cap; use " +
                    remedy + ", or max_device_bytes = 0");
}

CastRayBackend chooseCastRayBackend(const vk::Device& device, const MapParams& params) {
  if (params.cast_ray_backend == CastRayBackend::kWalk) return CastRayBackend::kWalk;
  if (params.cast_ray_backend == CastRayBackend::kAuto)
    return device.rayQuery() && device.loopLimit() == 0 ? CastRayBackend::kRayTracing
                                                        : CastRayBackend::kWalk;
  requireRayTracing(device, params, "MapParams::cast_ray_backend", "CastRayBackend::kAuto or kWalk",
                    /*refuse_cap=*/false);
  return CastRayBackend::kRayTracing;
}

ScanRays chooseScanRays(const vk::Device& device, const MapParams& params) {
  if (params.scan_rays == ScanRays::kWalk) return ScanRays::kWalk;
  requireRayTracing(device, params, "MapParams::scan_rays",
                    "ScanRays::kWalk (octovk integrate --rays walk)", /*refuse_cap=*/true);
  return ScanRays::kRayTracing;
}

double spanMs(const std::vector<double>& ns) {
  return ns.size() >= 2 ? (ns.back() - ns.front()) * 1e-6 : 0.0;
}

}  // namespace

RaySceneCache::RaySceneCache(MapCore& core)
    : core_(core),
      cast_ray_backend_(chooseCastRayBackend(core.device, core.params)),
      scan_rays_(chooseScanRays(core.device, core.params)) {}

RayScene& RaySceneCache::scanScene() {
  if (!scan_scene_) scan_scene_ = std::make_unique<RayScene>(core_.device);
  RayScene& scene = *scan_scene_;
  const gpu::AccelHeader header = passes::scanSceneHeader(core_.buffers);
  if (scene.boxes.valid() && header.box_capacity == scan_header_.box_capacity)
    return scene;           // the same capacity: the build reuses every structure and buffer
  core_.stream.waitIdle();  // the scans in flight build and trace the scene being replaced
  const std::size_t bytes = passes::accelBoxesBytes(header);
  if (!scene.boxes.valid() || scene.boxes.size() < bytes) {
    scene.boxes = vk::Buffer();
    scene.boxes = vk::Buffer(core_.device, bytes + bytes / 4, /*host_visible=*/false,
                             VK_BUFFER_USAGE_ACCELERATION_STRUCTURE_BUILD_INPUT_READ_ONLY_BIT_KHR);
  }
  scan_header_ = header;
  noteSceneBytes();
  return scene;
}

void RaySceneCache::noteSceneBytes() {
  core_.buffers.setSceneBytes((ray_scene_ ? ray_scene_->deviceBytes() : 0) +
                              (scan_scene_ ? scan_scene_->deviceBytes() : 0));
}

void RaySceneCache::releaseUnderCap() {
  if (core_.buffers.maxBytes() == 0 || !ray_scene_) return;
  ray_scene_.reset();
  noteSceneBytes();
}

bool RaySceneCache::castRaySceneFits(std::size_t bytes, const std::string& what) {
  const std::size_t held = ray_scene_ ? ray_scene_->deviceBytes() : 0;
  if (core_.buffers.fits(held, bytes)) return true;
  // Dropped either way: it describes an older tree, and the walk needs none of it.
  ray_scene_.reset();
  noteSceneBytes();
  if (core_.params.cast_ray_backend == CastRayBackend::kRayTracing)
    core_.buffers.checkBudget(0, bytes,
                              what +
                                  " (CastRayBackend::kAuto answers with the walk instead when it "
                                  "does not fit)");
  ++cap_fallbacks_;
  return false;
}

void RaySceneCache::release() {
  ray_scene_.reset();
  scan_scene_.reset();
  scan_header_ = {};
  noteSceneBytes();
}

OccupancyMap::CastRayInfo RaySceneCache::castRayInfo() const {
  OccupancyMap::CastRayInfo info = ray_scene_ ? ray_scene_->info : OccupancyMap::CastRayInfo{};
  info.backend = cast_ray_backend_;
  info.cap_fallbacks = cap_fallbacks_;
  info.device_bytes = ray_scene_ ? ray_scene_->deviceBytes() : 0;
  return info;
}

VkDeviceAddress RaySceneCache::castRayScene() {
  if (cast_ray_backend_ != CastRayBackend::kRayTracing) return 0;
  if (!ray_scene_) {
    ray_scene_ = std::make_unique<RayScene>(core_.device);
    noteSceneBytes();
  }
  RayScene& scene = *ray_scene_;
  if (scene.version == core_.tree_version) return scene.boxes.address();

  // Room for every leaf slot (occupied ones), twice (sorted and unsorted); at least one box, for
  // the inactive box of an empty geometry.
  gpu::AccelHeader header{};
  header.box_capacity = static_cast<std::uint32_t>(
      std::max<std::size_t>(core_.buffers.leaf_boxes.size() / sizeof(gpu::LeafBox), 1));
  const std::size_t bytes = passes::accelBoxesBytes(header);
  // Under a cap: the boxes buffer, with what the scene holds besides, must fit first (with
  // the headroom if it fits, else exactly); the structures are checked once the counts are known.
  // A scene that does not fit is dropped (castRaySceneFits): kAuto answers with the walk (the same
  // answers), kRayTracing throws.
  const std::string what = "castRay's acceleration structure over the map's boxes";
  if (!scene.boxes.valid() || scene.boxes.size() < bytes) {
    const std::size_t others = scene.readback.size() + scene.accel.deviceBytes();
    std::size_t alloc = bytes + bytes / 4;
    if (!core_.buffers.fits(scene.deviceBytes(), others + alloc)) alloc = bytes;
    if (!castRaySceneFits(others + alloc, what + " (its boxes buffer)")) return 0;
    scene.boxes = vk::Buffer();
    scene.boxes = vk::Buffer(core_.device, alloc, /*host_visible=*/false,
                             VK_BUFFER_USAGE_ACCELERATION_STRUCTURE_BUILD_INPUT_READ_ONLY_BIT_KHR);
    noteSceneBytes();
  }

  core_.stream.begin(core_.buffers.bindings);
  core_.stream.timestamp();
  if (core_.leaf_boxes == LeafBoxes::kStale) passes::recordLeafBoxes(core_.rec);
  passes::recordAccelBoxes(core_.rec, core_.queryParams(), scene.boxes, header, scene.readback);
  core_.stream.timestamp();
  core_.stream.submitAndWait();
  core_.leaf_boxes = LeafBoxes::kCurrent;
  const double boxes_ms = spanMs(core_.stream.timestampsNs());
  std::memcpy(&header, scene.readback.mapped(), sizeof(header));
  if (core_.buffers.maxBytes() != 0) {
    const vk::BoxGeometry geometry = passes::boxGeometry(scene.boxes, header.box_count);
    const std::size_t after =
        scene.boxes.size() + scene.readback.size() + scene.accel.bytesAfterBuild({&geometry, 1});
    if (!castRaySceneFits(after, what)) return 0;
  }

  core_.stream.begin(core_.buffers.bindings);
  core_.stream.timestamp();
  try {
    passes::recordAccelBuild(core_.rec, scene.accel, scene.boxes, header);  // allocates first
  } catch (...) {
    noteSceneBytes();  // what it holds after a failed allocation
    throw;
  }
  core_.stream.timestamp();
  core_.stream.submitAndWait();
  const double build_ms = spanMs(core_.stream.timestampsNs());
  noteSceneBytes();

  scene.version = core_.tree_version;
  scene.info.builds += 1;
  scene.info.last_boxes_ms = boxes_ms;
  scene.info.last_build_ms = boxes_ms + build_ms;
  scene.info.occupied_boxes = header.box_count;
  return scene.boxes.address();
}

}  // namespace octovk
