// OccupancyMap: the map's operations, each a short sequence of recorded passes (map/passes/) and
// the host decisions between them. Buffers and their growth: map/map_buffers.cpp.
#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstring>

#include "map/context_access.hpp"
#include "map/host_memory.hpp"
#include "map/host_tree.hpp"
#include "map/map_impl.hpp"
#include "gpu/gpu_types.h"

namespace octovk {

namespace {

const MapParams& validated(const MapParams& params) {
  if (std::string why = params.validate(); !why.empty())
    throw Error(ErrorCode::kInvalidArgument, why);
  return params;
}

// Most blocks the pool may have (MapParams::max_nodes, and 2^32 nodes).
std::uint32_t blockLimit(const MapParams& params) { return poolBlockLimit(params.max_nodes); }

}  // namespace

OccupancyMap::Impl::Impl(Context& context, const MapParams& params)
    : device_owner_(ContextAccess::shared(context)),
      device_(*device_owner_),
      params_(validated(params)),
      logs_(ref::LogOddsParams::from(params)),
      stream_(device_, kFramesInFlight),
      buffers_(device_, stream_, blockLimit(params), params.max_device_bytes),
      rec_(device_, stream_, buffers_) {
  cast_ray_backend_ = chooseCastRayBackend(device_, params_);
  scan_rays_ = chooseScanRays(device_, params_);
}

OccupancyMap::Impl::~Impl() {
  try {
    stream_.waitIdle();  // the buffers go before the stream: no scan may still use them
  } catch (...) {
    // a lost device: nothing left to wait for
  }
}

gpu::ScanParams OccupancyMap::Impl::scanParams(const Eigen::Vector3f& origin, const Pose* pose,
                                               double max_range, std::size_t count) const {
  gpu::ScanParams sp{};
  sp.resolution = params_.resolution;
  sp.resolution_factor = 1.0 / params_.resolution;
  sp.max_range = max_range;
  sp.origin_x = origin.x();
  sp.origin_y = origin.y();
  sp.origin_z = origin.z();
  sp.prob_hit_log = logs_.hit;
  sp.prob_miss_log = logs_.miss;
  sp.clamp_min_log = logs_.clamp_min;
  sp.clamp_max_log = logs_.clamp_max;
  sp.point_count = static_cast<std::uint32_t>(count);
  sp.hash_capacity = 1u << buffers_.hashLog2();
  sp.hash_log2 = buffers_.hashLog2();
  sp.endpoint_capacity = 1u << buffers_.endpointLog2();
  sp.endpoint_log2 = buffers_.endpointLog2();
  sp.active_capacity = static_cast<std::uint32_t>(buffers_.activeCapacity());
  sp.cell_capacity = (1u << buffers_.hashLog2()) * kCellsPerBrickSlot;
  sp.occupancy_log = logs_.occupancy;
  if (pose) {
    sp.rot_u = pose->rotation.w();
    sp.rot_x = pose->rotation.x();
    sp.rot_y = pose->rotation.y();
    sp.rot_z = pose->rotation.z();
    sp.trans_x = pose->translation.x();
    sp.trans_y = pose->translation.y();
    sp.trans_z = pose->translation.z();
  }
  return sp;
}

gpu::PoolState OccupancyMap::Impl::readPool() {
  flush();  // sees every scan submitted before it
  stream_.begin(buffers_.bindings);
  passes::recordReadback(rec_);
  stream_.submitAndWait();
  gpu::ScanCounters counters;
  gpu::PoolState pool;
  passes::readBack(buffers_, stream_.frame(), counters, pool);
  return pool;
}

void OccupancyMap::Impl::refreshLeafBoxes() {
  flush();  // sees every scan submitted before it
  if (!leaf_boxes_dirty_) return;
  stream_.begin(buffers_.bindings);
  passes::recordLeafBoxes(rec_);
  stream_.submitAndWait();
  leaf_boxes_dirty_ = false;
}

// ---- queries ---------------------------------------------------------------------------------

void OccupancyMap::Impl::queryOnDevice(bool rays, VkBuffer in, VkDeviceSize in_offset,
                                       VkDeviceSize in_size, VkBuffer out, VkDeviceSize out_offset,
                                       VkDeviceSize out_size, std::uint32_t count) {
  flush();  // sees every scan submitted before it
  const VkDeviceSize align = device_.storageOffsetAlignment();
  if (in == VK_NULL_HANDLE || out == VK_NULL_HANDLE)
    throw Error(ErrorCode::kInvalidArgument, "query on device: a buffer is VK_NULL_HANDLE");
  if (in_offset % align != 0 || out_offset % align != 0)
    throw Error(ErrorCode::kInvalidArgument,
                "query on device: buffer offsets must be multiples of " + std::to_string(align) +
                    " (minStorageBufferOffsetAlignment)");
  if (count == 0) return;
  const VkDeviceAddress ray_scene = rays ? rayScene() : 0;
  // The map's own query buffers are swapped for the caller's ranges for this one submission.
  buffers_.bindings.updateRange(gpu::kBindQueryIn, in, in_offset, in_size);
  buffers_.bindings.updateRange(gpu::kBindQueryOut, out, out_offset, out_size);
  try {
    const gpu::ScanParams sp = queryParams();
    stream_.begin(buffers_.bindings);
    stream_.update(buffers_.params, &sp, sizeof(sp));
    stream_.barrier();
    if (rays && ray_scene)
      passes::recordCastRaysRt(rec_, ray_scene, {0, count}, {0, count});
    else if (rays)
      passes::recordCastRays(rec_, count, passes::firstRayState(count));
    else
      passes::recordLookups(rec_, count, 0, 0);
    stream_.submitAndWait();
  } catch (...) {
    buffers_.rebind();
    throw;
  }
  buffers_.rebind();
}

QueryResults OccupancyMap::Impl::runQueries(const QueryRequest& q) {
  flush();  // sees every scan submitted before it
  if (q.rays.empty() && q.lookups.empty()) return {};
  if (q.rays.size() + q.lookups.size() > 0x7FFFFFFFu)
    throw Error(ErrorCode::kInvalidArgument, "queries: more than 2^31 queries in one batch");
  // Unfinished castRay walks are continued by indirect dispatches of one group per 64 rays.
  const std::size_t max_rays = std::size_t{device_.maxGroupsX()} * gpu::kWorkgroupSize;
  if (q.rays.size() > max_rays)
    throw Error(ErrorCode::kInvalidArgument,
                "castRays: " + std::to_string(q.rays.size()) + " rays in one batch; the device '" +
                    device_.info().name + "' takes at most " + std::to_string(max_rays) +
                    " (maxComputeWorkGroupCount x 64); split the batch");
  const VkDeviceAddress ray_scene = q.rays.empty() ? 0 : rayScene();
  std::uint32_t stop_rays = 0;
  const std::vector<std::uint32_t> order = passes::rayOrder(q.rays, params_.resolution, stop_rays);
  passes::stageQueries(buffers_, q, order);
  stream_.begin(buffers_.bindings);
  passes::recordQueries(rec_, queryParams(), q, ray_scene, stop_rays);
  stream_.submitAndWait();
  QueryResults out;
  passes::collectQueries(buffers_, q, order, out);
  return out;
}

std::vector<OccupancyMap::LeafBoxHost> OccupancyMap::Impl::leavesInBox(const Eigen::Vector3f& min,
                                                                       const Eigen::Vector3f& max,
                                                                       bool occupied_only) {
  flush();  // sees every scan submitted before it
  gpu::BoxQuery box{};
  const double factor = 1.0 / params_.resolution;
  if (!ref::coordToKeyChecked(factor, min.x(), box.min_x) ||
      !ref::coordToKeyChecked(factor, min.y(), box.min_y) ||
      !ref::coordToKeyChecked(factor, min.z(), box.min_z) ||
      !ref::coordToKeyChecked(factor, max.x(), box.max_x) ||
      !ref::coordToKeyChecked(factor, max.y(), box.max_y) ||
      !ref::coordToKeyChecked(factor, max.z(), box.max_z))
    return {};  // as OctoMap's iterator: a corner outside the map gives no leaves
  box.occupied_only = occupied_only ? 1u : 0u;
  buffers_.ensureQueries(sizeof(box),
                         std::size_t{buffers_.poolBlocks()} * 8 * sizeof(gpu::LeafBox));
  stream_.begin(buffers_.bindings);
  passes::recordLeavesInBox(rec_, queryParams(), box);
  passes::recordReadback(rec_);
  stream_.submitAndWait();
  gpu::ScanCounters counters;
  gpu::PoolState pool;
  passes::readBack(buffers_, stream_.frame(), counters, pool);
  std::vector<LeafBoxHost> out(counters.query_results);
  if (out.empty()) return out;
  const std::size_t bytes = out.size() * sizeof(gpu::LeafBox);
  stream_.begin(buffers_.bindings);
  stream_.copy(buffers_.query_out, buffers_.query_staging_out, bytes);
  stream_.submitAndWait();
  static_assert(sizeof(LeafBoxHost) == sizeof(gpu::LeafBox));
  std::memcpy(out.data(), buffers_.query_staging_out.mapped(), bytes);
  return out;
}

// ---- explicit transfers ----------------------------------------------------------------------

HostTree OccupancyMap::Impl::download() {
  flush();  // sees every scan submitted before it
  const gpu::PoolState pool = readPool();
  const std::size_t count = std::size_t{pool.bump} * 8;
  vk::Buffer staging(device_, count * sizeof(gpu::Node), true);
  stream_.begin(buffers_.bindings);
  stream_.copy(buffers_.nodes, staging, count * sizeof(gpu::Node));
  stream_.submitAndWait();
  return hostTreeFromPool({static_cast<const gpu::Node*>(staging.mapped()), count}, pool);
}

void OccupancyMap::Impl::upload(const HostTree& tree) {
  flush();  // sees every scan submitted before it
  const std::size_t blocks = std::max<std::size_t>((tree.nodes.size() + 7) / 8, 1);
  if (blocks > buffers_.blockLimit())
    throw Error(ErrorCode::kOutOfDeviceMemory,
                "upload: the tree needs " + std::to_string(blocks * 8) +
                    " pool nodes, over the limit of " +
                    std::to_string(buffers_.blockLimit() * 8ull) +
                    " (MapParams::max_nodes or 2^32); the map is unchanged");
  const PoolImage image = poolImageFromTree(tree);
  // The staging first: once the pool is replaced (its old nodes not copied) nothing else may
  // fail, or the map would be neither the old tree nor the new one.
  const std::size_t node_bytes = image.nodes.size() * sizeof(gpu::Node);
  const std::size_t meta_bytes = image.parents.size() * sizeof(std::uint32_t);
  const std::size_t free_bytes = image.free_blocks.size() * sizeof(std::uint32_t);
  vk::Buffer staging(device_, node_bytes + meta_bytes + free_bytes, true);
  auto* bytes = static_cast<unsigned char*>(staging.mapped());
  std::memcpy(bytes, image.nodes.data(), node_bytes);
  std::memcpy(bytes + node_bytes, image.parents.data(), meta_bytes);
  if (free_bytes)
    std::memcpy(bytes + node_bytes + meta_bytes, image.free_blocks.data(), free_bytes);
  releaseRaySceneUnderCap();
  const std::uint32_t capacity = std::min<std::uint32_t>(
      buffers_.blockLimit(),
      std::max<std::uint32_t>(image.blocks + image.blocks / 4, kInitialBlocks));
  if (capacity > buffers_.poolBlocks())
    buffers_.allocatePoolAtLeast(capacity, std::max<std::uint32_t>(image.blocks, 2),
                                 /*copy_old=*/false);
  gpu::PoolState pool{};
  pool.bump = image.blocks;
  pool.capacity = buffers_.poolBlocks();
  pool.free_count = static_cast<std::uint32_t>(image.free_blocks.size());
  pool.root_exists = image.root_exists ? 1u : 0u;
  pool.live_nodes = image.live_nodes;

  const gpu::ScanParams sp = queryParams();
  stream_.begin(buffers_.bindings);
  stream_.update(buffers_.params, &sp, sizeof(sp));
  stream_.update(buffers_.pool, &pool, sizeof(pool));
  stream_.copy(staging, buffers_.nodes, node_bytes);
  stream_.copy(staging, buffers_.block_parents, meta_bytes, node_bytes);
  stream_.copy(staging, buffers_.free_stack, free_bytes, node_bytes + meta_bytes);
  stream_.barrier();
  passes::recordLeafBoxes(rec_);
  stream_.submitAndWait();
  leaf_boxes_dirty_ = false;
  ++tree_version_;  // a new tree: the ray scene is rebuilt before the next castRays
}

OccupancyMap::DeviceBytes OccupancyMap::Impl::deviceBytesByUse() const {
  const BufferBytes b = buffers_.bytesByUse();  // the scenes are in b.queries
  return {.pool = b.pool,
          .leaf_boxes = b.leaf_boxes,
          .scratch = b.scratch,
          .queries = b.queries,
          .distance_fields = b.fields};
}

void OccupancyMap::Impl::trim() {
  flush();  // sees every scan submitted before it
  buffers_.releaseScratch();
  buffers_.releaseQueries();
  hash_guess_tried_ = 0;
  ray_scene_.reset();
  scan_scene_.reset();
  scan_header_ = {};
  noteSceneBytes();
}

std::vector<OccupancyMap::LeafBoxHost> OccupancyMap::Impl::downloadLeafBoxes() {
  flush();  // sees every scan submitted before it
  refreshLeafBoxes();
  const gpu::PoolState pool = readPool();
  std::vector<LeafBoxHost> out(pool.leaf_count);
  if (out.empty()) return out;
  const std::size_t bytes = out.size() * sizeof(gpu::LeafBox);
  vk::Buffer staging(device_, bytes, true);
  stream_.begin(buffers_.bindings);
  stream_.copy(buffers_.leaf_boxes, staging, bytes);
  stream_.submitAndWait();
  static_assert(sizeof(LeafBoxHost) == sizeof(gpu::LeafBox));
  std::memcpy(out.data(), staging.mapped(), bytes);
  return out;
}

// ---- public face -----------------------------------------------------------------------------

OccupancyMap::OccupancyMap(Context& context, const MapParams& params)
    : impl_(hostMemoryGuard("OccupancyMap",
                            [&] { return std::make_unique<Impl>(context, params); })) {}
OccupancyMap::~OccupancyMap() = default;
OccupancyMap::OccupancyMap(OccupancyMap&&) noexcept = default;
OccupancyMap& OccupancyMap::operator=(OccupancyMap&&) noexcept = default;

OccupancyMap::Impl& OccupancyMap::self() const {
  if (!impl_)
    throw Error(ErrorCode::kInvalidArgument,
                "OccupancyMap: this map was moved from and holds nothing; assign a map to it "
                "before using it again");
  return *impl_;
}

// The noexcept observers answer for a moved-from map as for an empty one.
const MapParams& OccupancyMap::params() const noexcept {
  static const MapParams kNone;
  return impl_ ? impl_->params() : kNone;
}

ScanStats OccupancyMap::insertPointCloud(std::span<const Eigen::Vector3f> points_world,
                                         const Eigen::Vector3f& origin_world, double max_range_m,
                                         bool discretize) {
  return hostMemoryGuard("insertPointCloud", [&] {
    return self().insert({.points = points_world}, origin_world, nullptr, max_range_m, discretize);
  });
}

ScanStats OccupancyMap::insertPointCloud(std::span<const Eigen::Vector3f> points_sensor,
                                         const Eigen::Vector3f& origin_sensor,
                                         const Pose& T_world_sensor, double max_range_m,
                                         bool discretize) {
  return hostMemoryGuard("insertPointCloud", [&] {
    const Eigen::Vector3f origin_world = T_world_sensor.transform(origin_sensor);
    return self().insert({.points = points_sensor}, origin_world, &T_world_sensor, max_range_m,
                         discretize);
  });
}

ScanStats OccupancyMap::insertDepthImage(const DepthImage& image, const Pose& T_world_camera,
                                         double max_range_m, const Eigen::Vector3f& origin_camera,
                                         bool discretize) {
  return hostMemoryGuard("insertDepthImage", [&] {
    if (std::string why = image.validate(); !why.empty())
      throw Error(ErrorCode::kInvalidArgument, "insertDepthImage: " + why);
    const Eigen::Vector3f origin_world = T_world_camera.transform(origin_camera);
    return self().insert({.depth = &image}, origin_world, &T_world_camera, max_range_m, discretize);
  });
}

ScanStats OccupancyMap::insertPointCloud(std::span<const Eigen::Vector3f> points_world,
                                         const Eigen::Vector3f& origin_world, double max_range_m,
                                         bool discretize, const QueryRequest& queries,
                                         QueryResults& results) {
  return hostMemoryGuard("insertPointCloud", [&] {
    return self().insert({.points = points_world}, origin_world, nullptr, max_range_m, discretize,
                         &queries, &results);
  });
}

ScanTicket OccupancyMap::submitPointCloud(std::span<const Eigen::Vector3f> points_world,
                                          const Eigen::Vector3f& origin_world, double max_range_m,
                                          bool discretize) {
  return hostMemoryGuard("submitPointCloud", [&] {
    return self().submit({.points = points_world}, origin_world, nullptr, max_range_m, discretize);
  });
}

ScanTicket OccupancyMap::submitPointCloud(std::span<const Eigen::Vector3f> points_sensor,
                                          const Eigen::Vector3f& origin_sensor,
                                          const Pose& T_world_sensor, double max_range_m,
                                          bool discretize) {
  return hostMemoryGuard("submitPointCloud", [&] {
    const Eigen::Vector3f origin_world = T_world_sensor.transform(origin_sensor);
    return self().submit({.points = points_sensor}, origin_world, &T_world_sensor, max_range_m,
                         discretize);
  });
}

ScanTicket OccupancyMap::submitDepthImage(const DepthImage& image, const Pose& T_world_camera,
                                          double max_range_m, const Eigen::Vector3f& origin_camera,
                                          bool discretize) {
  return hostMemoryGuard("submitDepthImage", [&] {
    if (std::string why = image.validate(); !why.empty())
      throw Error(ErrorCode::kInvalidArgument, "submitDepthImage: " + why);
    const Eigen::Vector3f origin_world = T_world_camera.transform(origin_camera);
    return self().submit({.depth = &image}, origin_world, &T_world_camera, max_range_m, discretize);
  });
}

void OccupancyMap::flush() {
  return hostMemoryGuard("flush", [&] { self().flush(); });
}

bool OccupancyMap::finished(ScanTicket ticket) {
  return hostMemoryGuard("finished", [&] { return self().finished(ticket); });
}

std::vector<ScanStats> OccupancyMap::takeScanStats() {
  return hostMemoryGuard("takeScanStats", [&] { return self().takeStats(); });
}

std::size_t OccupancyMap::scansInFlight() const noexcept {
  return impl_ ? impl_->scansInFlight() : 0;
}

OccupancyMap::SyncCounts OccupancyMap::syncCounts() const noexcept {
  return impl_ ? impl_->syncCounts() : SyncCounts{};
}

std::vector<Lookup> OccupancyMap::search(std::span<const Eigen::Vector3f> points) const {
  return hostMemoryGuard("search", [&] { return self().runQueries({points, {}}).lookups; });
}

std::vector<RayHit> OccupancyMap::castRays(std::span<const Ray> rays) const {
  return hostMemoryGuard("castRays", [&] { return self().runQueries({{}, rays}).rays; });
}

std::vector<OccupancyMap::LeafBoxHost> OccupancyMap::leavesInBox(const Eigen::Vector3f& min,
                                                                 const Eigen::Vector3f& max,
                                                                 bool occupied_only) const {
  return hostMemoryGuard("leavesInBox",
                         [&] { return self().leavesInBox(min, max, occupied_only); });
}

std::size_t OccupancyMap::nodeCount() const {
  return hostMemoryGuard("nodeCount", [&] {
    const gpu::PoolState pool = self().readPool();
    return pool.root_exists ? pool.live_nodes : 0;
  });
}

std::size_t OccupancyMap::leafCount() const {
  return hostMemoryGuard("leafCount", [&] {
    self().refreshLeafBoxes();
    return self().readPool().leaf_count;
  });
}

void OccupancyMap::setLeafBoxesEveryScan(bool every_scan) {
  return hostMemoryGuard("setLeafBoxesEveryScan",
                         [&] { self().setLeafBoxesEveryScan(every_scan); });
}

std::size_t OccupancyMap::deviceBytes() const {
  return hostMemoryGuard("deviceBytes", [&] { return self().deviceBytes(); });
}

OccupancyMap::CastRayInfo OccupancyMap::castRayInfo() const {
  return hostMemoryGuard("castRayInfo", [&] { return self().castRayInfo(); });
}

std::size_t OccupancyMap::poolBytes() const {
  return hostMemoryGuard("poolBytes", [&] { return self().poolBytes(); });
}

OccupancyMap::DeviceBytes OccupancyMap::deviceBytesByUse() const {
  return hostMemoryGuard("deviceBytesByUse", [&] { return self().deviceBytesByUse(); });
}

std::size_t OccupancyMap::scratchBytes() const {
  return hostMemoryGuard("scratchBytes", [&] { return self().deviceBytesByUse().scratch; });
}

void OccupancyMap::trim() {
  return hostMemoryGuard("trim", [&] { self().trim(); });
}

HostTree OccupancyMap::download() const {
  return hostMemoryGuard("download", [&] { return self().download(); });
}

void OccupancyMap::upload(const HostTree& tree) {
  return hostMemoryGuard("upload", [&] { self().upload(tree); });
}

std::vector<OccupancyMap::LeafBoxHost> OccupancyMap::downloadLeafBoxes() const {
  return hostMemoryGuard("downloadLeafBoxes", [&] { return self().downloadLeafBoxes(); });
}

}  // namespace octovk
