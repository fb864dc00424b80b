#include "map/map_core.hpp"

namespace octovk {

namespace {

const MapParams& validated(const MapParams& params) {
  if (std::string why = params.validate(); !why.empty())
    throw Error(ErrorCode::kInvalidArgument, why);
  return params;
}

}  // namespace

MapCore::MapCore(vk::Device& device, const MapParams& params)
    : device(device),
      params(validated(params)),
      logs(ref::LogOddsParams::from(params)),
      stream(device, kFramesInFlight),
      // Most blocks the pool may have: MapParams::max_nodes, and 2^32 nodes.
      buffers(device, stream, poolBlockLimit(params.max_nodes), params.max_device_bytes,
              params.payload),
      rec(device, stream, buffers) {}

gpu::ScanParams MapCore::scanParams(const Eigen::Vector3f& origin, const Pose* pose,
                                    double max_range, std::size_t count) const {
  gpu::ScanParams sp{};
  sp.resolution = params.resolution;
  sp.resolution_factor = 1.0 / params.resolution;
  sp.max_range = max_range;
  sp.origin_x = origin.x();
  sp.origin_y = origin.y();
  sp.origin_z = origin.z();
  sp.prob_hit_log = logs.hit;
  sp.prob_miss_log = logs.miss;
  sp.clamp_min_log = logs.clamp_min;
  sp.clamp_max_log = logs.clamp_max;
  sp.point_count = static_cast<std::uint32_t>(count);
  sp.hash_capacity = 1u << buffers.hashLog2();
  sp.hash_log2 = buffers.hashLog2();
  sp.endpoint_capacity = 1u << buffers.endpointLog2();
  sp.endpoint_log2 = buffers.endpointLog2();
  sp.touched_capacity =
      static_cast<std::uint32_t>(std::min<std::size_t>(buffers.listEntries(), 0xFFFFFFFFu));
  sp.cell_capacity = static_cast<std::uint32_t>(buffers.cellEntries());
  sp.walk_capacity = static_cast<std::uint32_t>(buffers.walkCapacity());
  sp.occupancy_log = logs.occupancy;
  sp.payload = static_cast<std::uint32_t>(params.payload);
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

gpu::PoolState MapCore::readPool() {
  stream.begin(buffers.bindings);
  passes::recordReadback(rec);
  stream.submitAndWait();
  gpu::ScanCounters counters;
  gpu::PoolState pool;
  passes::readBack(buffers, stream.frame(), counters, pool);
  return pool;
}

void MapCore::ensureLeafBoxes() {
  bool made = false;
  try {
    made = buffers.ensureLeafBoxes();
  } catch (const BudgetError&) {
    // Under the cap the scans' sets and lists (scratch, empty between scans) give way to them
    // and grow again, within what is left, for the next scan.
    if (!buffers.releaseSetsAndLists()) throw;
    made = buffers.ensureLeafBoxes();
  }
  if (made) leaf_boxes = LeafBoxes::kStale;
}

void MapCore::refreshLeafBoxes() {
  ensureLeafBoxes();
  if (leaf_boxes == LeafBoxes::kCurrent) return;
  stream.begin(buffers.bindings);
  passes::recordLeafBoxes(rec);
  stream.submitAndWait();
  leaf_boxes = LeafBoxes::kCurrent;
}

}  // namespace octovk
