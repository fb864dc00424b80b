#version 450
#extension GL_GOOGLE_include_directive : require
// Gives each node that asked at this level a block of 8 child slots, from the free-block stack
// first, then from the never-used tail. A node that existed before this scan (or came from an
// expansion) and has no children is a pruned leaf: expandNode, 8 children with its value.
// A node created in this scan gets only the children asked for, at 0 (createNodeChild).
#include "common.glsl"
#include "tree.glsl"

void main() {
  uint r = invocationIndex();
  uint level = pc.level;
  if (r >= counters.alloc_count[level]) return;
  AllocRequest req = alloc_list[level * params.active_capacity + r];
  uint n = req.node;

  uint pop = atomicAdd(pool.pops, 1u);
  uint block;
  if (pop < pool.free_count) {
    block = free_stack[pool.free_count - 1u - pop];
  } else {
    block = atomicAdd(pool.bump, 1u);
    if (block >= pool.capacity) {  // the host sizes the pool so this cannot happen
      atomicOr(counters.status, kStatusPoolFull);
      return;
    }
  }

  uint m = nodes[n].mask;
  uint want = (m >> kWantShift) & kChildMask;
  bool expand = (m & kFlagNew) == 0u;
  float parent_value = nodes[n].log_odds;
  for (uint s = 0u; s < 8u; ++s) {
    if (expand) nodes[block * 8u + s] = Node(parent_value, kNoBlock, 0u);
    else nodes[block * 8u + s] = Node(0.0, kNoBlock, (want & (1u << s)) != 0u ? kFlagNew : 0u);
  }
  uint children = expand ? kChildMask : want;
  atomicAdd(pool.live_nodes, uint(bitCount(children)));
  nodes[n].children = block;
  nodes[n].mask = (m & (kFlagNew | kFlagTouched)) | children;

  uvec3 k = cellKey(cells[req.cell].slot);
  uint keep = level == 0u ? 0u : (0xFFFFu << (kTreeDepth - level)) & 0xFFFFu;
  block_meta[block] = BlockMeta(n, level, (k.x & keep) | ((k.y & keep) << 16), k.z & keep);
}
