// Map surgery, clearing a box: clear_box.comp over every block of the pool, first listing the
// blocks by depth, then the leaves in the box (octomap_server's clear_bbx:
// setLogOdds(clamping_thres_min)), then over each depth's list, from the deepest, the inner nodes
// (updateInnerOccupancy).
#include "map/passes/passes.hpp"

namespace octovk::passes {

void recordClearBox(Recorder& r, const gpu::ScanParams& sp, const gpu::BoxQuery* box) {
  MapBuffers& b = r.buffers;
  const std::uint32_t blocks = b.poolBlocks();
  r.setParams(sp);
  // The lists by depth are counted in the prune pass's counters, free between scans.
  const gpu::ScanCounters fresh = freshCounters();
  r.stream.update(b.counters, &fresh, sizeof(fresh));
  if (box) r.stream.update(b.query_in, box, sizeof(*box));
  r.stream.barrier();
  r.dispatch<Shader::kClearBox>(blocks, gpu::ClearBoxConstants{.mode = gpu::kClearBoxDepths});
  r.stream.barrier();
  if (box) {
    r.dispatch<Shader::kClearBox>(blocks, gpu::ClearBoxConstants{.mode = gpu::kClearBoxLeaves});
    r.stream.barrier();
  }
  for (std::uint32_t level = gpu::kTreeDepth; level-- > 0;) {
    r.dispatchIndirect<Shader::kClearBox>(
        offsetof(gpu::ScanCounters, touched_args) + level * sizeof(gpu::DispatchArgs),
        gpu::ClearBoxConstants{.mode = gpu::kClearBoxInner, .level = level});
    r.stream.barrier();
  }
}

}  // namespace octovk::passes
