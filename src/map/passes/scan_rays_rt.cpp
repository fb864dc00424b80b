// Scans through ray tracing (ScanRays::kRayTracing): accel_boxes.comp (kAccelBoxesScan) writes
// the boxes a free update can change, the acceleration structure is built over them in the
// scan's own submission (at the lists' capacities, the tails inactive, so the host needs no box
// count), and scan_rays_rt.comp traces the scan's rays through it into the cell set.
#include "map/passes/passes.hpp"

namespace octovk::passes {

namespace {
constexpr std::uint32_t kScanBucketBits = 5;
static_assert((1u << (3 * kScanBucketBits)) % gpu::kAccelChunks == 0 &&
              kScanBucketBits <= gpu::kAccelBucketBits);
}  // namespace

gpu::AccelHeader scanSceneHeader(const MapBuffers& buffers) {
  gpu::AccelHeader header{};
  // Every box in the first list: a leaf or an unknown region per slot, and the root. The second
  // list stays empty (one empty box outside the map, kAccelBoxesTail).
  header.occupied_capacity = static_cast<std::uint32_t>(std::size_t{buffers.poolBlocks()} * 8 + 1);
  header.unknown_capacity = 1;
  return header;
}

void recordScanScene(Recorder& r, vk::BoxScene& scene, const vk::Buffer& boxes,
                     const gpu::AccelHeader& header) {
  r.stamp(Stamp::kBoxesStart);
  gpu::AccelHeader fresh = header;
  fresh.occupied_count = fresh.unknown_count = 0;
  fresh.lo_x = fresh.lo_y = fresh.lo_z = 0xFFFFFFFFu;  // the extent, shrunk by atomics
  fresh.hi_x = fresh.hi_y = fresh.hi_z = 0;
  // 2^15 Morton buckets per list rather than castRay's 2^21: clearing and summing the buckets
  // is a fixed cost of every scan (about 35 ms on lavapipe with 2^21, an empty map's whole
  // boxes stage); within a bucket the boxes keep the order the passes wrote them.
  fresh.bucket_bits = kScanBucketBits;
  r.stream.update(boxes, &fresh, sizeof(fresh));
  const std::size_t sort_at = accelBoxesBytes(header) - accelSortBytes();
  r.stream.fill(boxes, 0u, sort_at, accelSortBytes(kScanBucketBits));
  r.stream.barrier();
  const auto pass = [&](std::uint32_t mode, std::size_t items) {
    r.dispatch<Shader::kAccelBoxes>(
        items, gpu::AccelBoxesConstants{.boxes = boxes.address(), .mode = mode});
  };
  const std::size_t all = std::size_t{header.occupied_capacity} + header.unknown_capacity;
  pass(gpu::kAccelBoxesScan, r.buffers.poolBlocks());
  pass(gpu::kAccelBoxesCount, all);
  pass(gpu::kAccelBoxesChunks, 2 * gpu::kAccelChunks);
  pass(gpu::kAccelBoxesOffsets, 2 * gpu::kAccelChunks);
  pass(gpu::kAccelBoxesScatter, all);
  pass(gpu::kAccelBoxesTail, all);
  r.stamp(Stamp::kBoxesEnd);
  // Both lists at their capacities: the counts stay on the device.
  const auto geometries =
      boxGeometries(boxes, header, header.occupied_capacity, header.unknown_capacity);
  scene.recordBuild(r.stream, geometries);
  const VkDeviceAddress tlas = scene.tlasAddress();
  r.stream.update(boxes, &tlas, sizeof(tlas), offsetof(gpu::AccelHeader, tlas));
  r.stream.barrier();
  r.stamp(Stamp::kBuildEnd);
}

void recordScanRaysRt(Recorder& r, VkDeviceAddress boxes, std::uint32_t points, bool discretize) {
  // With discretize, one invocation per point covers the distinct end cells (at most as many).
  r.dispatch<Shader::kScanRaysRt>(
      points,
      gpu::ScanRaysRtConstants{.boxes = boxes,
                               .point_count = points,
                               .mode = discretize ? gpu::kRayKeysEndCells : gpu::kRayKeysPoints});
}

}  // namespace octovk::passes
