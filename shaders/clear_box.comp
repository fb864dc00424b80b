#version 450
#extension GL_GOOGLE_include_directive : require
// octomap_server's clear_bbx on the device, in three modes over every block of the pool:
// kClearBoxDepths: each live block's depth (that of the node it hangs under, found by climbing
//   block_parent once) into block_depth, so that the inner mode need not climb at every level.
//   block_depth is the leaf-box buffer (a leaf box per slot, so at least a word per block), which
//   the edit leaves stale anyway: the host marks the leaf boxes for a rebuild.
// kClearBoxLeaves: every leaf OctoMap's leaf_bbx_iterator visits for the query's BoxQuery (a
//   pruned leaf that reaches into the box included, whole) gets the lower clamping bound's
//   log-odds (setLogOdds(clamping_thres_min)); no node is created, expanded or pruned.
// kClearBoxInner (one dispatch per level, from the deepest up): updateInnerOccupancy: every inner
//   node at pc.level takes the maximum log-odds of its live children (getMaxChildLogOdds), the
//   block of children hanging under it read whole. Levels run bottom-up with a barrier between,
//   so a node's children are final when it reads them; each node is written by the one
//   invocation of its child block.
#include "tree_search.glsl"
#include "block_key.glsl"

layout(push_constant) uniform PushBlock { ClearBoxConstants pc; };

layout(std430, binding = kBindQueryIn) buffer QueryInBuf { BoxQuery box; };

OCTOVK_ADDRESSED(BlockDepthsRef, uint, 4);
#define block_depth (BlockDepthsRef(buffer_address[kBindLeafBoxes]).v)

void main() {
  uint b = invocationIndex();
  if (b >= pool.bump) return;
  if (pc.mode == kClearBoxLeaves) {
    uvec3 lo = uvec3(box.min_x, box.min_y, box.min_z);
    uvec3 hi = uvec3(box.max_x, box.max_y, box.max_z);
    if (b == 0u) {  // the root, when it is a leaf (its box is the whole map)
      if (pool.root_exists != 0u && childBlock(kRootNode) == kNoChildren &&
          nodeMeetsBox(uvec3(0u), 0u, lo, hi))
        nodes[kRootNode].log_odds = params.clamp_min_log;
      return;
    }
    uint parent = block_parent[b];
    if (parent == kNoBlock) return;
    uint depth;
    uvec3 parent_key = parentKeyOfBlock(parent, depth);
    uint bit = 15u - depth;
    for (uint s = 0u; s < 8u; ++s) {
      uint link = nodes[b * 8u + s].link;
      if ((link & kFlagLive) == 0u || (link & kBlockMask) != kNoChildren) continue;
      uvec3 key = parent_key | (uvec3(s & 1u, (s >> 1) & 1u, (s >> 2) & 1u) << bit);
      if (nodeMeetsBox(key, depth + 1u, lo, hi)) nodes[b * 8u + s].log_odds = params.clamp_min_log;
    }
    return;
  }
  if (b == 0u) return;  // block 0 holds only the root
  uint parent = block_parent[b];
  if (parent == kNoBlock) return;
  if (pc.mode == kClearBoxDepths) {
    uint depth;
    parentKeyOfBlock(parent, depth);
    block_depth[b] = depth;
    return;
  }
  // kClearBoxInner
  if (block_depth[b] != pc.level) return;
  float mx = -3.402823466e+38;  // -FLT_MAX, as getMaxChildLogOdds starts
  for (uint s = 0u; s < 8u; ++s) {
    Node child = nodes[b * 8u + s];
    if ((child.link & kFlagLive) != 0u && child.log_odds > mx) mx = child.log_odds;
  }
  nodes[parent].log_odds = mx;
}
