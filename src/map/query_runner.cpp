#include "map/query_runner.hpp"

#include <algorithm>
#include <array>
#include <cstring>
#include <string>
#include <vector>

#include "gpu/gpu_types.h"

namespace octovk {

bool boxKeys(double resolution, const Eigen::Vector3f& min, const Eigen::Vector3f& max,
             gpu::BoxQuery& box) {
  const double factor = 1.0 / resolution;
  return ref::coordToKeyChecked(factor, min.x(), box.min_x) &&
         ref::coordToKeyChecked(factor, min.y(), box.min_y) &&
         ref::coordToKeyChecked(factor, min.z(), box.min_z) &&
         ref::coordToKeyChecked(factor, max.x(), box.max_x) &&
         ref::coordToKeyChecked(factor, max.y(), box.max_y) &&
         ref::coordToKeyChecked(factor, max.z(), box.max_z);
}

void QueryRunner::onDevice(bool rays, VkBuffer in, VkDeviceSize in_offset, VkDeviceSize in_size,
                           VkBuffer out, VkDeviceSize out_offset, VkDeviceSize out_size,
                           std::uint32_t count) {
  const VkDeviceSize align = core_.device.storageOffsetAlignment();
  if (in == VK_NULL_HANDLE || out == VK_NULL_HANDLE)
    throw Error(ErrorCode::kInvalidArgument, "query on device: a buffer is VK_NULL_HANDLE");
  if (in_offset % align != 0 || out_offset % align != 0)
    throw Error(ErrorCode::kInvalidArgument,
                "query on device: buffer offsets must be multiples of " + std::to_string(align) +
                    " (minStorageBufferOffsetAlignment)");
  if (count == 0) return;
  const passes::TraceScene ray_scene = rays ? scenes_.castRayScene() : passes::TraceScene{};
  // The map's own query buffers are swapped for the caller's ranges for this one submission.
  core_.buffers.bindings.updateRange(gpu::kBindQueryIn, in, in_offset, in_size);
  core_.buffers.bindings.updateRange(gpu::kBindQueryOut, out, out_offset, out_size);
  try {
    const gpu::ScanParams sp = core_.queryParams();
    core_.stream.begin(core_.buffers.bindings);
    core_.rec.setParams(sp);
    core_.stream.barrier();
    if (rays && ray_scene)
      passes::recordCastRaysRt(core_.rec, ray_scene, {0, count}, {0, count});
    else if (rays)
      passes::recordCastRays(core_.rec, count, passes::firstRayState(count));
    else
      passes::recordLookups(core_.rec, count, 0, 0);
    core_.stream.submitAndWait();
  } catch (...) {
    core_.buffers.rebind();
    throw;
  }
  core_.buffers.rebind();
}

bool QueryRunner::fitsOneBatch(std::size_t rays, std::size_t lookups) const {
  // Input and output each go through one descriptor binding (kBindQueryIn / kBindQueryOut, at
  // most maxBindingBytes), and unfinished castRay walks are continued by indirect dispatches of
  // one group per 64 rays. At most kMaxBatch queries a batch also keeps the query buffers (and
  // their host staging) small however many queries a call brings.
  const std::uint64_t binding = core_.device.maxBindingBytes();
  return rays + lookups <= kMaxBatch &&
         rays <= std::size_t{core_.device.maxGroupsX()} * gpu::kWorkgroupSize &&
         rays * sizeof(gpu::RayQuery) + lookups * 3 * sizeof(float) <= binding &&
         passes::queryOutputBytes(rays, lookups) <= binding;
}

std::size_t QueryRunner::batchLimit(bool rays) const {
  std::size_t fits = 0, fails = kMaxBatch + 1;  // the largest n that fits, by bisection
  while (fails - fits > 1) {
    const std::size_t n = fits + (fails - fits) / 2;
    (fitsOneBatch(rays ? n : 0, rays ? 0 : n) ? fits : fails) = n;
  }
  if (fits == 0)
    throw Error(ErrorCode::kMissingFeature, "queries: the device '" + core_.device.info().name +
                                                "' binds at most " +
                                                std::to_string(core_.device.maxBindingBytes()) +
                                                " bytes per storage buffer, too few for one query");
  return fits;
}

QueryResults QueryRunner::run(const QueryRequest& q) {
  try {
    return runSplit(q);
  } catch (const BudgetError&) {
    throw;  // names the cap
  } catch (const Error& e) {
    if (e.code() != ErrorCode::kOutOfDeviceMemory) throw;
    // What asked for the room and what to change, in the caller's words.
    const std::size_t cap = core_.buffers.maxBytes();
    throw Error(ErrorCode::kOutOfDeviceMemory,
                "queries: " + std::to_string(q.lookups.size()) + " search points and " +
                    std::to_string(q.rays.size()) +
                    " rays need more device memory than the device gave (" + e.message() +
                    "); the map is unchanged. Ask for fewer at once" +
                    (cap == 0 ? std::string(" (MapParams::max_device_bytes is not set: only the "
                                            "device limits the map)")
                              : ", or lower MapParams::max_device_bytes (now " +
                                    std::to_string(cap) + " bytes) to what the device holds"),
                0, e.detail());
  }
}

QueryResults QueryRunner::runSplit(const QueryRequest& q) {
  if (q.rays.empty() && q.lookups.empty()) return {};
  // A request that fits is one batch; a larger one is split, each kind in batches of its own.
  // Every query is answered alone, against the same tree, so the answers are the same.
  if (fitsOneBatch(q.rays.size(), q.lookups.size())) return runBatch(q);
  const std::size_t ray_limit = q.rays.empty() ? 0 : batchLimit(true);
  const std::size_t lookup_limit = q.lookups.empty() ? 0 : batchLimit(false);
  QueryResults out;
  out.rays.reserve(q.rays.size());
  out.lookups.reserve(q.lookups.size());
  for (std::size_t i = 0; i < q.rays.size(); i += ray_limit) {
    const QueryResults part = runBatch(
        {.lookups = {}, .rays = q.rays.subspan(i, std::min(ray_limit, q.rays.size() - i))});
    out.rays.insert(out.rays.end(), part.rays.begin(), part.rays.end());
  }
  for (std::size_t i = 0; i < q.lookups.size(); i += lookup_limit) {
    const QueryResults part =
        runBatch({.lookups = q.lookups.subspan(i, std::min(lookup_limit, q.lookups.size() - i)),
                  .rays = {}});
    out.lookups.insert(out.lookups.end(), part.lookups.begin(), part.lookups.end());
  }
  return out;
}

QueryResults QueryRunner::runBatch(const QueryRequest& q) {
  const passes::TraceScene ray_scene =
      q.rays.empty() ? passes::TraceScene{} : scenes_.castRayScene();
  std::uint32_t stop_rays = 0;
  const std::vector<std::uint32_t> order =
      passes::rayOrder(q.rays, core_.params.resolution, stop_rays);
  passes::stageQueries(core_.buffers, q, order);
  core_.stream.begin(core_.buffers.bindings);
  passes::recordQueries(core_.rec, core_.queryParams(), q, ray_scene, stop_rays);
  core_.stream.submitAndWait();
  QueryResults out;
  passes::collectQueries(core_.buffers, q, order, out);
  return out;
}

std::vector<OccupancyMap::LeafBoxHost> QueryRunner::leavesInBox(const Eigen::Vector3f& min,
                                                                const Eigen::Vector3f& max,
                                                                bool occupied_only) {
  gpu::BoxQuery box{};
  if (!boxKeys(core_.params.resolution, min, max, box))
    return {};  // as OctoMap's iterator: a corner outside the map gives no leaves
  box.occupied_only = occupied_only ? 1u : 0u;
  // At most every leaf of the pool, and at most what one binding holds.
  const std::size_t capacity =
      std::min<std::size_t>(std::size_t{core_.buffers.poolBlocks()} * 8,
                            core_.device.maxBindingBytes() / sizeof(gpu::LeafBox));
  std::vector<OccupancyMap::LeafBoxHost> out;
  if (leavesInKeyBox(box, capacity, out)) {
    // The box was asked in parts: a leaf reaching into several came back once from each.
    const auto bits = [](const OccupancyMap::LeafBoxHost& l) {
      std::array<std::uint32_t, 5> b;
      std::memcpy(b.data(), &l, sizeof(l));
      return b;
    };
    std::sort(out.begin(), out.end(),
              [&](const auto& x, const auto& y) { return bits(x) < bits(y); });
    out.erase(std::unique(out.begin(), out.end(),
                          [&](const auto& x, const auto& y) { return bits(x) == bits(y); }),
              out.end());
  }
  return out;
}

bool QueryRunner::leavesInKeyBox(const gpu::BoxQuery& box, std::size_t capacity,
                                 std::vector<OccupancyMap::LeafBoxHost>& out) {
  core_.buffers.ensureQueries(sizeof(box), capacity * sizeof(gpu::LeafBox));
  core_.stream.begin(core_.buffers.bindings);
  passes::recordLeavesInBox(core_.rec, core_.queryParams(), box);
  passes::recordReadback(core_.rec);
  core_.stream.submitAndWait();
  gpu::ScanCounters counters;
  gpu::PoolState pool;
  passes::readBack(core_.buffers, core_.stream.frame(), counters, pool);
  const std::size_t count = counters.query_results;
  if (count > capacity) {
    // More leaves than one binding holds: the two halves of the box along its widest axis.
    gpu::BoxQuery lo = box, hi = box;
    const std::array<std::uint32_t*, 3> lo_max = {&lo.max_x, &lo.max_y, &lo.max_z};
    const std::array<std::uint32_t*, 3> hi_min = {&hi.min_x, &hi.min_y, &hi.min_z};
    const std::array<std::uint32_t, 3> from = {box.min_x, box.min_y, box.min_z};
    const std::array<std::uint32_t, 3> to = {box.max_x, box.max_y, box.max_z};
    std::size_t axis = 0;
    for (std::size_t a = 1; a < 3; ++a)
      if (to[a] - from[a] > to[axis] - from[axis]) axis = a;
    if (to[axis] == from[axis])
      throw Error(ErrorCode::kInternal, "internal error: leavesInBox found " +
                                            std::to_string(count) + " leaves in one cell");
    const std::uint32_t middle = from[axis] + (to[axis] - from[axis]) / 2;
    *lo_max[axis] = middle;
    *hi_min[axis] = middle + 1;
    leavesInKeyBox(lo, capacity, out);
    leavesInKeyBox(hi, capacity, out);
    return true;
  }
  if (count == 0) return false;
  const std::size_t bytes = count * sizeof(gpu::LeafBox);
  core_.stream.begin(core_.buffers.bindings);
  core_.stream.copy(core_.buffers.query_out, core_.buffers.query_staging_out, bytes);
  core_.stream.submitAndWait();
  static_assert(sizeof(OccupancyMap::LeafBoxHost) == sizeof(gpu::LeafBox));
  const std::size_t at = out.size();
  out.resize(at + count);
  std::memcpy(out.data() + at, core_.buffers.query_staging_out.mapped(), bytes);
  return false;
}

}  // namespace octovk
