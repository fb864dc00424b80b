#version 450
#extension GL_GOOGLE_include_directive : require
// Keeping only a box (a rolling window): afterwards the tree holds exactly the leaves OctoMap's
// leaf_bbx_iterator visits for the query's BoxQuery (a pruned leaf reaching into the box stays
// whole), the inner nodes on their paths, and nothing else. Three modes, one invocation per block
// of the pool (block 0 stands for the root), a barrier between them:
// kKeepBoxMark: a block's leaves in the box get kFlagTouched, and so does every node above them
//   (climbing block_parent with atomicOr; a climb stops at a node another climb already marked,
//   whose climb goes on to the root, so no order between invocations matters).
// kKeepBoxSweep: a block whose parent node is unmarked is freed whole (its parent is deleted, so
//   are all its slots): block_parent to kNoBlock, pushed on the free stack. In a block whose
//   parent is marked, every live unmarked slot is deleted (link to kNoChildren, not live). An
//   unmarked root empties the tree. The marks are not changed here: each decision reads a mark
//   that no invocation of this dispatch writes.
// kKeepBoxUnmark: the marks are cleared (each block its own slots, block 0 the root).
// updateInnerOccupancy follows (clear_box's inner mode, recorded by TreeEdits).
// Concurrent words: node links are marked with atomicOr, read with atomic loads and deleted with
// atomicExchange; live_nodes and free_count are atomic counters; every other write is to a word
// of the invocation's own block.
#include "tree_search.glsl"
#include "block_key.glsl"

layout(push_constant) uniform PushBlock { KeepBoxConstants pc; };

layout(std430, binding = kBindQueryIn) buffer QueryInBuf { BoxQuery box; };

// Marks `n` and the nodes above it, up to one already marked (or the root).
void markPath(uint n) {
  for (uint up = 0u; up <= kTreeDepth; ++up) {
    uint old = atomicOrLink(n, kFlagTouched);
    if ((old & kFlagTouched) != 0u || n == kRootNode) return;
    n = BLOCK_PARENT[n / 8u];
  }
}

bool marked(uint n) { return (linkOf(n) & kFlagTouched) != 0u; }

void main() {
  uint b = invocationIndex();
  if (b >= pool.bump) return;
  if (b == 0u) {  // the root
    if (pool.root_exists == 0u) return;
    if (pc.mode == kKeepBoxMark) {
      // A root without children is a leaf whose box is the whole map.
      if (childBlock(kRootNode) == kNoChildren &&
          nodeMeetsBox(uvec3(0u), 0u, uvec3(box.min_x, box.min_y, box.min_z),
                       uvec3(box.max_x, box.max_y, box.max_z)))
        markPath(kRootNode);
    } else if (pc.mode == kKeepBoxSweep) {
      if (!marked(kRootNode)) {  // nothing is kept: the tree is empty
        atomicSetLink(kRootNode, kNoChildren);
        pool.root_exists = 0u;
        atomicAdd(pool.live_nodes, uint(-1));
      }
    } else {
      clearLinkBits(kRootNode, kFlagTouched);
    }
    return;
  }
  uint parent = BLOCK_PARENT[b];
  if (parent == kNoBlock) return;
  if (pc.mode == kKeepBoxMark) {
    uint depth;
    uvec3 parent_key = parentKeyOfBlock(parent, depth);
    uint bit = 15u - depth;
    uvec3 lo = uvec3(box.min_x, box.min_y, box.min_z);
    uvec3 hi = uvec3(box.max_x, box.max_y, box.max_z);
    bool any_kept = false;
    for (uint s = 0u; s < 8u; ++s) {
      uint link = linkOf(b * 8u + s);
      if (!linkLiveLeaf(link)) continue;
      uvec3 key = parent_key | (uvec3(s & 1u, (s >> 1) & 1u, (s >> 2) & 1u) << bit);
      if (!nodeMeetsBox(key, depth + 1u, lo, hi)) continue;
      atomicOrLink(b * 8u + s, kFlagTouched);
      any_kept = true;
    }
    if (any_kept) markPath(parent);
    return;
  }
  if (pc.mode == kKeepBoxSweep) {
    uint deleted = 0u;
    if (!marked(parent)) {  // the parent goes, and all of its children with it
      for (uint s = 0u; s < 8u; ++s)
        if (linkLive(linkOf(b * 8u + s))) ++deleted;
      BLOCK_PARENT[b] = kNoBlock;
      FREE_STACK[atomicAdd(pool.free_count, 1u)] = b;
    } else {
      for (uint s = 0u; s < 8u; ++s) {
        uint link = linkOf(b * 8u + s);
        if (!linkLive(link) || (link & kFlagTouched) != 0u) continue;
        atomicSetLink(b * 8u + s, kNoChildren);
        ++deleted;
      }
    }
    if (deleted != 0u) atomicAdd(pool.live_nodes, uint(-int(deleted)));
    return;
  }
  // kKeepBoxUnmark: only this invocation reads or writes its block's links in this dispatch.
  for (uint s = 0u; s < 8u; ++s) clearLinkBits(b * 8u + s, kFlagTouched);
}
