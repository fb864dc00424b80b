// The scan state machine: scans submitted back to back without waiting (each one submission,
// the device deciding whether it fits, tree_gate), their results taken when their frame is
// needed again or at a synchronisation, and the rare scan the device refused run again, in
// order, with everything behind it, once the host has grown what was short. The blocking
// insert is a submit and a flush.
#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstring>
#include <utility>

#include "map/map_impl.hpp"
#include "gpu/gpu_types.h"

namespace octovk {

namespace {

double msSince(std::chrono::steady_clock::time_point start) {
  return std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - start)
      .count();
}

// A depth image's pixel bytes, and those rounded up to whole words (the shader reads words):
// what `stage` copies and what `prepareBuffers` makes room for.
std::size_t pixelBytes(const OccupancyMap::Impl::ScanSource& source) {
  return source.count() * (source.depth->encoding == DepthImage::Encoding::kUint16 ? 2 : 4);
}
std::size_t wholeWords(std::size_t bytes) { return (bytes + 3) & ~std::size_t{3}; }

}  // namespace

// ---- checks and growth ----------------------------------------------------------------------

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
void OccupancyMap::Impl::reservePool(std::uint64_t blocks, const gpu::PoolState& pool, bool ahead) {
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
      limit, std::max<std::uint64_t>(
                 needed, std::uint64_t{buffers_.poolBlocks()} + buffers_.poolBlocks() / 2));
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
                    std::to_string(target * 8) + " nodes; the map is unchanged (" + e.what() + ")");
  }
}

passes::RayKeysInput OccupancyMap::Impl::stage(const ScanSource& source, std::uint32_t frame) {
  vk::Buffer& upload = buffers_.uploads[frame];
  passes::RayKeysInput in;
  in.source = upload.handle();
  if (!source.depth) {
    static_assert(sizeof(Eigen::Vector3f) == 3 * sizeof(float));
    in.bytes = source.count() * sizeof(Eigen::Vector3f);
    if (source.device != VK_NULL_HANDLE) {
      in.source = source.device;
      in.source_offset = source.device_offset;
    } else {
      std::memcpy(upload.mapped(), source.points.data(), in.bytes);
    }
    return in;
  }
  const DepthImage& image = *source.depth;
  const bool u16 = image.encoding == DepthImage::Encoding::kUint16;
  in.unproject = true;
  in.camera = {
      image.fx,          image.fy,    image.cx,     image.cy,
      image.depth_scale, image.width, image.height, u16 ? gpu::kDepthUint16 : gpu::kDepthFloat32};
  const std::size_t pixel_bytes = pixelBytes(source);
  in.bytes = wholeWords(pixel_bytes);
  if (source.device != VK_NULL_HANDLE) {
    in.source = source.device;
    in.source_offset = source.device_offset;
    in.bytes = pixel_bytes;  // the caller's range may end there; the last half word is unused
  } else {
    auto* bytes = static_cast<unsigned char*>(upload.mapped());
    std::memcpy(bytes, image.pixels, pixel_bytes);
    std::memset(bytes + pixel_bytes, 0, in.bytes - pixel_bytes);
  }
  return in;
}

// An upper bound of the DDA steps of the scan's longest ray (each axis crosses at most
// |d| / resolution + 1 cell borders): from the host's points or pixels, or unbounded for a
// caller's device buffer. Ray lengths do not change with the pose (a rotation and a translation
// of both ends), so they are measured in the frame the input is given in.
static double worstSteps(const OccupancyMap::Impl::ScanSource& source,
                         const Eigen::Vector3f& origin_world, const Pose* pose, double max_range,
                         double resolution) {
  if (source.device != VK_NULL_HANDLE) return HUGE_VAL;
  const Eigen::Vector3f origin = pose ? pose->inverse().transform(origin_world) : origin_world;
  double longest = 0.0;  // metres
  if (source.depth) {
    const DepthImage& im = *source.depth;
    double z_max = 0.0;
    const std::size_t n = std::size_t{im.width} * im.height;
    if (im.encoding == DepthImage::Encoding::kUint16) {
      const auto* d = static_cast<const std::uint16_t*>(im.pixels);
      std::uint16_t m = 0;
      for (std::size_t i = 0; i < n; ++i) m = std::max(m, d[i]);
      z_max = m / static_cast<double>(im.depth_scale);
    } else {
      const auto* d = static_cast<const float*>(im.pixels);
      float m = 0.0f;
      for (std::size_t i = 0; i < n; ++i)
        if (std::isfinite(d[i])) m = std::max(m, std::fabs(d[i]));
      z_max = m / static_cast<double>(std::fabs(im.depth_scale));
    }
    const double cx = im.cx, cy = im.cy;
    const double u = std::max(std::fabs(cx), std::fabs(im.width - 1.0 - cx)) / std::fabs(im.fx);
    const double v = std::max(std::fabs(cy), std::fabs(im.height - 1.0 - cy)) / std::fabs(im.fy);
    longest = z_max * std::sqrt(1.0 + u * u + v * v) + origin.norm();
  } else {
    for (const Eigen::Vector3f& p : source.points)
      if (p.allFinite()) longest = std::max(longest, static_cast<double>((p - origin).norm()));
  }
  if (max_range > 0) longest = std::min(longest, max_range);
  // Float rounding of the ends, a discretized end cell's centre: a cell more at each end.
  return 1.8 * (longest / resolution + 2.0) + 3.0;
}

