// Walking down the tree: OctoMap's search() along a key's path. A pass that writes no node
// defines OCTOVK_NODES_READ_ONLY before including it (node.glsl).
#ifndef OCTOVK_TREE_SEARCH_GLSL
#define OCTOVK_TREE_SEARCH_GLSL

#include "keys.glsl"
#include "node.glsl"

// How a walk down the tree along a key's path ended (searchDown).
const uint kSearchOpen = 0u;     // reached the depth it was asked to stop at
const uint kSearchLeaf = 1u;     // at a node without children: search() finds it
const uint kSearchMissing = 2u;  // at a node with other children but not this one: not found

// OctoMap's search() from `node` at `depth` along k's path, down to at most depth `until`:
// steps into the child on the path while it exists; `parent` follows.
uint searchDown(uvec3 k, uint until, inout uint node, inout uint parent, inout uint depth) {
  for (; depth < until; ++depth) {
    uint block = childBlock(node);
    if (block == kNoChildren) return kSearchLeaf;
    uint child = block * 8u + childIndex(k, depth);
    if (!linkLive(linkOf(child))) return kSearchMissing;
    parent = node;
    node = child;
  }
  return kSearchOpen;
}

// OcTreeBaseImpl::search(key): the deepest existing node on the key's path. Returns false when
// the path ends at a node that has other children but not this one (or there is no root).
// `node` and `depth` are the deepest node reached either way.
bool searchNode(uvec3 k, out uint node, out uint depth) {
  node = kRootNode;
  depth = 0u;
  if (pool.root_exists == 0u) return false;
  uint parent = kNoBlock;
  return searchDown(k, kTreeDepth, node, parent, depth) != kSearchMissing;
}

#endif  // OCTOVK_TREE_SEARCH_GLSL
