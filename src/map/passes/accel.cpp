// castRay's ray-tracing backend: accel_boxes.comp writes the boxes an acceleration structure is
// built over (on the device, from the leaf-box buffer and the pool), the structure is built from
// them on the device, and cast_ray_rt.comp answers castRay through it.
#include <cstring>

#include "map/passes/passes.hpp"

namespace octovk::passes {

void recordAccelBoxes(Recorder& r, const gpu::ScanParams& sp, const vk::Buffer& boxes,
                      const gpu::AccelHeader& header, const vk::Buffer& readback) {
  r.stream.update(r.buffers.params, &sp, sizeof(sp));
  r.stream.update(boxes, &header, sizeof(header));
  r.stream.barrier();
  r.dispatch("accel_boxes", header.occupied_capacity,
             gpu::AccelBoxesConstants{.boxes = boxes.address(),
                                      .mode = gpu::kAccelBoxesOccupied});
  r.dispatch("accel_boxes", r.buffers.poolBlocks(),
             gpu::AccelBoxesConstants{.boxes = boxes.address(), .mode = gpu::kAccelBoxesUnknown});
  r.stream.copy(boxes, readback, sizeof(gpu::AccelHeader));
}

void recordAccelBuild(Recorder& r, vk::BoxScene& scene, const vk::Buffer& boxes,
                      const gpu::AccelHeader& header) {
  const VkDeviceAddress first = boxes.address() + sizeof(gpu::AccelHeader);
  const vk::BoxGeometry geometries[] = {
      {.data = first, .count = header.occupied_count, .mask = gpu::kAccelMaskOccupied},
      {.data = first + std::uint64_t{header.occupied_capacity} * sizeof(gpu::AccelBox),
       .count = header.unknown_count,
       .mask = gpu::kAccelMaskUnknown}};
  // An empty geometry is built from one inactive box (min x NaN), which the build skips.
  const float nan = std::numeric_limits<float>::quiet_NaN();
  const gpu::AccelBox inactive{nan, 0.0f, 0.0f, 0.0f, 0.0f, 0.0f};
  for (const vk::BoxGeometry& g : geometries)
    if (g.count == 0)
      r.stream.update(boxes, &inactive, sizeof(inactive), g.data - boxes.address());
  scene.recordBuild(r.stream, geometries);
  const VkDeviceAddress tlas = scene.tlasAddress();
  r.stream.update(boxes, &tlas, sizeof(tlas), offsetof(gpu::AccelHeader, tlas));
  r.stream.barrier();
}

void recordCastRaysRt(Recorder& r, std::uint32_t rays, VkDeviceAddress boxes) {
  r.dispatch("cast_ray_rt", rays, gpu::CastRayRtConstants{.boxes = boxes, .ray_count = rays});
}

}  // namespace octovk::passes