static std::size_t depthBytesOf(const OccupancyMap::Impl::ScanSource& source) {
  if (!source.depth) return 0;
  return sizeof(gpu::DepthCamera) + wholeWords(pixelBytes(source));
}

void OccupancyMap::Impl::growAhead(const gpu::PoolState* pool, bool release) {
  if (ahead_blocks_ > 0) {
    const std::uint64_t blocks = std::exchange(ahead_blocks_, 0);
    reservePool(blocks, pool ? *pool : readPool(), /*ahead=*/true);
  }
  if (ahead_active_ > 0) {
    const std::size_t active = std::exchange(ahead_active_, 0);
    if (active > buffers_.activeCapacity()) {
      try {
        buffers_.allocateLists(std::size_t{1} << nextPow2Log2(active));
      } catch (const BudgetError&) {
        // ahead of need: the cap leaves no room, and the scan that needs it will say so
      }
    }
  }
  if (release && release_scratch_) {
    release_scratch_ = false;
    buffers_.releaseScratch();
    hash_guess_tried_ = 0;
  }
}

void OccupancyMap::Impl::prepareBuffers(std::size_t count, std::size_t depth_bytes) {
  // First guess of the cell set's size: 4 brick slots (16 cells) per point (a 320x240 depth view
  // at 0.05 m touches 0.6-1 million cells in about a quarter as many bricks), at most 2^20 brick
  // slots; it grows (and the scan is redone) when a scan needs more, and keeps its size for the
  // next scans.
  const std::uint32_t guess = std::min<std::uint32_t>(nextPow2Log2(count * 4), 20);
  const bool grow = count > buffers_.pointCapacity() || depth_bytes > buffers_.depth.size() ||
                    depth_bytes > buffers_.uploads[0].size() || guess > hash_guess_tried_ ||
                    ahead_blocks_ > 0 || ahead_active_ > 0 || release_scratch_;
  if (!grow) return;
  // Buffers are replaced (and rebound) only while no scan is in flight.
  flush();
  growAhead();
  buffers_.ensurePoints(count);
  if (depth_bytes > 0) buffers_.ensureDepth(depth_bytes);
  if (guess > hash_guess_tried_) {
    buffers_.growHashToward(guess);  // as far as MapParams::max_device_bytes allows
    hash_guess_tried_ = guess;
  }
}

// ---- one scan ---------------------------------------------------------------------------------

void OccupancyMap::Impl::record(PendingScan& p) {
  const gpu::ScanParams sp =
      scanParams(p.origin, p.pose ? &*p.pose : nullptr, p.max_range, p.count);  // sizes may grow
  passes::RayKeysInput input = p.input;
  if (p.host_input) input.source = buffers_.uploads[p.staging_frame].handle();
  input.fill_sets = buffers_.setsNeedFill();  // new sets; else the last scan emptied them
  input.resume = resume_;
  input.trace = scan_rays_ == ScanRays::kRayTracing;
  RayScene* scene = input.trace ? &scanScene() : nullptr;  // before recording: it may wait
  stream_.begin(buffers_.bindings);
  passes::recordRayKeys(rec_, sp, input);
  if (scene) {
    passes::recordScanScene(rec_, scene->accel, scene->boxes, scan_header_);
    noteSceneBytes();  // the build allocated before recording
    passes::recordScanRaysRt(rec_, scene->boxes.address(), sp.point_count, input.discretize);
  }
  passes::recordClassify(rec_, input.discretize, sp.point_count);
  passes::recordTreeUpdate(rec_);
  passes::recordPrune(rec_);
  if (leaf_boxes_every_scan_) passes::recordLeafBoxes(rec_);
  if (p.queries) passes::recordQueries(rec_, queryParams(), *p.queries);
  passes::recordClearSets(rec_);
  passes::recordReadback(rec_);
  p.serial = stream_.submit();
  p.frame = stream_.frame();
  ++p.stats.cell_set_attempts;
  buffers_.setSetsNeedFill(false);
  resume_ = false;
  leaf_boxes_dirty_ = !leaf_boxes_every_scan_;
}

