#version 450
#extension GL_GOOGLE_include_directive : require
// One level of the descent (updateNodeRecurs going down), for every active cell at once.
// A cell at node n (depth pc.level) needs child c: if it exists, step into it; if n has a block
// of children, claim the slot and create c alone; if n has no children, ask the alloc pass for a
// block (alloc decides between OctoMap's expandNode and a single createNodeChild).
// Cells start at the deepest node that existed before the scan (found by classify), so a cell
// whose leaf exists skips every level.
#include "common.glsl"
#include "tree.glsl"

void main() {
  uint i = invocationIndex();
  if (i >= pc.count) return;
  uint level = pc.level;
  ActiveCell cell = cells[i];
  if (cell.depth > level) return;  // its path exists down to cell.depth: nothing to create here
  uint n = resolveNode(cell);

  // A child bit missed by this plain read is caught by the atomicOr below.
  uint old = nodes[n].mask;

  uint c = childIndex(cellKey(cell.slot), level);
  uint bit = 1u << c;
  uint block = nodes[n].children;  // only the alloc pass changes it
  if ((old & bit) != 0u) {
    cell.node = block * 8u + c;
    cell.pending = kNoBlock;
  } else if (block != kNoBlock) {
    uint before = atomicOr(nodes[n].mask, bit);
    uint child = block * 8u + c;
    if ((before & bit) == 0u) {
      nodes[child] = Node(0.0, kNoBlock, kFlagNew);
      atomicAdd(pool.live_nodes, 1u);
    }
    cell.node = child;
    cell.pending = kNoBlock;
  } else {
    if ((old & (bit << kWantShift)) == 0u) atomicOr(nodes[n].mask, bit << kWantShift);
    if ((old & kFlagAllocReq) == 0u) {
      uint before = atomicOr(nodes[n].mask, kFlagAllocReq);
      if ((before & kFlagAllocReq) == 0u) appendAlloc(level, n, i);
    }
    cell.node = n;
    cell.pending = c;
  }
  cells[i] = cell;
}
