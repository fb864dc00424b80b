#version 450
#extension GL_GOOGLE_include_directive : require
// The descent and the log-odds update (updateNodeRecurs going down, then updateNodeLogOdds), for
// every active cell in one pass. A cell starts at the deepest node that existed before the scan
// (found by classify) and walks to its leaf. At a node that lacks the child:
// - the node had children before the scan: the child's slot is ready (classify made it), the
//   cell switches its bit on (createNodeChild);
// - otherwise the cell links the block alloc gave to this node (every cell that gets here links
//   the same one) and switches on that child alone if the node was created in this scan
//   (createNodeChild), all 8 if it is a pruned leaf or the child of an expansion (expandNode).
// At the leaf: add the update, clamp, and list the parent for the prune pass.
//
// No ordering between invocations is needed: a node's block is a function of the node (its
// entry in the second set), so a cell that does not yet see another cell's link finds the block
// itself; child bits only grow, by atomicOr; block contents were written by earlier passes.
#include "common.glsl"
#include "tree.glsl"

void main() {
  uint i = invocationIndex();
  if (i >= pc.count) return;
  // pc.offset cells that descend at the front of `cells`, the ones whose leaf existed at the back
  // (see classify).
  ActiveCell cell = cells[i < pc.offset ? i : params.hash_capacity - 1u - (i - pc.offset)];
  uvec3 k = cellKey(cell.slot);
  uint n = cell.node;
  uint parent = cell.parent;
  uint added = 0u;
  for (uint d = cell.depth; d < kTreeDepth; ++d) {
    uint c = childIndex(k, d);
    uint bit = 1u << c;
    uint m = nodes[n].mask;
    uint block = nodes[n].children;
    bool linked = block != kNoBlock;
    if (!linked) {
      block = blockOfPrefix(k, d);
      if (block == kNoBlock) {  // not counted by classify: cannot happen
        atomicOr(counters.status, kStatusPoolFull);
        return;
      }
    }
    if ((m & bit) == 0u) {
      uint want = !linked && (m & kFlagNew) == 0u ? kChildMask : bit;
      if (!linked) {
        block_meta[block].parent = n;
        nodes[n].children = block;
      }
      uint before = atomicOr(nodes[n].mask, want);
      added += bitCount(want & ~before);
    }
    parent = n;
    n = block * 8u + c;
  }
  if (added != 0u) atomicAdd(pool.live_nodes, added);

  precise float value = nodes[n].log_odds + cellUpdate(cell.slot);
  if (value < params.clamp_min_log) value = params.clamp_min_log;
  else if (value > params.clamp_max_log) value = params.clamp_max_log;
  nodes[n].log_odds = value;
  nodes[n].mask = 0u;
  listNode(kTreeDepth - 1u, parent);
}