std::uint64_t OccupancyMap::Impl::submit(const ScanSource& source, const Eigen::Vector3f& origin,
                                         const Pose* pose, double max_range, bool discretize) {
  return enqueue(source, origin, pose, max_range, discretize, false, nullptr, nullptr);
}

std::uint64_t OccupancyMap::Impl::enqueue(const ScanSource& source, const Eigen::Vector3f& origin,
                                          const Pose* pose, double max_range, bool discretize,
                                          bool blocking, const QueryRequest* queries,
                                          QueryResults* results) {
  const auto start = std::chrono::steady_clock::now();
  const std::size_t count = source.count();
  checkScan(count, origin, pose, max_range);
  PendingScan p;
  p.stats.points = count;
  p.blocking = blocking;
  if (count > 0) {
    releaseRaySceneUnderCap();  // the scan's growth comes first; castRays builds it again
    prepareBuffers(count, depthBytesOf(source));
    if (queries) {
      passes::stageQueries(buffers_, *queries);  // after the growth: nothing in flight
      // Sized now: collected once the scan is in the map, where nothing may fail.
      results->rays.resize(queries->rays.size());
      results->lookups.resize(queries->lookups.size());
    }
    // The frame this scan records into must have no scan of ours in flight.
    while (pending_.size() >= stream_.frames()) confirmOldest();
    p.staging_frame = stream_.nextFrame();
    p.host_input = source.device == VK_NULL_HANDLE;
    p.input = stage(source, p.staging_frame);
    p.input.transform = pose != nullptr;
    p.input.discretize = discretize;
    p.input.walk_rounds = passes::walkRounds(
        device_, worstSteps(source, origin, pose, max_range, params_.resolution));
    p.origin = origin;
    if (pose) p.pose = *pose;
    p.max_range = max_range;
    p.count = count;
    p.queries = queries;
    p.results = results;
    // A caller's semaphore guards its buffer: the first submission that reads it waits for it.
    if (source.wait != VK_NULL_HANDLE) stream_.waitBeforeNextSubmit(source.wait, source.wait_value);
    try {
      record(p);
    } catch (...) {
      stream_.waitBeforeNextSubmit(VK_NULL_HANDLE, 0);  // not for some later submission
      throw;
    }
  }
  p.ticket = p.stats.ticket = next_ticket_++;  // only for a scan submitted (or empty)
  p.stats.wall_ms = msSince(start);
  const std::uint64_t ticket = p.ticket;
  pending_.push_back(std::move(p));
  // Results already there are taken without waiting (statistics early, growth ahead asked for);
  // never this scan's own: a scan refused on the device is then always noticed after the scan
  // submitted next, which the device refused too (halted) and which runs again with it.
  while (pending_.size() > 1 && stream_.finished(pending_.front().serial)) confirmOldest();
  return ticket;
}

