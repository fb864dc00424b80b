// Stage 3, the log-odds update: tree_begin.comp, alloc.comp, tree_fixup.comp, link.comp (the
// blocks classify counted, created and hung in the tree) and descend.comp (each active cell's
// leaf updated, nodes created on the way where needed).
#include "map/passes/passes.hpp"

namespace octovk::passes {

void recordTreeUpdate(Recorder& r, std::uint32_t new_blocks, std::uint32_t active,
                      std::uint32_t descending) {
  r.dispatch("tree_begin", 1);
  if (new_blocks > 0) {
    r.dispatch("alloc", new_blocks);
    r.dispatch("tree_fixup", 1);
    r.dispatch("link", new_blocks);
  }
  r.dispatch("descend", active,
             gpu::DescendConstants{.cell_count = active, .descending = descending});
  r.stream.timestamp();
}

}  // namespace octovk::passes
