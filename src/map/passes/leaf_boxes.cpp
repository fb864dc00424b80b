// Stage 5, the leaf boxes: leaf_boxes.comp over every block, rebuilding the map's leaf-box buffer
// or compacting the leaves of a box query.
#include "map/passes/passes.hpp"

namespace octovk::passes {

namespace {
// The one dispatch of leaf_boxes.comp: over every block of the pool, in `mode`.
void dispatchLeafBoxes(Recorder& r, std::uint32_t mode) {
  r.dispatch<Shader::kLeafBoxes>(r.buffers.poolBlocks(), gpu::LeafBoxesConstants{.mode = mode});
}
}  // namespace

void recordLeafBoxes(Recorder& r) {
  r.stream.fill(r.buffers.pool, 0u, offsetof(gpu::PoolState, leaf_count), sizeof(std::uint32_t));
  r.stream.barrier();
  dispatchLeafBoxes(r, gpu::kLeafBoxesRebuild);
  r.stamp(Stamp::kLeafBoxesEnd);
}

void recordLeavesInBox(Recorder& r, const gpu::ScanParams& sp, const gpu::BoxQuery& box) {
  MapBuffers& b = r.buffers;
  r.setParams(sp);
  r.stream.update(b.query_in, &box, sizeof(box));
  r.stream.fill(b.counters, 0u, offsetof(gpu::ScanCounters, query_results), sizeof(std::uint32_t));
  r.stream.barrier();
  dispatchLeafBoxes(r, gpu::kLeafBoxesInBox);
}

}  // namespace octovk::passes
