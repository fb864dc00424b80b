#version 450
#extension GL_GOOGLE_include_directive : require
// octomap_server's clear_bbx on the device, in three modes:
// kClearBoxDepths (over every block of the pool): each live block is listed under its depth (that
//   of the node it hangs under, found by climbing block_parent once): block_lists[depth *
//   capacity + n] for the n-th, counted in ScanCounters::touched_count[depth], with the indirect
//   arguments touched_args[depth] kept covering the list (the prune pass's, unused between scans).
//   block_lists is the leaf-box buffer (a box per slot: 40 words per block, 16 needed), which the
//   edit leaves stale anyway: the host marks the leaf boxes for a rebuild.
// kClearBoxLeaves (over every block of the pool): every leaf OctoMap's leaf_bbx_iterator visits
//   for the query's BoxQuery (a pruned leaf that reaches into the box included, whole) gets the
//   lower clamping bound's log-odds (setLogOdds(clamping_thres_min)); no node is created,
//   expanded or pruned.
// kClearBoxInner (indirect over the blocks listed at pc.level, one dispatch per level from the
//   deepest up): updateInnerOccupancy: the node each block hangs under takes the maximum log-odds
//   of the block's live slots (getMaxChildLogOdds), the block read whole. Levels run bottom-up
//   with a barrier between, so a node's children are final when it reads them; each node is
//   written by the one invocation of its child block. Payloads as updateInnerOccupancy gives them
//   (node.glsl's innerNodeData); kClearBoxInnerAt stamps the nodes with pc.now.
// kClearBoxDegrade (over every block of the pool): OcTreeStamped::degradeOutdatedNodes at query
//   time pc.now: each live leaf (a pruned one included) that is occupied and whose stamp is more
//   than pc.threshold seconds older (unsigned difference, as OctoMap) takes one miss, clamped,
//   its stamp kept (integrateMissNoTime); no node is created, expanded or pruned.
#include "tree_search.glsl"
#include "block_key.glsl"

layout(push_constant) uniform PushBlock { ClearBoxConstants pc; };

layout(std430, binding = kBindQueryIn) buffer QueryInBuf { BoxQuery box; };

OCTOVK_ADDRESSED(BlockListsRef, uint, 4);
#define block_lists (BlockListsRef(buffer_address[kBindLeafBoxes]).v)

void main() {
  if (pc.mode == kClearBoxInner || pc.mode == kClearBoxInnerAt) {
    uint n = invocationIndex();
    if (n >= counters.touched_count[pc.level]) return;
    uint block = block_lists[pc.level * pool.capacity + n];
    uint parent = BLOCK_PARENT[block];
    setNodeData(parent, innerNodeData(parent, block, pc.mode == kClearBoxInnerAt, pc.now));
    return;
  }
  uint b = invocationIndex();
  if (b >= pool.bump) return;
  if (pc.mode == kClearBoxDegrade) {
    uint first = b == 0u ? kRootNode : b * 8u;
    uint last = b == 0u ? kRootNode : b * 8u + 7u;
    if (b == 0u && pool.root_exists == 0u) return;
    if (b != 0u && BLOCK_PARENT[b] == kNoBlock) return;
    for (uint n = first; n <= last; ++n) {
      if (!linkLiveLeaf(settledLinkOf(n)) || !nodeOccupied(n)) continue;
      if (pc.now - nodePayload(n) <= pc.threshold) continue;
      precise float value = nodeLogOdds(n) + params.prob_miss_log;
      if (value < params.clamp_min_log) value = params.clamp_min_log;
      else if (value > params.clamp_max_log) value = params.clamp_max_log;
      setNodeLogOdds(n, value);
    }
    return;
  }
  if (pc.mode == kClearBoxLeaves) {
    uvec3 lo = uvec3(box.min_x, box.min_y, box.min_z);
    uvec3 hi = uvec3(box.max_x, box.max_y, box.max_z);
    if (b == 0u) {  // the root, when it is a leaf (its box is the whole map)
      if (pool.root_exists != 0u && childBlock(kRootNode) == kNoChildren &&
          nodeMeetsBox(uvec3(0u), 0u, lo, hi))
        setNodeLogOdds(kRootNode, params.clamp_min_log);
      return;
    }
    uint parent = BLOCK_PARENT[b];
    if (parent == kNoBlock) return;
    uint depth;
    uvec3 parent_key = parentKeyOfBlock(parent, depth);
    uint bit = 15u - depth;
    for (uint s = 0u; s < 8u; ++s) {
      // No link changes in this mode: read plainly.
      if (!linkLiveLeaf(settledLinkOf(b * 8u + s))) continue;
      uvec3 key = parent_key | (uvec3(s & 1u, (s >> 1) & 1u, (s >> 2) & 1u) << bit);
      if (nodeMeetsBox(key, depth + 1u, lo, hi)) setNodeLogOdds(b * 8u + s, params.clamp_min_log);
    }
    return;
  }
  if (b == 0u) return;  // block 0 holds only the root
  uint parent = BLOCK_PARENT[b];
  if (parent == kNoBlock) return;
  // kClearBoxDepths
  uint depth;
  parentKeyOfBlock(parent, depth);
  uint at = atomicAdd(counters.touched_count[depth], 1u);
  block_lists[depth * pool.capacity + at] = b;
  OCTOVK_COVER_LIST(counters.touched_args[depth], at + 1u);
}
