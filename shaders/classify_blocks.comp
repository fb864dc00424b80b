#version 450
#extension GL_GOOGLE_include_directive : require
// What the descent creates, for the active cells that descend (classify put them at the front
// of `CELLS`: their search ended above the finest level): the child slot the path steps into
// made ready, and each node on the path that gets a block listed once in the second set, with
// the exact count of new blocks that tree_gate checks against the pool.
#include "cell_set.glsl"
#include "tree_search.glsl"
#include "tree.glsl"

// A child slot made ready for the descent: a new node's data, no children, not live yet.
void prepareChild(uint slot) {
  setNodeData(slot, newNodeData());
  atomicSetLink(slot, kNoChildren);
}

void main() {
  uint i = invocationIndex();
  if ((OCTOVK_LOAD(counters.status) & kStatusHashFull) != 0u) return;
  if (i >= counters.active_cells) return;
  ActiveCell cell = CELLS[i];
  uvec3 k = cellKey(cell.slot);
  uint n = cell.node;
  uint depth = cell.depth;
  // classify's search found the cell's node (a leaf above the finest level, whose children the
  // descent creates by expansion) or stopped at a node that has other children but not this
  // one. No pass before this one changed n's link.
  bool found = pool.root_exists != 0u && childBlock(n) == kNoChildren;

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
    PREFIX_BLOCKS[prefix_slot] = NewBlock(node, source, kNoBlock);
  }
}
