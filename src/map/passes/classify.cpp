// Stage 2, cells against the tree: list_cells.comp (the distinct cells of the cell set),
// classify.comp (early abort, existing leaf or descent) and classify_blocks.comp (over the cells
// that descend: nodes to create, new-block prefixes).
#include "map/passes/passes.hpp"

namespace octovk::passes {

void recordClassify(Recorder& r, bool discretize, std::uint32_t points) {
  r.stamp(Stamp::kClassifyStart);
  // The second set now collects the prefixes of nodes that get a block: empty discretize's end
  // cells out of it first.
  if (discretize) recordClearSets(r, ClearSets::kEndCells, points);
  r.dispatchIndirect<Shader::kListCells>(offsetof(gpu::ScanCounters, brick_args));
  r.dispatchIndirect<Shader::kClassify>(offsetof(gpu::ScanCounters, cell_args));
  r.dispatchIndirect<Shader::kClassifyBlocks>(offsetof(gpu::ScanCounters, active_args));
  r.stamp(Stamp::kClassifyEnd);
}

}  // namespace octovk::passes
