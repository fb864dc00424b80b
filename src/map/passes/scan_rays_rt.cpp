// Scans through ray tracing (ScanRays::kRayTracing): accel_boxes.comp (kAccelBoxesScan) writes
// the boxes a free update can change, the acceleration structure is built over them in the
// scan's own submission (at the list's capacity, the tail inactive, so the host needs no box
// count), and scan_rays_rt (.comp with ray queries, .rgen through a ray-tracing pipeline) traces
// the scan's rays through it into the cell set.
#include "map/passes/passes.hpp"

namespace octovk::passes {

gpu::AccelHeader scanSceneHeader(const MapBuffers& buffers) {
  gpu::AccelHeader header{};
  // A leaf or an unknown region per slot, and the root.
  header.box_capacity = static_cast<std::uint32_t>(std::size_t{buffers.poolBlocks()} * 8 + 1);
  return header;
}

void recordScanScene(Recorder& r, vk::BoxScene& scene, const vk::Buffer& boxes,
                     const gpu::AccelHeader& header) {
  r.stamp(Stamp::kBoxesStart);
  recordBoxes(r, boxes, header, BoxesFor::kScan);
  r.stamp(Stamp::kBoxesEnd);
  // The list at its capacity: the count stays on the device.
  const vk::BoxGeometry geometry = boxGeometry(boxes, header.box_capacity);
  scene.recordBuild(r.stream, {&geometry, 1});
  const VkDeviceAddress tlas = scene.tlasAddress();
  r.stream.update(boxes, &tlas, sizeof(tlas), offsetof(gpu::AccelHeader, tlas));
  r.stream.barrier();
  r.stamp(Stamp::kBuildEnd);
}

void recordScanRaysRt(Recorder& r, TraceScene scene, std::uint32_t points, bool discretize) {
  // With discretize, one invocation per point covers the distinct end cells (at most as many).
  const gpu::ScanRaysRtConstants pc{
      .boxes = scene.boxes,
      .point_count = points,
      .mode = discretize ? gpu::kRayKeysEndCells : gpu::kRayKeysPoints};
  if (scene.pipeline)
    traceRays(r, kScanRaygen, points, pc);
  else
    r.dispatch<Shader::kScanRaysRt>(points, pc);
}

}  // namespace octovk::passes