bool OccupancyMap::Impl::takeResult(PendingScan& p, const gpu::ScanCounters& counters,
                                    const gpu::PoolState& pool) {
  if (counters.status & gpu::kStatusNotApplied) return false;
  if (counters.status & gpu::kStatusPoolFull)
    throw Error(ErrorCode::kInternal,
                "internal error: the node pool ran out during a scan despite its size check; "
                "please report this with the input");
  ScanStats& stats = p.stats;
  // The scan is in the map: from here on nothing may throw (statistics go without, instead).
  std::vector<double> t;
  try {
    t = stream_.timestampsNs(p.frame);
  } catch (const std::bad_alloc&) {
    // no memory for the timestamps: the statistics go without device times
  }
  const auto span = [&](passes::Stamp from, passes::Stamp to) {
    return rec_.spanMs(p.frame, t, from, to);
  };
  using passes::Stamp;
  stats.device.upload_ms = span(Stamp::kScanStart, Stamp::kUploaded);
  stats.device.ray_keys_ms = span(Stamp::kUploaded, Stamp::kClassifyStart);
  stats.device.classify_ms = span(Stamp::kClassifyStart, Stamp::kClassifyEnd);
  stats.device.tree_update_ms = span(Stamp::kClassifyEnd, Stamp::kTreeUpdateEnd);
  stats.device.prune_ms = span(Stamp::kTreeUpdateEnd, Stamp::kPruneEnd);
  stats.device.leaf_boxes_ms = span(Stamp::kPruneEnd, Stamp::kLeafBoxesEnd);
  // With ScanRays::kRayTracing, the parts of ray_keys_ms: boxes, build, then the trace.
  stats.device.scan_boxes_ms = span(Stamp::kBoxesStart, Stamp::kBoxesEnd);
  stats.device.scan_build_ms = span(Stamp::kBoxesEnd, Stamp::kBuildEnd);
  stats.device.scan_trace_ms = span(Stamp::kBuildEnd, Stamp::kClassifyStart);
  if (p.queries) passes::collectQueries(buffers_, *p.queries, {}, *p.results);
  stats.skipped_no_depth = counters.no_depth;
  stats.skipped_nonfinite = counters.skipped_nonfinite - counters.no_depth;  // NaN points
  stats.skipped_outside = counters.skipped_outside;
  stats.free_cells = counters.free_cells;
  stats.occupied_cells = counters.occupied_cells;
  stats.aborted_cells = counters.aborted;
  stats.nodes = pool.root_exists ? pool.live_nodes : 0;
  last_nodes_ = stats.nodes;
  if (counters.active_cells + counters.leaf_cells > 0)
    ++tree_version_;  // the ray scene is rebuilt before the next castRays
  if (p.blocking)
    blocking_stats_ = stats;  // the call's result, which must not need an allocation
  else
    keepStats(stats);
  // Room ahead for more scans like this one, so that they are not run twice: after a blocking
  // call, for the next one; after a submitted scan, for as many as may be in flight when the
  // growth is next possible (the submits behind it were recorded before its result was seen).
  // Grown at the next submit (or at the end of the blocking call).
  const std::uint64_t scans_ahead = p.blocking ? 1 : stream_.frames();
  const std::uint64_t room = std::uint64_t{pool.capacity} - pool.bump + pool.free_count;
  const std::uint64_t want = std::uint64_t{counters.new_blocks} * scans_ahead;
  if (want > room) ahead_blocks_ = std::max(ahead_blocks_, want);
  const std::size_t active = std::size_t{counters.active_cells} + counters.leaf_cells;
  if (active > buffers_.activeCapacity() / 2) ahead_active_ = std::max(ahead_active_, active * 2);
  if (buffers_.noteScan(p.count)) release_scratch_ = true;  // released once none is in flight
  return true;
}

void OccupancyMap::Impl::keepStats(const ScanStats& stats) noexcept {
  try {
    finished_stats_.push_back(stats);
  } catch (const std::bad_alloc&) {
    return;  // the scan is in the map; without host memory its statistics are dropped
  }
  if (finished_stats_.size() > kKeptStats) finished_stats_.pop_front();
}

void OccupancyMap::Impl::confirmOldest() {
  PendingScan& p = pending_.front();
  if (p.count == 0) {  // an empty scan: in the map once the scans before it are
    p.stats.nodes = last_nodes_;
    keepStats(p.stats);
    pending_.pop_front();
    return;
  }
  stream_.wait(p.serial);
  gpu::ScanCounters counters{};
  gpu::PoolState pool{};
  passes::readBack(buffers_, p.frame, counters, pool);
  if (!takeResult(p, counters, pool)) return recover(counters, pool);
  pending_.pop_front();
}

