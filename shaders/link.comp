#version 450
#extension GL_GOOGLE_include_directive : require
// Hangs each block alloc filled under its node: the node is known (it existed before alloc), or
// it is a child in the block of the node one level up. (An expansion's children exist already;
// a created node's children are switched on by the descent, one per path.)
#include "hash_set.glsl"

void main() {
  uint n = invocationIndex();
  if (n >= counters.new_blocks) return;
  uint slot = slots[params.hash_capacity + n];
  NewBlock nb = prefix_blocks[slot];
  uint node = nb.node;
  uint64_t prefix = endpoint_keys[slot];
  uint depth = uint(prefix >> 48);
  if (node == kNoBlock) {
    uvec3 k = unpackKey(prefix);
    uint up = findEndpoint(prefixKey(k, depth - 1u));
    if (up == kNoBlock) {  // classify lists every node above a listed one: cannot happen
      atomicOr(counters.status, kStatusPoolFull);
      return;
    }
    node = prefix_blocks[up].block * 8u + childIndex(k, depth - 1u);
  }
  nodes[node].link = (nodes[node].link & ~kBlockMask) | nb.block;
  block_parent[nb.block] = node;
}
