#version 450
#extension GL_GOOGLE_include_directive : require
// One level of the ascent (updateNodeRecurs going up), over the parents of the nodes updated one
// level below:
// pruneNode when all 8 children exist, are leaves and hold equal values; otherwise the node takes
// the max of its children (updateOccupancyChildren). Pruned blocks go onto the free stack.
#include "bindings.glsl"
#include "tree.glsl"

layout(push_constant) uniform PushBlock { PruneConstants pc; };

void main() {
  uint r = invocationIndex();
  uint level = pc.level;
  if (r >= counters.touched_count[level]) return;
  uint base = touchedBase(level);
  uint n = TOUCHED[base + r];
  // n and its children are read plainly: this level's invocations write only their own node,
  // and listParent marks the level above.
  uint block = settledLinkOf(n) & kBlockMask;
  bool collapsible;
  NodeData inner = summariseChildren(n, block, collapsible);
  if (collapsible) {
    setNodeData(n, prunedNodeData(block));
    setLink(n, kNoChildren | kFlagLive);
    BLOCK_PARENT[block] = kNoBlock;
    uint at = atomicAdd(pool.free_count, 1u);
    FREE_STACK[at] = block;
    atomicAdd(pool.live_nodes, uint(-8));
  } else {
    setNodeData(n, inner);
    setLink(n, block | kFlagLive);
  }
  // The level above starts right after this one, which is complete.
  if (level > 0u) listParent(level - 1u, base + counters.touched_count[level], n);
}
