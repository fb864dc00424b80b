#include "map/query_runner.hpp"

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
  const VkDeviceAddress ray_scene = rays ? scenes_.castRayScene() : 0;
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

QueryResults QueryRunner::run(const QueryRequest& q) {
  if (q.rays.empty() && q.lookups.empty()) return {};
  if (q.rays.size() + q.lookups.size() > 0x7FFFFFFFu)
    throw Error(ErrorCode::kInvalidArgument, "queries: more than 2^31 queries in one batch");
  // Unfinished castRay walks are continued by indirect dispatches of one group per 64 rays.
  const std::size_t max_rays = std::size_t{core_.device.maxGroupsX()} * gpu::kWorkgroupSize;
  if (q.rays.size() > max_rays)
    throw Error(ErrorCode::kInvalidArgument,
                "castRays: " + std::to_string(q.rays.size()) + " rays in one batch; the device '" +
                    core_.device.info().name + "' takes at most " + std::to_string(max_rays) +
                    " (maxComputeWorkGroupCount x 64); split the batch");
  const VkDeviceAddress ray_scene = q.rays.empty() ? 0 : scenes_.castRayScene();
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
  core_.buffers.ensureQueries(sizeof(box),
                              std::size_t{core_.buffers.poolBlocks()} * 8 * sizeof(gpu::LeafBox));
  core_.stream.begin(core_.buffers.bindings);
  passes::recordLeavesInBox(core_.rec, core_.queryParams(), box);
  passes::recordReadback(core_.rec);
  core_.stream.submitAndWait();
  gpu::ScanCounters counters;
  gpu::PoolState pool;
  passes::readBack(core_.buffers, core_.stream.frame(), counters, pool);
  std::vector<OccupancyMap::LeafBoxHost> out(counters.query_results);
  if (out.empty()) return out;
  const std::size_t bytes = out.size() * sizeof(gpu::LeafBox);
  core_.stream.begin(core_.buffers.bindings);
  core_.stream.copy(core_.buffers.query_out, core_.buffers.query_staging_out, bytes);
  core_.stream.submitAndWait();
  static_assert(sizeof(OccupancyMap::LeafBoxHost) == sizeof(gpu::LeafBox));
  std::memcpy(out.data(), core_.buffers.query_staging_out.mapped(), bytes);
  return out;
}

}  // namespace octovk
