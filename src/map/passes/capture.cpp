// A store's capture of the map after a scan, in the scan's own submission: the node pool, its
// payload and the touched lists copied to host-visible staging. The commit then needs no
// submission of its own, and the next scan need not wait for it (ScanPipeline::record).
#include <algorithm>

#include "map/passes/passes.hpp"

namespace octovk::passes {

CaptureLayout captureLayout(const MapBuffers& b, Payload payload) {
  CaptureLayout l;
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
  if (l.node_bytes) r.stream.copy(b.nodes, staging, l.node_bytes);
  if (l.payload_bytes) r.stream.copy(b.payload, staging, l.payload_bytes, 0, l.node_bytes);
  if (l.touched_bytes)
    r.stream.copy(b.touched, staging, l.touched_bytes, 0, l.node_bytes + l.payload_bytes);
}

}  // namespace octovk::passes
