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
  uint n = TOUCHED[level * params.active_capacity + r];
  uint link = NODES[n].link;
  uint block = link & kBlockMask;

  bool collapsible = true;
  float first = NODES[block * 8u].log_odds;
  float max_value = -3.40282347e38;
  for (uint s = 0u; s < 8u; ++s) {
    Node child = NODES[block * 8u + s];
    if ((child.link & kFlagLive) == 0u) {
      collapsible = false;
      continue;
    }
    if ((child.link & kBlockMask) != kNoChildren || child.log_odds != first) collapsible = false;
    if (child.log_odds > max_value) max_value = child.log_odds;
  }
  if (collapsible) {
    NODES[n] = Node(first, kNoChildren | kFlagLive);
    BLOCK_PARENT[block] = kNoBlock;
    uint at = atomicAdd(pool.free_count, 1u);
    FREE_STACK[at] = block;
    atomicAdd(pool.live_nodes, uint(-8));
  } else {
    NODES[n].log_odds = max_value;
    NODES[n].link = block | kFlagLive;
  }
  if (level > 0u) listParent(level - 1u, n);
}
