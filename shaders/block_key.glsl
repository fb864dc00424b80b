// Where a block of the pool sits in the tree: the key prefix and depth of the node it hangs
// under, from the slots of the nodes above it (the node at depth d is child `slot` of the node
// above, which sets bit 16 - d of the key).
#ifndef OCTOVK_BLOCK_KEY_GLSL
#define OCTOVK_BLOCK_KEY_GLSL

#include "bindings.glsl"

uvec3 parentKeyOfBlock(uint parent, out uint depth) {
  uvec3 up_bits = uvec3(0u);
  depth = 0u;
  for (uint n = parent; n != kRootNode && depth < kTreeDepth; n = block_parent[n / 8u]) {
    uint s = n % 8u;
    up_bits |= uvec3(s & 1u, (s >> 1) & 1u, (s >> 2) & 1u) << depth;
    ++depth;
  }
  return depth == 0u ? uvec3(0u) : up_bits << (kTreeDepth - depth);
}

#endif  // OCTOVK_BLOCK_KEY_GLSL
