// Map surgery, keeping only a box: keep_box.comp over every block of the pool, marking what is
// kept, deleting the rest (its blocks back on the free stack), clearing the marks. The inner
// nodes' values are then updated by recordClearBox without a box (updateInnerOccupancy).
#include "map/passes/passes.hpp"

namespace octovk::passes {

void recordKeepBox(Recorder& r, const gpu::ScanParams& sp, const gpu::BoxQuery* box) {
  MapBuffers& b = r.buffers;
  const std::uint32_t blocks = b.poolBlocks();
  r.setParams(sp);
  if (box) r.stream.update(b.query_in, box, sizeof(*box));
  r.stream.barrier();
  if (box) {  // without a box nothing is marked, so the sweep deletes the whole tree
    r.dispatch<Shader::kKeepBox>(blocks, gpu::KeepBoxConstants{.mode = gpu::kKeepBoxMark});
    r.stream.barrier();
  }
  r.dispatch<Shader::kKeepBox>(blocks, gpu::KeepBoxConstants{.mode = gpu::kKeepBoxSweep});
  r.stream.barrier();
  r.dispatch<Shader::kKeepBox>(blocks, gpu::KeepBoxConstants{.mode = gpu::kKeepBoxUnmark});
  r.stream.barrier();
}

}  // namespace octovk::passes
