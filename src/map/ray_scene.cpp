// castRay's ray-tracing backend on a map: which backend runs, and the lazy rebuild of the
// acceleration structure after the tree changed (two submissions: the boxes and their count,
// then the build over exactly that many boxes; no box leaves the device).
#include <algorithm>
#include <cstring>
#include <string>

#include "map/map_impl.hpp"

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

}  // namespace

CastRayBackend OccupancyMap::Impl::chooseCastRayBackend(const vk::Device& device,
                                                        const MapParams& params) {
  if (params.cast_ray_backend == CastRayBackend::kWalk) return CastRayBackend::kWalk;
  if (params.cast_ray_backend == CastRayBackend::kAuto)
    return device.rayQuery() && device.loopLimit() == 0 ? CastRayBackend::kRayTracing
                                                        : CastRayBackend::kWalk;
  requireRayTracing(device, params, "MapParams::cast_ray_backend",
                    "CastRayBackend::kAuto or kWalk", /*refuse_cap=*/false);
  return CastRayBackend::kRayTracing;
}

ScanRays OccupancyMap::Impl::chooseScanRays(const vk::Device& device, const MapParams& params) {
  if (params.scan_rays == ScanRays::kWalk) return ScanRays::kWalk;
  requireRayTracing(device, params, "MapParams::scan_rays",
                    "ScanRays::kWalk (octovk integrate --rays walk)", /*refuse_cap=*/true);
  return ScanRays::kRayTracing;
}

RayScene& OccupancyMap::Impl::scanScene() {
  if (!scan_scene_) scan_scene_ = std::make_unique<RayScene>(device_);
  RayScene& scene = *scan_scene_;
  const gpu::AccelHeader header = passes::scanSceneHeader(buffers_);
  if (scene.boxes.valid() && header.occupied_capacity == scan_header_.occupied_capacity &&
      header.unknown_capacity == scan_header_.unknown_capacity)
    return scene;      // the same capacities: the build reuses every structure and buffer
  stream_.waitIdle();  // the scans in flight build and trace the scene being replaced
  const std::size_t bytes = passes::accelBoxesBytes(header);
  if (!scene.boxes.valid() || scene.boxes.size() < bytes) {
    scene.boxes = vk::Buffer();
    scene.boxes = vk::Buffer(device_, bytes + bytes / 4, /*host_visible=*/false,
                             VK_BUFFER_USAGE_ACCELERATION_STRUCTURE_BUILD_INPUT_READ_ONLY_BIT_KHR);
  }
  scan_header_ = header;
  noteSceneBytes();
  return scene;
}

void OccupancyMap::Impl::noteSceneBytes() {
  buffers_.setSceneBytes((ray_scene_ ? ray_scene_->deviceBytes() : 0) +
                         (scan_scene_ ? scan_scene_->deviceBytes() : 0));
}

void OccupancyMap::Impl::releaseRaySceneUnderCap() {
  if (buffers_.maxBytes() == 0 || !ray_scene_) return;
  ray_scene_.reset();
  noteSceneBytes();
}

bool OccupancyMap::Impl::rayScenefits(std::size_t bytes, const std::string& what) {
  const std::size_t held = ray_scene_ ? ray_scene_->deviceBytes() : 0;
  if (buffers_.fits(held, bytes)) return true;
  // Dropped either way: it describes an older tree, and the walk needs none of it.
  ray_scene_.reset();
  noteSceneBytes();
  if (params_.cast_ray_backend == CastRayBackend::kRayTracing)
    buffers_.checkBudget(0, bytes,
                         what + " (CastRayBackend::kAuto answers with the walk instead when it "
                                "does not fit)");
  ++cap_fallbacks_;
  return false;
}

OccupancyMap::CastRayInfo OccupancyMap::Impl::castRayInfo() const {
  OccupancyMap::CastRayInfo info = ray_scene_ ? ray_scene_->info : OccupancyMap::CastRayInfo{};
  info.backend = cast_ray_backend_;
  info.cap_fallbacks = cap_fallbacks_;
  info.device_bytes = ray_scene_ ? ray_scene_->deviceBytes() : 0;
  return info;
}

