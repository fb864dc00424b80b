#version 450
#extension GL_GOOGLE_include_directive : require
// Early abort: for every distinct cell of the scan, OctoMap's search() on the tree as it was
// before the scan; cells already at the clamping bound in their update's direction are dropped,
// the rest become the active cells of the tree passes. What the descent will create for the
// active cells is counted by classify_blocks.comp, over the cells that descend only: llvmpipe
// (Mesa 22.3) runs all of a shader's code for every group of lanes, masked, so that code kept
// here would cost every cell, while after a few scans most cells end here.
#include "tree_search.glsl"
#include "tree.glsl"


void main() {
  uint i = invocationIndex();
  // A set found too small (the scan is redone): nothing to classify.
  if ((OCTOVK_LOAD(counters.status) & kStatusHashFull) != 0u) return;
  if (i >= counters.cell_entries) return;
  uint slot = CELL_LIST[i];
  // list_cells counted the free and occupied cells per brick, tree_gate the aborted ones: one
  // atomic per cell less each (per lane and masked on llvmpipe).
  float update = cellUpdate(slot);
  uvec3 k = cellKey(slot);

  // search(): the deepest existing node on the path; a node with other children but not this
  // one means "not found". depth = depth of the deepest existing node (0 without a root).
  // list_cells searched down to the brick's node for all cells of the brick; an open search
  // goes on from there.
  uint brick = (slot / kCellsPerBrick) * kBrickFlagWords;
  uint n = CELL_SET_FLAGS[brick];
  uint shared_search = CELL_SET_FLAGS[brick + 1u];
  uint depth = shared_search & 0xFFu;
  bool found = (shared_search & kBrickFound) != 0u;
  uint parent = n == kRootNode ? kNoBlock : BLOCK_PARENT[n / 8u];
  if ((shared_search & kBrickOpen) != 0u &&
      searchDown(k, kTreeDepth, n, parent, depth) == kSearchMissing)
    found = false;
  float value = nodeLogOdds(n);
  // list_cells dropped the cells it found aborted already; the test stays (same tree, same
  // answer), so that what classify lists never depends on it.
  if (found && earlyAbort(update, value)) {
    return;
  }
  // The descent starts at the deepest existing node (the root, created by tree_begin, if none).
  // Cells whose leaf exists need no descent: they are kept at the back of `CELLS`.
  uint at;
  if (depth == kTreeDepth) {
    at = params.cell_capacity - 1u - atomicAdd(counters.leaf_cells, 1u);
  } else {
    at = atomicAdd(counters.active_cells, 1u);
    // classify_blocks runs over these (tree_gate sets these arguments again for descend).
    if (at % kWorkgroupSize == 0u) OCTOVK_COVER_LIST(counters.active_args, at + 1u);
  }
  CELLS[at] = ActiveCell(slot, n, parent, depth);
}

