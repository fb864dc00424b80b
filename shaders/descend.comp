#version 450
#extension GL_GOOGLE_include_directive : require
// The descent and the log-odds update (updateNodeRecurs going down, then updateNodeLogOdds), for
// every active cell in one pass. A cell starts at the deepest node that existed before the scan
// (found by classify) and walks to its leaf; every node on the way has its block of children
// (alloc and link gave one to each node that had none). A child missing on the way is switched on
// (createNodeChild: classify or alloc made its slot ready). At the leaf: add the update, clamp,
// and list the parent for the prune pass. Live bits only grow, by atomicOr, so the cells need
// no ordering between them. With change detection on, each updated leaf is noted in the change
// set (change_set.glsl): created when this cell switched its leaf's slot on (createNodeChild: the
// slot was made ready but not live; a leaf under an expanded pruned node was made live by alloc
// with the pruned value, expandNode), flipped when isNodeOccupied changed.
#include "tree_search.glsl"
#include "tree.glsl"
#include "change_set.glsl"


void main() {
  uint i = invocationIndex();
  // The cells that descend at the front of `CELLS`, the ones whose leaf existed at the back (see
  // classify); dispatched over both (tree_gate), nothing when the scan is not applied.
  uint descending = counters.active_cells;
  if (i >= descending + counters.leaf_cells) return;
  ActiveCell cell = CELLS[i < descending ? i : params.cell_capacity - 1u - (i - descending)];
  uvec3 k = cellKey(cell.slot);
  uint n = cell.node;
  uint parent = cell.parent;
  uint added = 0u;
  bool created = false;  // this cell switched its leaf on (the last child of the walk)
  for (uint d = cell.depth; d < kTreeDepth; ++d) {
    uint child = childBlock(n) * 8u + childIndex(k, d);
    created = false;
    if (!linkLive(linkOf(child))) {
      uint before = atomicOrLink(child, kFlagLive);
      if (!linkLive(before)) {
        ++added;
        created = true;
      }
    }
    parent = n;
    n = child;
  }
  if (added != 0u) atomicAdd(pool.live_nodes, added);

  float old_value = nodeLogOdds(n);
  precise float value = old_value + cellUpdate(cell.slot);
  if (value < params.clamp_min_log) value = params.clamp_min_log;
  else if (value > params.clamp_max_log) value = params.clamp_max_log;
  setUpdatedLeaf(n, value);
  noteChange(k, created,
             (old_value >= params.occupancy_log) != (value >= params.occupancy_log));
  setLink(n, kNoChildren | kFlagLive);
  listNode(kTreeDepth - 1u, 0u, parent);  // the deepest level's list starts at 0
}
