// OccupancyMap: the map's operations, each a short sequence of recorded passes (map/passes/) and
// the host decisions between them. Buffers and their growth: map/map_buffers.cpp.
#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstring>

#include "map/host_tree.hpp"
#include "map/map_impl.hpp"
#include "octovk/gpu_types.h"

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
    : device_(context.vulkan()),
      params_(validated(params)),
      logs_(ref::LogOddsParams::from(params)),
      stream_(device_),
      buffers_(device_, stream_, blockLimit(params), params.max_device_bytes),
      rec_(device_, stream_, buffers_) {
  cast_ray_backend_ = chooseCastRayBackend(device_, params_);
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
  stream_.begin(buffers_.bindings);
  passes::recordReadback(rec_);
  stream_.submitAndWait();
  gpu::ScanCounters counters;
  gpu::PoolState pool;
  passes::readBack(buffers_, counters, pool);
  return pool;
}

void OccupancyMap::Impl::refreshLeafBoxes() {
  if (!leaf_boxes_dirty_) return;
  stream_.begin(buffers_.bindings);
  passes::recordLeafBoxes(rec_);
  stream_.submitAndWait();
  leaf_boxes_dirty_ = false;
}

// ---- one scan --------------------------------------------------------------------------------

void OccupancyMap::Impl::checkScan(std::size_t count, const Eigen::Vector3f& origin,
                                   const Pose* pose, double max_range) const {
  if (!origin.allFinite())
    throw Error(ErrorCode::kInvalidArgument,
                "insertPointCloud: the sensor origin is not finite (NaN or inf); pass the "
                "sensor position in metres");
  if (pose && (!pose->translation.allFinite() || !pose->rotation.coeffs().allFinite()))
    throw Error(ErrorCode::kInvalidArgument,
                "insertPointCloud: the sensor pose is not finite (NaN or inf)");
  if (std::isnan(max_range))
    throw Error(ErrorCode::kInvalidArgument,
                "insertPointCloud: max_range is NaN; use a negative value for unlimited range");
  // Lists of points and cells are walked by indirect dispatches of one group per 64 entries.
  const std::size_t max_items =
      std::min<std::size_t>(0x7FFFFFFFu, std::size_t{device_.maxGroupsX()} * gpu::kWorkgroupSize);
  if (count > max_items)
    throw Error(ErrorCode::kInvalidArgument,
                "insertPointCloud: " + std::to_string(count) + " points in one scan; the device '" +
                    device_.info().name + "' takes at most " + std::to_string(max_items) +
                    " (maxComputeWorkGroupCount x 64); split the scan");
}

// Grows what a scan that was not applied found short (throws, map unchanged, where it may not).
void OccupancyMap::Impl::growForRetry(const gpu::ScanCounters& counters,
                                      const gpu::PoolState& pool) {
  const std::uint32_t status = counters.status;
  if (status & gpu::kStatusRayCut)
    throw Error(ErrorCode::kMissingFeature,
                "insertPointCloud: a ray crosses more cells than octovk walks on the device '" +
                    device_.info().name +
                    "' (about 196,000 steps); the map is unchanged. Use a coarser resolution "
                    "or a max range");
  // A full set stopped classify early: its other counts are partial, so only the set grows.
  if (status & gpu::kStatusHashFull) {
    if (buffers_.hashLog2() + 2 > kMaxHashLog2)
      throw Error(ErrorCode::kOutOfDeviceMemory,
                  "insertPointCloud: a scan touches more than 2^25 bricks of 4x4x4 cells; the "
                  "map is unchanged. Split the scan");
    buffers_.allocateHash(buffers_.hashLog2() + 2);
    return;
  }
  if (status & gpu::kStatusEndpointHashFull) {
    if (buffers_.endpointLog2() >= 30)
      throw Error(ErrorCode::kOutOfDeviceMemory,
                  "insertPointCloud: a scan creates more than 2^29 blocks; split the scan");
    buffers_.allocateEndpoints(buffers_.endpointLog2() + 2);
    return;
  }
  if (status & gpu::kStatusPoolShort) reservePool(counters.new_blocks, pool, /*ahead=*/false);
  const std::uint32_t active = counters.active_cells + counters.leaf_cells;
  if (status & gpu::kStatusListsShort)
    buffers_.allocateLists(std::size_t{1} << nextPow2Log2(active));
}

