// Stage 3, the log-odds update: tree_gate.comp (does the scan fit: sets the dispatch arguments
// below, or none and marks the scan not applied), tree_begin.comp, alloc.comp, tree_fixup.comp,
// link.comp (the blocks classify counted, created and hung in the tree) and descend.comp (each
// active cell's leaf updated, nodes created on the way where needed). All sizes come from the
// device's counters: the host records this without having seen classify's results.
#include "map/passes/passes.hpp"

namespace octovk::passes {

void recordTreeUpdate(Recorder& r) {
  r.dispatch<Shader::kTreeGate>(1);
  r.dispatch<Shader::kTreeBegin>(1);
  r.dispatchIndirect<Shader::kAlloc>(offsetof(gpu::ScanCounters, block_args));
  r.dispatch<Shader::kTreeFixup>(1);
  r.dispatchIndirect<Shader::kLink>(offsetof(gpu::ScanCounters, block_args));
  r.dispatchIndirect<Shader::kDescend>(offsetof(gpu::ScanCounters, active_args));
  r.stamp(Stamp::kTreeUpdateEnd);
}

}  // namespace octovk::passes
