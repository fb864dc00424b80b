#version 450
#extension GL_GOOGLE_include_directive : require
// One level of the ascent (updateNodeRecurs going up), over the parents of the nodes updated one
// level below:
// pruneNode when all 8 children exist, are leaves and hold equal values; otherwise the node takes
// the max of its children (updateOccupancyChildren). Pruned blocks go onto the free stack.
#include "common.glsl"
#include "tree.glsl"

void main() {
  uint r = invocationIndex();
  uint level = pc.level;
  if (r >= counters.touched_count[level]) return;
  uint n = touched[level * params.active_capacity + r];
  uint children = nodes[n].mask & kChildMask;
  uint block = nodes[n].children;

  bool collapsible = children == kChildMask;
  float first = nodes[block * 8u].log_odds;
  float max_value = -3.40282347e38;
  for (uint s = 0u; s < 8u; ++s) {
    if ((children & (1u << s)) == 0u) continue;
    Node child = nodes[block * 8u + s];
    if ((child.mask & kChildMask) != 0u || child.log_odds != first) collapsible = false;
    if (child.log_odds > max_value) max_value = child.log_odds;
  }
  if (collapsible) {
    nodes[n] = Node(first, kNoBlock, 0u);
    block_meta[block].parent = kNoBlock;
    uint at = atomicAdd(pool.free_count, 1u);
    free_stack[at] = block;
    atomicAdd(pool.live_nodes, uint(-8));
    atomicAdd(counters.pruned_blocks, 1u);
  } else {
    nodes[n].log_odds = max_value;
    nodes[n].mask = children;
  }
  if (level > 0u) listParent(level - 1u, n);
}