// Makes room in the pool for `blocks` more blocks (exactly classify's count). Ahead of need (for
// the next scans) a refusal is not an error: the scan that needs the room will report it.
void OccupancyMap::Impl::reservePool(std::uint64_t blocks, const gpu::PoolState& pool,
                                     bool ahead) {
  const std::uint64_t available = std::uint64_t{pool.capacity} - pool.bump + pool.free_count;
  if (blocks <= available) return;
  const std::uint64_t needed = std::uint64_t{pool.bump} + blocks - pool.free_count + 1;
  const std::uint64_t limit = buffers_.blockLimit();
  if (needed > limit) {
    if (ahead) return;
    throw Error(ErrorCode::kOutOfDeviceMemory,
                "insertPointCloud: the scan needs a node pool of " + std::to_string(needed * 8) +
                    " nodes, over the limit of " + std::to_string(limit * 8) +
                    " (MapParams::max_nodes or 2^32); the map is unchanged");
  }
  const std::uint64_t target = std::min<std::uint64_t>(
      limit, std::max<std::uint64_t>(needed, std::uint64_t{buffers_.poolBlocks()} +
                                                 buffers_.poolBlocks() / 2));
  try {
    buffers_.allocatePoolAtLeast(static_cast<std::uint32_t>(target),
                                 static_cast<std::uint32_t>(needed), /*copy_old=*/true);
  } catch (const BudgetError&) {
    if (ahead) return;
    throw;  // names the cap
  } catch (const Error& e) {
    if (ahead) return;
    throw Error(ErrorCode::kOutOfDeviceMemory,
                std::string("insertPointCloud: the device has no room to grow the node pool "
                            "to ") +
                    std::to_string(target * 8) + " nodes; the map is unchanged (" + e.what() +
                    ")");
  }
}

passes::RayKeysInput OccupancyMap::Impl::stage(const ScanSource& source) {
  passes::RayKeysInput in;
  in.source = buffers_.upload.handle();
  if (!source.depth) {
    static_assert(sizeof(Eigen::Vector3f) == 3 * sizeof(float));
    in.bytes = source.count() * sizeof(Eigen::Vector3f);
    if (source.device != VK_NULL_HANDLE) {
      in.source = source.device;
      in.source_offset = source.device_offset;
    } else {
      std::memcpy(buffers_.upload.mapped(), source.points.data(), in.bytes);
    }
    return in;
  }
  const DepthImage& image = *source.depth;
  const bool u16 = image.encoding == DepthImage::Encoding::kUint16;
  in.unproject = true;
  in.camera = {image.fx,    image.fy,     image.cx,
               image.cy,    image.depth_scale, image.width,
               image.height, u16 ? gpu::kDepthUint16 : gpu::kDepthFloat32};
  const std::size_t pixel_bytes = source.count() * (u16 ? 2 : 4);
  in.bytes = (pixel_bytes + 3) & ~std::size_t{3};  // whole words: the shader reads words
  buffers_.ensureDepth(sizeof(gpu::DepthCamera) + in.bytes);
  if (source.device != VK_NULL_HANDLE) {
    in.source = source.device;
    in.source_offset = source.device_offset;
    in.bytes = pixel_bytes;  // the caller's range may end there; the last half word is unused
  } else {
    in.source = buffers_.upload.handle();
    auto* upload = static_cast<unsigned char*>(buffers_.upload.mapped());
    std::memcpy(upload, image.pixels, pixel_bytes);
    std::memset(upload + pixel_bytes, 0, in.bytes - pixel_bytes);
  }
  return in;
}

