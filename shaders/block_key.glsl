// Where a block of the pool sits in the tree: the key prefix and depth of the node it hangs
// under, from the slots of the nodes above it (the node at depth d is child `slot` of the node
// above, which sets bit 16 - d of the key).
#ifndef OCTOVK_BLOCK_KEY_GLSL
#define OCTOVK_BLOCK_KEY_GLSL

#include "bindings.glsl"

uvec3 parentKeyOfBlock(uint parent, out uint depth) {
  uvec3 up_bits = uvec3(0u);
  depth = 0u;
  for (uint n = parent; n != kRootNode && depth < kTreeDepth; n = BLOCK_PARENT[n / 8u]) {
    uint s = n % 8u;
    up_bits |= uvec3(s & 1u, (s >> 1) & 1u, (s >> 2) & 1u) << depth;
    ++depth;
  }
  return depth == 0u ? uvec3(0u) : up_bits << (kTreeDepth - depth);
}

// Whether the node at `depth` with key prefix `prefix` is one OctoMap's leaf_bbx_iterator visits
// for the box of keys [lo, hi]: its key range, as the iterator computes it from the node's centre
// key (prefix + 32768 >> depth), overlaps the box's.
bool nodeMeetsBox(uvec3 prefix, uint depth, uvec3 lo, uvec3 hi) {
  int off = int(kTreeMaxVal >> depth);
  ivec3 centre = ivec3(prefix) + ivec3(off);
  return !any(greaterThan(ivec3(lo), centre + off)) && !any(lessThan(ivec3(hi), centre - off));
}

#endif  // OCTOVK_BLOCK_KEY_GLSL
