#version 450
#extension GL_GOOGLE_include_directive : require
// Gives every node that gets children in this scan (the entries of the second set, counted by
// classify) its block of 8 child slots: the n-th entry takes the n-th block from the top of the
// free-block stack, then from the never-used tail. The block is filled before the descent links
// it, from the tree as it was before the scan:
// - the node lies at or under a pruned leaf (a leaf that existed, or its expansion): expandNode,
//   8 children with the leaf's value;
// - otherwise the node is created in this scan: createNodeChild, children at 0 that the descent
//   switches on one by one.
#include "common.glsl"

void main() {
  uint n = invocationIndex();
  if (n >= counters.new_blocks) return;
  uint slot = slots[params.hash_capacity + n];
  uint64_t prefix = endpoint_keys[slot];
  uint depth = uint(prefix >> 48);
  uvec3 k = unpackKey(prefix);

  uint block;
  if (n < pool.free_count) {
    block = free_stack[pool.free_count - 1u - n];
  } else {
    block = pool.bump + (n - pool.free_count);
    if (block >= pool.capacity) {  // the host sizes the pool so this cannot happen
      atomicOr(counters.status, kStatusPoolFull);
      return;
    }
  }
  endpoint_blocks[slot] = block;

  // The deepest existing node on the way to the prefix's node.
  uint node = kRootNode;
  uint d = 0u;
  for (; d < depth; ++d) {
    uint m = nodes[node].mask;
    uint c = childIndex(k, d);
    if ((m & (1u << c)) == 0u) break;
    node = nodes[node].children * 8u + c;
  }
  uint m = nodes[node].mask;
  bool expand = (m & kChildMask) == 0u && (m & kFlagNew) == 0u;
  Node child = expand ? Node(nodes[node].log_odds, kNoBlock, 0u) : Node(0.0, kNoBlock, kFlagNew);
  for (uint s = 0u; s < 8u; ++s) nodes[block * 8u + s] = child;
  // The parent is set by the descent, which links the block.
  block_meta[block] = BlockMeta(kNoBlock, depth, uint(prefix & 0xFFFFFFFFul), k.z);
}