// A scan is one submission: every stage, the device deciding between them (tree_gate) whether
// it fits, then the queries and a readback. The host waits for it once; a scan the device did not
// apply (a set, the pool or the lists too small) left the map as it was, and runs again after
// the host grew what was short. After a scan, room for another like it is made ahead.
ScanStats OccupancyMap::Impl::insert(const ScanSource& source, const Eigen::Vector3f& origin,
                                     const Pose* pose, double max_range, bool discretize,
                                     const QueryRequest* queries, QueryResults* results) {
  const auto start = std::chrono::steady_clock::now();
  const std::size_t count = source.count();
  checkScan(count, origin, pose, max_range);
  ScanStats stats;
  stats.points = count;
  gpu::ScanCounters counters{};
  gpu::PoolState pool{};
  if (count == 0) {
    if (queries) *results = runQueries(*queries);
    pool = readPool();
    stats.nodes = pool.root_exists ? pool.live_nodes : 0;
    return stats;
  }
  buffers_.ensurePoints(count);
  // First guess of the cell set's size: 4 brick slots (16 cells) per point (a 320x240 depth view
  // at 0.05 m touches 0.6-1 million cells in about a quarter as many bricks), at most 2^20 brick
  // slots; it grows (and the scan is redone) when a scan needs more, and keeps its size for the
  // next scans.
  const std::uint32_t guess = std::min<std::uint32_t>(nextPow2Log2(count * 4), 20);
  buffers_.growHashToward(guess);  // as far as MapParams::max_device_bytes allows
  passes::RayKeysInput input = stage(source);
  input.transform = pose != nullptr;
  input.discretize = discretize;
  if (queries) passes::stageQueries(buffers_, *queries);
  // Until this scan is applied, the sets' contents are not known to be only its listed slots.
  input.fill_sets = buffers_.setsNeedFill();
  input.filled_bricks = filled_bricks_;
  input.filled_endpoints = filled_endpoints_;
  buffers_.setSetsNeedFill(true);
  // A caller's semaphore guards its buffer: the first submission that reads it waits for it.
  if (source.wait != VK_NULL_HANDLE) stream_.waitBeforeNextSubmit(source.wait, source.wait_value);
  try {
    for (;; input.fill_sets = true) {
      const gpu::ScanParams sp = scanParams(origin, pose, max_range, count);  // sizes may grow
      stream_.begin(buffers_.bindings);
      passes::recordRayKeys(rec_, sp, input);
      passes::recordClassify(rec_, discretize, sp.point_count);
      passes::recordTreeUpdate(rec_);
      passes::recordPrune(rec_);
      if (leaf_boxes_every_scan_) passes::recordLeafBoxes(rec_);
      if (queries)
        passes::recordQueries(rec_, queryParams(), *queries);
      passes::recordReadback(rec_);
      stream_.submitAndWait();
      ++stats.cell_set_attempts;
      passes::readBack(buffers_, counters, pool);
      if (!(counters.status & gpu::kStatusNotApplied)) break;
      growForRetry(counters, pool);
    }
  } catch (...) {
    stream_.waitBeforeNextSubmit(VK_NULL_HANDLE, 0);  // not for some later submission
    throw;
  }
  if (counters.status & gpu::kStatusPoolFull)
    throw Error(ErrorCode::kVulkan,
                "internal error: the node pool ran out during a scan despite its size check; "
                "please report this with the input");
  if (const auto t = stream_.timestampsNs(); t.size() >= 6) {
    stats.device.upload_ms = (t[1] - t[0]) * 1e-6;
    stats.device.ray_keys_ms = (t[2] - t[1]) * 1e-6;
    stats.device.classify_ms = (t[3] - t[2]) * 1e-6;
    stats.device.tree_update_ms = (t[4] - t[3]) * 1e-6;
    stats.device.prune_ms = (t[5] - t[4]) * 1e-6;
    if (t.size() >= 7) stats.device.leaf_boxes_ms = (t[6] - t[5]) * 1e-6;
  }
  if (queries) *results = passes::collectQueries(buffers_, *queries);
  stats.skipped_no_depth = counters.no_depth;
  stats.skipped_nonfinite = counters.skipped_nonfinite - counters.no_depth;  // NaN points
  stats.skipped_outside = counters.skipped_outside;
  stats.free_cells = counters.free_cells;
  stats.occupied_cells = counters.occupied_cells;
  stats.aborted_cells = counters.aborted;
  const std::uint32_t active = counters.active_cells + counters.leaf_cells;
  if (active > 0) leaf_boxes_dirty_ = !leaf_boxes_every_scan_;
  if (active > 0) ++tree_version_;  // the ray scene is rebuilt before the next castRays
  filled_bricks_ = counters.brick_entries;
  filled_endpoints_ = counters.new_blocks;
  buffers_.setSetsNeedFill(false);
  stats.nodes = pool.root_exists ? pool.live_nodes : 0;
  // Room for another scan like this one, so that the next is not run twice.
  reservePool(counters.new_blocks, pool, /*ahead=*/true);
  if (active > buffers_.activeCapacity() / 2) {
    try {
      buffers_.allocateLists(std::size_t{1} << nextPow2Log2(std::size_t{active} * 2));
    } catch (const BudgetError&) {
      // ahead of need: the cap leaves no room, and the scan that needs it will say so
    }
  }
  buffers_.noteScan(count);  // may release scratch an outsized scan grew
  stats.wall_ms =
      std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - start).count();
  return stats;
}

