#version 450
#extension GL_GOOGLE_include_directive : require
// Gives every node that gets children in this scan (the entries of the second set, listed by
// classify) its block of 8 child slots: the n-th entry takes the n-th block from the top of the
// free-block stack, then from the never-used tail, and fills it:
// - under a pruned leaf (the leaf itself, or a child of its expansion): expandNode, 8 children
//   with the leaf's value;
// - a node created in this scan: createNodeChild, children at 0 that the descent switches on.
// The link pass then hangs the blocks in the tree.
#include "node.glsl"

void main() {
  uint n = invocationIndex();
  if (n >= counters.new_blocks) return;
  uint slot = SLOTS[params.hash_capacity + n];
  NewBlock nb = PREFIX_BLOCKS[slot];

  uint block;
  if (n < pool.free_count) {
    block = FREE_STACK[pool.free_count - 1u - n];
  } else {
    block = pool.bump + (n - pool.free_count);
    if (block >= pool.capacity) {  // the host sizes the pool so this cannot happen
      atomicOr(counters.status, kStatusPoolFull);
      return;
    }
  }
  PREFIX_BLOCKS[slot].block = block;

  // Children of an expansion exist at once; the ones of a created node when the descent
  // switches them on.
  bool expand = nb.source != kNoBlock;
  NodeData data = expand ? nodeData(nb.source) : newNodeData();
  uint link = expand ? kNoChildren | kFlagLive : kNoChildren;
  for (uint s = 0u; s < 8u; ++s) {
    setNodeData(block * 8u + s, data);
    setLink(block * 8u + s, link);
  }
  if (expand) atomicAdd(pool.live_nodes, 8u);
  BLOCK_PARENT[block] = kNoBlock;  // set by link
}