namespace {
double spanMs(const std::vector<double>& ns) {
  return ns.size() >= 2 ? (ns.back() - ns.front()) * 1e-6 : 0.0;
}
}  // namespace

VkDeviceAddress OccupancyMap::Impl::rayScene() {
  if (cast_ray_backend_ != CastRayBackend::kRayTracing) return 0;
  if (!ray_scene_) {
    ray_scene_ = std::make_unique<RayScene>(device_);
    noteSceneBytes();
  }
  RayScene& scene = *ray_scene_;
  if (scene.version == tree_version_) return scene.boxes.address();

  // Room for every leaf slot (occupied ones) and 8 unknown children per block, twice (sorted and
  // unsorted); at least one box each, for the inactive box of an empty geometry.
  gpu::AccelHeader header{};
  header.occupied_capacity = static_cast<std::uint32_t>(
      std::max<std::size_t>(buffers_.leaf_boxes.size() / sizeof(gpu::LeafBox), 1));
  header.unknown_capacity =
      static_cast<std::uint32_t>(std::max<std::size_t>(std::size_t{buffers_.poolBlocks()} * 8, 1));
  const std::size_t bytes = passes::accelBoxesBytes(header);
  // Under a cap: the boxes buffer, with what the scene holds besides, must fit first (with
  // the headroom if it fits, else exactly); the structures are checked once the counts are known.
  // A scene that does not fit is dropped (rayScenefits): kAuto answers with the walk (the same
  // answers), kRayTracing throws.
  const std::string what = "castRay's acceleration structure over the map's boxes";
  if (!scene.boxes.valid() || scene.boxes.size() < bytes) {
    const std::size_t others = scene.readback.size() + scene.accel.deviceBytes();
    std::size_t alloc = bytes + bytes / 4;
    if (!buffers_.fits(scene.deviceBytes(), others + alloc)) alloc = bytes;
    if (!rayScenefits(others + alloc, what + " (its boxes buffer)")) return 0;
    scene.boxes = vk::Buffer();
    scene.boxes = vk::Buffer(device_, alloc, /*host_visible=*/false,
                             VK_BUFFER_USAGE_ACCELERATION_STRUCTURE_BUILD_INPUT_READ_ONLY_BIT_KHR);
    noteSceneBytes();
  }

  stream_.begin(buffers_.bindings);
  stream_.timestamp();
  if (leaf_boxes_dirty_) passes::recordLeafBoxes(rec_);
  passes::recordAccelBoxes(rec_, queryParams(), scene.boxes, header, scene.readback);
  stream_.timestamp();
  stream_.submitAndWait();
  leaf_boxes_dirty_ = false;
  const double boxes_ms = spanMs(stream_.timestampsNs());
  std::memcpy(&header, scene.readback.mapped(), sizeof(header));
  if (buffers_.maxBytes() != 0) {
    const auto geometries = passes::boxGeometries(scene.boxes, header, header.occupied_count,
                                                  header.unknown_count);
    const std::size_t after = scene.boxes.size() + scene.readback.size() +
                              scene.accel.bytesAfterBuild(geometries);
    if (!rayScenefits(after, what)) return 0;
  }

  stream_.begin(buffers_.bindings);
  stream_.timestamp();
  try {
    passes::recordAccelBuild(rec_, scene.accel, scene.boxes, header);  // allocates first
  } catch (...) {
    noteSceneBytes();  // what it holds after a failed allocation
    throw;
  }
  stream_.timestamp();
  stream_.submitAndWait();
  const double build_ms = spanMs(stream_.timestampsNs());
  noteSceneBytes();

  scene.version = tree_version_;
  scene.info.builds += 1;
  scene.info.last_boxes_ms = boxes_ms;
  scene.info.last_build_ms = boxes_ms + build_ms;
  scene.info.occupied_boxes = header.occupied_count;
  scene.info.unknown_boxes = header.unknown_count;
  return scene.boxes.address();
}

}  // namespace octovk