// ---- queries ---------------------------------------------------------------------------------

void OccupancyMap::Impl::queryOnDevice(bool rays, VkBuffer in, VkDeviceSize in_offset,
                                       VkDeviceSize in_size, VkBuffer out, VkDeviceSize out_offset,
                                       VkDeviceSize out_size, std::uint32_t count) {
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
  const std::vector<std::uint32_t> order =
      ray_scene ? passes::rayOrderByKind(q.rays, stop_rays) : std::vector<std::uint32_t>{};
  passes::stageQueries(buffers_, q, order);
  stream_.begin(buffers_.bindings);
  passes::recordQueries(rec_, queryParams(), q, ray_scene, stop_rays);
  stream_.submitAndWait();
  return passes::collectQueries(buffers_, q, order);
}

std::vector<OccupancyMap::LeafBoxHost> OccupancyMap::Impl::leavesInBox(const Eigen::Vector3f& min,
                                                                       const Eigen::Vector3f& max,
                                                                       bool occupied_only) {
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
  buffers_.ensureQueries(sizeof(box), std::size_t{buffers_.poolBlocks()} * 8 * sizeof(gpu::LeafBox));
  stream_.begin(buffers_.bindings);
  passes::recordLeavesInBox(rec_, queryParams(), box);
  passes::recordReadback(rec_);
  stream_.submitAndWait();
  gpu::ScanCounters counters;
  gpu::PoolState pool;
  passes::readBack(buffers_, counters, pool);
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
  const gpu::PoolState pool = readPool();
  const std::size_t count = std::size_t{pool.bump} * 8;
  vk::Buffer staging(device_, count * sizeof(gpu::Node), true);
  stream_.begin(buffers_.bindings);
  stream_.copy(buffers_.nodes, staging, count * sizeof(gpu::Node));
  stream_.submitAndWait();
  return hostTreeFromPool({static_cast<const gpu::Node*>(staging.mapped()), count}, pool);
}

void OccupancyMap::Impl::upload(const HostTree& tree) {
  const std::size_t blocks = std::max<std::size_t>((tree.nodes.size() + 7) / 8, 1);
  if (blocks > buffers_.blockLimit())
    throw Error(ErrorCode::kOutOfDeviceMemory,
                "upload: the tree needs " + std::to_string(blocks * 8) +
                    " pool nodes, over the limit of " +
                    std::to_string(buffers_.blockLimit() * 8ull) +
                    " (MapParams::max_nodes or 2^32); the map is unchanged");
  const PoolImage image = poolImageFromTree(tree);
  const std::uint32_t capacity = std::min<std::uint32_t>(
      buffers_.blockLimit(), std::max<std::uint32_t>(image.blocks + image.blocks / 4, kInitialBlocks));
  if (capacity > buffers_.poolBlocks())
    buffers_.allocatePoolAtLeast(capacity, std::max<std::uint32_t>(image.blocks, 2),
                                 /*copy_old=*/false);
  gpu::PoolState pool{};
  pool.bump = image.blocks;
  pool.capacity = buffers_.poolBlocks();
  pool.free_count = static_cast<std::uint32_t>(image.free_blocks.size());
  pool.root_exists = image.root_exists ? 1u : 0u;
  pool.live_nodes = image.live_nodes;

  const std::size_t node_bytes = image.nodes.size() * sizeof(gpu::Node);
  const std::size_t meta_bytes = image.parents.size() * sizeof(std::uint32_t);
  const std::size_t free_bytes = image.free_blocks.size() * sizeof(std::uint32_t);
  vk::Buffer staging(device_, node_bytes + meta_bytes + free_bytes, true);
  auto* bytes = static_cast<unsigned char*>(staging.mapped());
  std::memcpy(bytes, image.nodes.data(), node_bytes);
  std::memcpy(bytes + node_bytes, image.parents.data(), meta_bytes);
  if (free_bytes) std::memcpy(bytes + node_bytes + meta_bytes, image.free_blocks.data(), free_bytes);
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
  const BufferBytes b = buffers_.bytesByUse();
  const std::size_t scene = ray_scene_ ? ray_scene_->deviceBytes() : 0;
  return {.pool = b.pool,
          .leaf_boxes = b.leaf_boxes,
          .scratch = b.scratch,
          .queries = b.queries + scene};
}

