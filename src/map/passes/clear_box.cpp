// Map surgery, clearing a box: clear_box.comp over every block of the pool, first listing the
// blocks by depth, then the leaves in the box (octomap_server's clear_bbx:
// setLogOdds(clamping_thres_min)), then over each depth's list, from the deepest, the inner nodes
// (updateInnerOccupancy).
#include "map/passes/passes.hpp"

namespace octovk::passes {

namespace {

// Lists the blocks by depth, runs `leaves` (a kClearBox* mode over every block, or none), then
// the inner nodes bottom-up in `inner` mode.
void recordBlocksThenInner(Recorder& r, const gpu::ScanParams& sp, const gpu::BoxQuery* box,
                           const gpu::ClearBoxConstants* leaves, gpu::ClearBoxConstants inner) {
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
  if (leaves) {
    r.dispatch<Shader::kClearBox>(blocks, *leaves);
    r.stream.barrier();
  }
  for (std::uint32_t level = gpu::kTreeDepth; level-- > 0;) {
    inner.level = level;
    r.dispatchIndirect<Shader::kClearBox>(
        offsetof(gpu::ScanCounters, touched_args) + level * sizeof(gpu::DispatchArgs), inner);
    r.stream.barrier();
  }
}

}  // namespace

void recordClearBox(Recorder& r, const gpu::ScanParams& sp, const gpu::BoxQuery* box) {
  const gpu::ClearBoxConstants leaves{.mode = gpu::kClearBoxLeaves};
  recordBlocksThenInner(r, sp, box, box ? &leaves : nullptr,
                        gpu::ClearBoxConstants{.mode = gpu::kClearBoxInner});
}

void recordDegrade(Recorder& r, const gpu::ScanParams& sp, std::uint32_t now,
                   std::uint32_t threshold) {
  const gpu::ClearBoxConstants leaves{
      .mode = gpu::kClearBoxDegrade, .now = now, .threshold = threshold};
  recordBlocksThenInner(r, sp, nullptr, &leaves,
                        gpu::ClearBoxConstants{.mode = gpu::kClearBoxInnerAt, .now = now});
}

}  // namespace octovk::passes
