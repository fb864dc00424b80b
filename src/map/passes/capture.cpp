// A store's capture of the map after a scan, in the scan's own submission, into host-visible
// staging: the node pool, its payload and the touched lists copied whole, or (when the host holds
// the pool as it was before the scan) only what the scan changed, gathered by capture.comp. The
// commit then needs no submission of its own, and the next scan need not wait for it
// (ScanPipeline::record).
#include <algorithm>

#include "map/passes/passes.hpp"

namespace octovk::passes {

CaptureLayout captureLayout(const MapBuffers& b, Payload payload, bool change, bool folded,
                            std::size_t points) {
  CaptureLayout l;
  l.folded = folded;
  l.points = points;
  if (change) {
    // The lists' entries, then the folded list's (a node a point at most).
    l.records = (b.touched.valid() ? b.touched.size() / sizeof(std::uint32_t) : 0) +
                (folded ? b.pointCapacity() : 0);
    l.records = std::max<std::size_t>(l.records, 1);
    return l;
  }
  l.nodes =
      std::min<std::size_t>(std::size_t{b.poolBlocks()} * 8, b.nodes.size() / sizeof(gpu::Node));
  l.node_bytes = l.nodes * sizeof(gpu::Node);
  l.payload_bytes = payload != Payload::kNone ? l.nodes * sizeof(std::uint32_t) : 0;
  l.touched_bytes = b.touched.valid() ? b.touched.size() : 0;
  return l;
}

void recordCapture(Recorder& r, const CaptureLayout& l, const vk::Buffer& staging) {
  const MapBuffers& b = r.buffers;
  r.stream.barrier();  // after every pass of the scan
  if (l.records) {
    // A few workgroups, each invocation taking every stride-th entry: a scan lists some
    // thousand nodes, the lists have room for far more. A CPU device (lavapipe) runs every
    // workgroup whether it has entries or not: 8 there (FR-079's scans, about 1,400 records:
    // 0.2 ms a capture on Mesa 22.3 against 0.37 ms with 64), 64 on a GPU.
    const std::size_t invocations = r.device.info().type == "CPU" ? 64 * 8 : 64 * 64;
    const gpu::CaptureConstants pc{
        .records = staging.address(),
        .capacity = static_cast<std::uint32_t>(l.records),
        .folded_at = l.folded ? foldedListAt(b, l.points) : gpu::kNoFoldedList};
    r.dispatch<Shader::kCapture>(std::min(l.records, invocations), pc);
    return;
  }
  if (l.node_bytes) r.stream.copy(b.nodes, staging, l.node_bytes);
  if (l.payload_bytes) r.stream.copy(b.payload, staging, l.payload_bytes, 0, l.node_bytes);
  if (l.touched_bytes)
    r.stream.copy(b.touched, staging, l.touched_bytes, 0, l.node_bytes + l.payload_bytes);
}

}  // namespace octovk::passes