void OccupancyMap::Impl::trim() {
  buffers_.releaseScratch();
  buffers_.releaseQueries();
  ray_scene_.reset();
}

std::vector<OccupancyMap::LeafBoxHost> OccupancyMap::Impl::downloadLeafBoxes() {
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
    : impl_(std::make_unique<Impl>(context, params)) {}
OccupancyMap::~OccupancyMap() = default;
OccupancyMap::OccupancyMap(OccupancyMap&&) noexcept = default;
OccupancyMap& OccupancyMap::operator=(OccupancyMap&&) noexcept = default;

const MapParams& OccupancyMap::params() const noexcept { return impl_->params(); }

ScanStats OccupancyMap::insertPointCloud(std::span<const Eigen::Vector3f> points_world,
                                         const Eigen::Vector3f& origin_world, double max_range_m,
                                         bool discretize) {
  return impl_->insert({.points = points_world}, origin_world, nullptr, max_range_m, discretize);
}

ScanStats OccupancyMap::insertPointCloud(std::span<const Eigen::Vector3f> points_sensor,
                                         const Eigen::Vector3f& origin_sensor,
                                         const Pose& T_world_sensor, double max_range_m,
                                         bool discretize) {
  const Eigen::Vector3f origin_world = T_world_sensor.transform(origin_sensor);
  return impl_->insert({.points = points_sensor}, origin_world, &T_world_sensor, max_range_m,
                       discretize);
}

ScanStats OccupancyMap::insertDepthImage(const DepthImage& image, const Pose& T_world_camera,
                                         double max_range_m,
                                         const Eigen::Vector3f& origin_camera, bool discretize) {
  if (std::string why = image.validate(); !why.empty())
    throw Error(ErrorCode::kInvalidArgument, "insertDepthImage: " + why);
  const Eigen::Vector3f origin_world = T_world_camera.transform(origin_camera);
  return impl_->insert({.depth = &image}, origin_world, &T_world_camera, max_range_m, discretize);
}

ScanStats OccupancyMap::insertPointCloud(std::span<const Eigen::Vector3f> points_world,
                                         const Eigen::Vector3f& origin_world, double max_range_m,
                                         bool discretize, const QueryRequest& queries,
                                         QueryResults& results) {
  return impl_->insert({.points = points_world}, origin_world, nullptr, max_range_m, discretize,
                       &queries, &results);
}

std::vector<Lookup> OccupancyMap::search(std::span<const Eigen::Vector3f> points) const {
  return impl_->runQueries({points, {}}).lookups;
}

std::vector<RayHit> OccupancyMap::castRays(std::span<const Ray> rays) const {
  return impl_->runQueries({{}, rays}).rays;
}

std::vector<OccupancyMap::LeafBoxHost> OccupancyMap::leavesInBox(const Eigen::Vector3f& min,
                                                                 const Eigen::Vector3f& max,
                                                                 bool occupied_only) const {
  return impl_->leavesInBox(min, max, occupied_only);
}

std::size_t OccupancyMap::nodeCount() const {
  const gpu::PoolState pool = impl_->readPool();
  return pool.root_exists ? pool.live_nodes : 0;
}

std::size_t OccupancyMap::leafCount() const {
  impl_->refreshLeafBoxes();
  return impl_->readPool().leaf_count;
}

void OccupancyMap::setLeafBoxesEveryScan(bool every_scan) {
  impl_->setLeafBoxesEveryScan(every_scan);
}

std::size_t OccupancyMap::deviceBytes() const { return impl_->deviceBytes(); }

OccupancyMap::CastRayInfo OccupancyMap::castRayInfo() const { return impl_->castRayInfo(); }

std::size_t OccupancyMap::poolBytes() const { return impl_->poolBytes(); }

OccupancyMap::DeviceBytes OccupancyMap::deviceBytesByUse() const {
  return impl_->deviceBytesByUse();
}

std::size_t OccupancyMap::scratchBytes() const { return impl_->deviceBytesByUse().scratch; }

void OccupancyMap::trim() { impl_->trim(); }

HostTree OccupancyMap::download() const { return impl_->download(); }

void OccupancyMap::upload(const HostTree& tree) { impl_->upload(tree); }

std::vector<OccupancyMap::LeafBoxHost> OccupancyMap::downloadLeafBoxes() const {
  return impl_->downloadLeafBoxes();
}

}  // namespace octovk
