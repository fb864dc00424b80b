#version 450
#extension GL_GOOGLE_include_directive : require
// Early abort: for every distinct cell of the scan, OctoMap's search() on the tree as it was
// before the scan; cells already at the clamping bound in their update's direction are dropped,
// the rest become the active cells of the tree passes.
#include "common.glsl"
#include "tree.glsl"

// A child slot made ready for the descent: log-odds 0, no children, not live yet.
void prepareChild(uint slot) {
  nodes[slot].log_odds = 0.0;
  atomicExchange(nodes[slot].link, kNoChildren);
}

void main() {
  uint i = invocationIndex();
  // A set found too small (the scan is redone): nothing to classify.
  if ((OCTOVK_LOAD(counters.status) & kStatusHashFull) != 0u) return;
  if (i >= counters.cell_entries) return;
  uint slot = cell_list[i];
  bool occupied = cellOccupied(slot);
  if (occupied) atomicAdd(counters.occupied_cells, 1u);
  else atomicAdd(counters.free_cells, 1u);
  float update = cellUpdate(slot);
  uvec3 k = cellKey(slot);

  // search(): the deepest existing node on the path; a node with other children but not this
  // one means "not found". depth = depth of the deepest existing node (0 without a root).
  // list_cells searched down to the brick's node for all cells of the brick; an open search
  // goes on from there.
  uint brick = (slot / kCellsPerBrick) * kBrickFlagWords;
  uint n = hash_flags[brick];
  uint shared_search = hash_flags[brick + 1u];
  uint depth = shared_search & 0xFFu;
  bool found = (shared_search & kBrickFound) != 0u;
  uint parent = n == kRootNode ? kNoBlock : block_parent[n / 8u];
  if ((shared_search & kBrickOpen) != 0u &&
      searchDown(k, kTreeDepth, n, parent, depth) == kSearchMissing)
    found = false;
  float value = nodes[n].log_odds;
  if (found && ((update >= 0.0 && value >= params.clamp_max_log) ||
                (update <= 0.0 && value <= params.clamp_min_log))) {
    atomicAdd(counters.aborted, 1u);
    return;
  }
  // The descent starts at the deepest existing node (the root, created by tree_begin, if none).
  // Cells whose leaf exists need no descent: they are kept at the back of `cells`.
  uint at;
  if (depth == kTreeDepth) {
    at = params.cell_capacity - 1u - atomicAdd(counters.leaf_cells, 1u);
  } else {
    at = atomicAdd(counters.active_cells, 1u);
  }
  cells[at] = ActiveCell(slot, n, parent, depth);

  // The path leaves an inner node that lacks this child: the child slot of its existing block is
  // made ready (no pass before the descent steps into it), so that the descent only sets the
  // child's bit. One invocation writes it: the one cell whose leaf it is (depth 15), else the
  // one cell that inserts the child's entry into the second set below. Others read its link
  // (atomically) meanwhile: not live before, not live after.
  bool prepare = !found && pool.root_exists != 0u;
  uint prepared = prepare ? childBlock(n) * 8u + childIndex(k, depth) : kNoBlock;
  if (prepare && depth + 1u == kTreeDepth) prepareChild(prepared);

  // Exact count of the blocks this scan allocates: one per distinct node on an active path that
  // has no children yet (a missing root, a pruned leaf, or a node still to be created). The
  // host grows the pool to fit before the tree changes, so the update passes cannot run out.
  // From the deepest such node up: a node already listed was listed by a cell that also lists
  // every node above it (their paths agree up to there), so the walk stops at the first one.
  // Each listed node records what alloc needs: whether it exists before alloc runs (the root,
  // the pruned leaf itself, or the child made ready above) and whether its block is an expansion.
  uint first = pool.root_exists == 0u ? 0u : (found ? depth : depth + 1u);
  uint known_depth = pool.root_exists == 0u ? 0u : first;
  uint known_node = pool.root_exists == 0u
                        ? kRootNode
                        : (found ? n : childBlock(n) * 8u + childIndex(k, depth));
  uint source = found && pool.root_exists != 0u ? n : kNoBlock;
  for (uint d = kTreeDepth; d-- > first;) {
    uint prefix_slot;
    uint inserted = insertEndpoint(prefixKey(k, d), prefix_slot);
    if (inserted != 1u) break;  // present, or the set is full (the scan is then redone)
    if (prepare && d == depth + 1u) prepareChild(prepared);
    countEndpointEntry(atomicAdd(counters.new_blocks, 1u), prefix_slot);
    uint node = d == known_depth ? known_node : kNoBlock;
    prefix_blocks[prefix_slot] = NewBlock(node, source, kNoBlock);
  }
}
