#version 450
#extension GL_GOOGLE_include_directive : require
// Hangs each block alloc filled under its node: the node is known (it existed before alloc), or
// it is a child in the block of the node one level up. (An expansion's children exist already;
// a created node's children are switched on by the descent, one per path.)
#include "cell_set.glsl"
#include "node.glsl"

void main() {
  uint n = invocationIndex();
  if (n >= counters.new_blocks) return;
  uint slot = SLOTS[params.hash_capacity + n];
  NewBlock nb = PREFIX_BLOCKS[slot];
  uint node = nb.node;
  uint64_t prefix = ENDPOINT_KEYS[slot];
  uint depth = uint(prefix >> 48);
  if (node == kNoBlock) {
    uvec3 k = unpackKey(prefix);
    uint up = findEndpoint(prefixKey(k, depth - 1u));
    if (up == kNoBlock) {  // classify lists every node above a listed one: cannot happen
      atomicOr(counters.status, kStatusPoolFull);
      return;
    }
    node = PREFIX_BLOCKS[up].block * 8u + childIndex(k, depth - 1u);
  }
  // Only this invocation writes the node in the dispatch, and none reads it.
  setLink(node, (settledLinkOf(node) & ~kBlockMask) | nb.block);
  BLOCK_PARENT[nb.block] = node;
}
