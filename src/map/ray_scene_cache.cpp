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

// What the names of the ray-tracing values read as in messages.
const char* tracingName(CastRayBackend backend) {
  switch (backend) {
    case CastRayBackend::kRayQuery:
      return "kRayQuery";
    case CastRayBackend::kRayTracingPipeline:
      return "kRayTracingPipeline";
    default:
      return "kRayTracing";
  }
}

// The way the device traces rays for `wanted` (kRayTracing: ray queries where it has them, else a
// ray-tracing pipeline; or the one forced): kRayQuery or kRayTracingPipeline. Ray queries come
// first where both exist: on Mesa 25's lavapipe castRay and traced scans ran faster with them.
// The traced passes also need loops without a driver limit (they are not resumable); the scans'
// no memory cap (their structure is sized for the pool's capacity and built inside the scan,
// which a cap could not refuse cleanly; castRay's is checked against the cap before each build).
// Throws naming `option` and the way out, `remedy`, when one of them is missing.
CastRayBackend tracingPath(const vk::Device& device, const MapParams& params, CastRayBackend wanted,
                           const std::string& option, const std::string& remedy, bool refuse_cap) {
  const std::string name =
      option + " is " + tracingName(wanted) + ", but device '" + device.info().name + "'";
  const DeviceInfo& info = device.info();
  const bool query = wanted != CastRayBackend::kRayTracingPipeline;
  const bool pipeline = wanted != CastRayBackend::kRayQuery;
  CastRayBackend path = CastRayBackend::kWalk;
  if (query && device.rayQuery())
    path = CastRayBackend::kRayQuery;
  else if (pipeline && device.rayTracingPipeline())
    path = CastRayBackend::kRayTracingPipeline;
  if (path == CastRayBackend::kWalk) {
    const bool offer_query = query && info.ray_query;
    if (offer_query || (pipeline && info.ray_tracing_pipeline))
      throw Error(ErrorCode::kMissingFeature,
                  name + " has " + (offer_query ? "ray queries" : "ray-tracing pipelines") +
                      " but was opened with ContextOptions::enable_ray_query = false; use " +
                      remedy);
    const char* missing =
        !pipeline ? "has no ray queries (VK_KHR_acceleration_structure and VK_KHR_ray_query; "
                    "Mesa's lavapipe has them from Mesa 25)"
        : !query  ? "has no ray-tracing pipelines (VK_KHR_acceleration_structure and "
                    "VK_KHR_ray_tracing_pipeline; Mesa's lavapipe has them from Mesa 25)"
                  : "has neither ray queries nor ray-tracing pipelines "
                    "(VK_KHR_acceleration_structure with VK_KHR_ray_query or "
                    "VK_KHR_ray_tracing_pipeline; Mesa's lavapipe has both from Mesa 25)";
    throw Error(ErrorCode::kMissingFeature, name + " " + missing + "; use " + remedy);
  }
  if (device.loopLimit() != 0)
    throw Error(ErrorCode::kMissingFeature,
                name + " ends shader loops after " + std::to_string(device.loopLimit()) +
                    " iterations and the ray-tracing passes are not resumable; use " + remedy);
  if (refuse_cap && params.max_device_bytes != 0)
    throw Error(ErrorCode::kInvalidArgument,
                option + " is " + tracingName(wanted) +
                    " together with max_device_bytes: the acceleration structure is not held "
                    "under the cap; use " +
                    remedy + ", or max_device_bytes = 0");
  return path;
}

CastRayBackend chooseCastRayBackend(const vk::Device& device, const MapParams& params) {
  const CastRayBackend wanted = params.cast_ray_backend;
  if (wanted == CastRayBackend::kWalk) return CastRayBackend::kWalk;
  if (wanted == CastRayBackend::kAuto &&
      ((!device.rayQuery() && !device.rayTracingPipeline()) || device.loopLimit() != 0))
    return CastRayBackend::kWalk;
  return tracingPath(device, params,
                     wanted == CastRayBackend::kAuto ? CastRayBackend::kRayTracing : wanted,
                     "MapParams::cast_ray_backend", "CastRayBackend::kAuto or kWalk",
                     /*refuse_cap=*/false);
}

ScanRays chooseScanRays(const vk::Device& device, const MapParams& params) {
  if (params.scan_rays == ScanRays::kWalk) return ScanRays::kWalk;
  // Numbered alike (params.hpp).
  return static_cast<ScanRays>(tracingPath(
      device, params, static_cast<CastRayBackend>(params.scan_rays), "MapParams::scan_rays",
      "ScanRays::kWalk (octovk integrate --rays walk)", /*refuse_cap=*/true));
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
  // The pipeline is built before the scan's recording, which would otherwise build it.
  if (scan_rays_ == ScanRays::kRayTracingPipeline) core_.device.rayPipeline(passes::kScanRaygen);
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
  if (core_.params.cast_ray_backend != CastRayBackend::kAuto)
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

passes::TraceScene RaySceneCache::scanTrace() const {
  return {.boxes = scan_scene_ ? scan_scene_->boxes.address() : 0,
          .pipeline = scan_rays_ == ScanRays::kRayTracingPipeline};
}

passes::TraceScene RaySceneCache::castRayScene() {
  if (cast_ray_backend_ == CastRayBackend::kWalk) return {};
  const bool pipeline = cast_ray_backend_ == CastRayBackend::kRayTracingPipeline;
  // The pipeline is built before the queries' recording, which would otherwise build it.
  if (pipeline) core_.device.rayPipeline(passes::kCastRayRaygen);
  if (!ray_scene_) {
    ray_scene_ = std::make_unique<RayScene>(core_.device);
    noteSceneBytes();
  }
  RayScene& scene = *ray_scene_;
  if (scene.version == core_.tree_version) return {scene.boxes.address(), pipeline};

  // The boxes are built from the leaf boxes: where the cap has no room for them, kAuto answers
  // with the walk (the same answers), kRayTracing throws.
  try {
    core_.ensureLeafBoxes();
  } catch (const BudgetError&) {
    if (core_.params.cast_ray_backend != CastRayBackend::kAuto) throw;
    ray_scene_.reset();
    noteSceneBytes();
    ++cap_fallbacks_;
    return {};
  }
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
    if (!castRaySceneFits(others + alloc, what + " (its boxes buffer)")) return {};
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
    if (!castRaySceneFits(after, what)) return {};
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
  return {scene.boxes.address(), pipeline};
}

}  // namespace octovk
