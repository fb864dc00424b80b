// castRay's ray-tracing backend: accel_boxes.comp writes the boxes an acceleration structure is
// built over (on the device, from the leaf-box buffer and the pool), the structure is built from
// them on the device, and cast_ray_rt.comp answers castRay through it.
#include <cstring>
#include <limits>

#include "map/passes/passes.hpp"

static_assert(sizeof(octovk::gpu::AccelBox) == sizeof(VkAabbPositionsKHR),
              "the build reads AccelBoxes as VkAabbPositionsKHR");

namespace octovk::passes {

namespace {
// A traced scan's sort: 2^15 Morton buckets rather than castRay's 2^21. Clearing and
// summing the buckets is a fixed cost of every scan (about 35 ms on lavapipe with 2^21, an empty
// map's whole boxes stage); within a bucket the boxes keep the order the passes wrote them.
constexpr std::uint32_t kScanBucketBits = 5;
static_assert((1u << (3 * kScanBucketBits)) % gpu::kAccelChunks == 0 &&
              kScanBucketBits <= gpu::kAccelBucketBits);
}  // namespace

std::size_t accelBoxesBytes(const gpu::AccelHeader& header) {
  return sizeof(gpu::AccelHeader) + 2 * std::size_t{header.box_capacity} * sizeof(gpu::AccelBox) +
         accelSortBytes();
}

std::size_t accelSortBytes() { return accelSortBytes(gpu::kAccelBucketBits); }

std::size_t accelSortBytes(std::uint32_t bucket_bits) {
  const std::size_t buckets = std::size_t{1} << (3 * bucket_bits);
  return (buckets + std::size_t{gpu::kAccelChunks}) * sizeof(std::uint32_t);
}

void recordBoxes(Recorder& r, const vk::Buffer& boxes, const gpu::AccelHeader& header,
                 BoxesFor target) {
  const bool scan = target == BoxesFor::kScan;
  gpu::AccelHeader fresh = header;
  fresh.box_count = 0;
  fresh.lo_x = fresh.lo_y = fresh.lo_z = 0xFFFFFFFFu;  // the extent, shrunk by atomics
  fresh.hi_x = fresh.hi_y = fresh.hi_z = 0;
  fresh.bucket_bits = scan ? kScanBucketBits : gpu::kAccelBucketBits;
  r.stream.update(boxes, &fresh, sizeof(fresh));
  const std::size_t sort_at = accelBoxesBytes(header) - accelSortBytes();
  r.stream.fill(boxes, 0u, sort_at, accelSortBytes(fresh.bucket_bits));
  r.stream.barrier();
  const auto pass = [&](std::uint32_t mode, std::size_t items) {
    r.dispatch<Shader::kAccelBoxes>(
        items, gpu::AccelBoxesConstants{.boxes = boxes.address(), .mode = mode});
  };
  // The boxes, unsorted; then the counting sort along the Morton curve into their places.
  if (scan)
    pass(gpu::kAccelBoxesScan, r.buffers.poolBlocks());
  else
    pass(gpu::kAccelBoxesOccupied, header.box_capacity);
  pass(gpu::kAccelBoxesCount, header.box_capacity);
  pass(gpu::kAccelBoxesChunks, gpu::kAccelChunks);
  pass(gpu::kAccelBoxesOffsets, gpu::kAccelChunks);
  pass(gpu::kAccelBoxesScatter, header.box_capacity);
  if (scan) pass(gpu::kAccelBoxesTail, header.box_capacity);
}

void recordAccelBoxes(Recorder& r, const gpu::ScanParams& sp, const vk::Buffer& boxes,
                      const gpu::AccelHeader& header, const vk::Buffer& readback) {
  r.setParams(sp);
  recordBoxes(r, boxes, header, BoxesFor::kCastRay);
  r.stream.copy(boxes, readback, sizeof(gpu::AccelHeader));
}

vk::BoxGeometry boxGeometry(const vk::Buffer& boxes, std::uint32_t count) {
  return vk::BoxGeometry{.data = boxes.address() + sizeof(gpu::AccelHeader), .count = count};
}

void recordAccelBuild(Recorder& r, vk::BoxScene& scene, const vk::Buffer& boxes,
                      const gpu::AccelHeader& header) {
  const vk::BoxGeometry geometry = boxGeometry(boxes, header.box_count);
  // An empty geometry is built from one inactive box (min x NaN), which the build skips.
  const float nan = std::numeric_limits<float>::quiet_NaN();
  const gpu::AccelBox inactive{nan, 0.0f, 0.0f, 0.0f, 0.0f, 0.0f};
  if (geometry.count == 0)
    r.stream.update(boxes, &inactive, sizeof(inactive), geometry.data - boxes.address());
  scene.recordBuild(r.stream, {&geometry, 1});
  const VkDeviceAddress tlas = scene.tlasAddress();
  r.stream.update(boxes, &tlas, sizeof(tlas), offsetof(gpu::AccelHeader, tlas));
  r.stream.barrier();
}

void recordCastRaysRt(Recorder& r, TraceScene scene, RayRange stop, RayRange ignore) {
  // On lavapipe an invocation of the ray-query pass costs more than the whole walk of a ray
  // that stops at unknown space, even when it returns at once: each pass gets its own range.
  if (stop.count)
    r.dispatch<Shader::kCastRayJump>(
        stop.count, gpu::CastRayRtConstants{
                        .boxes = scene.boxes, .ray_count = stop.count, .first_ray = stop.first});
  if (!ignore.count) return;
  const gpu::CastRayRtConstants pc{
      .boxes = scene.boxes, .ray_count = ignore.count, .first_ray = ignore.first};
  if (scene.pipeline)
    traceRays(r, kCastRayRaygen, ignore.count, pc);
  else
    r.dispatch<Shader::kCastRayRt>(ignore.count, pc);
}

}  // namespace octovk::passes