void OccupancyMap::Impl::recover(gpu::ScanCounters counters, gpu::PoolState pool) {
  // Every scan behind the refused one was refused too (halted): the map is as before it.
  stream_.waitIdle();
  resume_ = true;
  try {
    for (bool first = true; !pending_.empty(); first = false) {
      PendingScan& p = pending_.front();
      if (p.count == 0) {
        confirmOldest();
        continue;
      }
      if (!first) {
        // What the scans run again so far asked for (`pool`: the last one's state, the current
        // one); the scratch stays: it holds the inputs of the scans still to run.
        growAhead(&pool, /*release=*/false);
        record(p);
        stream_.wait(p.serial);
        passes::readBack(buffers_, p.frame, counters, pool);
      }
      while (!takeResult(p, counters, pool)) {
        resume_ = true;
        // A walk outran the rounds estimated for its length (the set's probes): every round.
        const std::uint32_t full = passes::fullWalkRounds(device_);
        if ((counters.status & gpu::kStatusRayCut) && p.input.walk_rounds < full) {
          p.input.walk_rounds = full;
          counters.status &= ~gpu::kStatusRayCut;
        }
        growForRetry(counters, pool);
        record(p);
        stream_.wait(p.serial);
        passes::readBack(buffers_, p.frame, counters, pool);
      }
      pending_.pop_front();
    }
  } catch (const Error& e) {
    // The map holds every scan before the one that failed; it and the later ones are dropped.
    const std::uint64_t failed = pending_.empty() ? 0 : pending_.front().ticket;
    const std::size_t dropped = pending_.size();
    const bool alone = dropped == 1 && pending_.front().blocking;
    pending_.clear();
    resume_ = true;
    if (alone) throw;  // the blocking call's own scan: its message says the map is unchanged
    throw Error(e.code(),
                std::string(e.what()) + " [scan " + std::to_string(failed) +
                    " was not inserted, nor the " + std::to_string(dropped - 1) +
                    " submitted after it; the map holds every scan before it]",
                failed);
  } catch (...) {
    pending_.clear();
    resume_ = true;
    throw;
  }
}

void OccupancyMap::Impl::flush() {
  while (!pending_.empty()) confirmOldest();
}

std::vector<ScanStats> OccupancyMap::Impl::takeStats() {
  while (!pending_.empty() && stream_.finished(pending_.front().serial)) confirmOldest();
  std::vector<ScanStats> out(finished_stats_.begin(), finished_stats_.end());
  finished_stats_.clear();
  return out;
}

bool OccupancyMap::Impl::finished(std::uint64_t ticket) {
  while (!pending_.empty() && pending_.front().ticket <= ticket &&
         stream_.finished(pending_.front().serial))
    confirmOldest();
  return ticket < next_ticket_ && (pending_.empty() || pending_.front().ticket > ticket);
}

// The blocking call: the same path, waited for. Its errors leave the map as before the scan.
ScanStats OccupancyMap::Impl::insert(const ScanSource& source, const Eigen::Vector3f& origin,
                                     const Pose* pose, double max_range, bool discretize,
                                     const QueryRequest* queries, QueryResults* results) {
  const auto start = std::chrono::steady_clock::now();
  flush();
  if (source.count() == 0) {
    checkScan(0, origin, pose, max_range);
    ScanStats stats;
    stats.ticket = next_ticket_++;
    if (queries) *results = runQueries(*queries);
    const gpu::PoolState pool = readPool();
    stats.nodes = pool.root_exists ? pool.live_nodes : 0;
    stats.wall_ms = msSince(start);
    return stats;
  }
  const std::uint64_t ticket =
      enqueue(source, origin, pose, max_range, discretize, true, queries, results);
  flush();
  // The scan is in the map: from here on nothing may throw, or a caller that retries would
  // insert it twice. Growth for the next scan is best-effort; what fails is asked for again
  // by the next scan, which then reports it with the map unchanged.
  const std::uint64_t ahead_blocks = ahead_blocks_;
  const std::size_t ahead_active = ahead_active_;
  try {
    growAhead();
  } catch (const std::exception&) {  // octovk::Error or std::bad_alloc: asked for again
    ahead_blocks_ = std::max(ahead_blocks_, ahead_blocks);
    ahead_active_ = std::max(ahead_active_, ahead_active);
  }
  // Its statistics are the call's result, not left for takeStats().
  ScanStats stats = blocking_stats_;
  if (stats.ticket != ticket)
    throw Error(ErrorCode::kInternal, "internal error: the blocking scan's statistics are missing");
  stats.wall_ms = msSince(start);
  return stats;
}

}  // namespace octovk
