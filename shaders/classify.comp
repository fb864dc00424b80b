#version 450
#extension GL_GOOGLE_include_directive : require
// Early abort: for every distinct cell of the scan, OctoMap's search() on the tree as it was
// before the scan; cells already at the clamping bound in their update's direction are dropped,
// the rest become the active cells of the tree passes.
#include "common.glsl"
#include "tree.glsl"

void main() {
  uint i = invocationIndex();
  if (i >= counters.hash_entries) return;
  uint slot = slots[i];
  bool occupied = (hash_flags[slot] & kHashFlagOccupied) != 0u;
  if (occupied) atomicAdd(counters.occupied_cells, 1u);
  else atomicAdd(counters.free_cells, 1u);
  float update = cellUpdate(slot);
  uvec3 k = cellKey(slot);

  // search(): the deepest existing node on the path; a node with other children but not this
  // one means "not found". depth = depth of the deepest existing node (0 without a root).
  uint n, depth;
  bool found = searchNode(k, n, depth);
  float value = nodes[n].log_odds;
  if (found && ((update >= 0.0 && value >= params.clamp_max_log) ||
                (update <= 0.0 && value <= params.clamp_min_log))) {
    atomicAdd(counters.aborted, 1u);
    return;
  }
  // The descent starts at the deepest existing node (the root, created by tree_begin, if none).
  // Cells whose leaf exists need no descent: they are kept at the back of `cells`, so that the
  // descent passes run over the front part only.
  uint at;
  if (depth == kTreeDepth) {
    at = params.hash_capacity - 1u - atomicAdd(counters.first_depth_hist[kTreeDepth], 1u);
  } else {
    at = atomicAdd(counters.active_cells, 1u);
    atomicAdd(counters.first_depth_hist[depth], 1u);
  }
  cells[at] = ActiveCell(slot, n, kNoBlock, depth);

  // Exact count of the blocks this scan allocates: one per distinct node on an active path that
  // has no children yet (a missing root, a pruned leaf, or a node still to be created). The
  // host grows the pool to fit before the tree changes, so the update passes cannot run out.
  uint first = pool.root_exists == 0u ? 0u : (found ? depth : depth + 1u);
  for (uint d = first; d < kTreeDepth; ++d) {
    uint keep = d == 0u ? 0u : (0xFFFFu << (kTreeDepth - d)) & 0xFFFFu;
    uint64_t prefix = packKey(k & uvec3(keep)) | (uint64_t(d) << 48);
    uint prefix_slot;
    if (insertEndpoint(prefix, prefix_slot) == 1u)
      countEndpointEntry(atomicAdd(counters.new_blocks, 1u), prefix_slot);
  }
}
