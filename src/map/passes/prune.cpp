// Stage 4, inner nodes and pruning: prune.comp once per level, deepest first, over the nodes the
// update touched at that level (indirect: descend counts them).
#include "map/passes/passes.hpp"

namespace octovk::passes {

void recordPrune(Recorder& r) {
  for (std::uint32_t level = gpu::kTreeDepth; level-- > 0;)
    r.dispatchIndirect<Shader::kPrune>(
        offsetof(gpu::ScanCounters, touched_args) + level * sizeof(gpu::DispatchArgs),
        gpu::PruneConstants{.level = level});
  r.stamp(Stamp::kPruneEnd);
}

}  // namespace octovk::passes
