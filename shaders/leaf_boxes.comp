#version 450
#extension GL_GOOGLE_include_directive : require
// Leaves of the map, found by scanning the live blocks (block 0 stands for the root itself); a
// block's place in the tree comes from the parents above it.
// kLeafBoxesRebuild: every leaf's centre, edge length and log-odds into leaf_boxes.
// kLeafBoxesInBox: the leaves OctoMap's leaf_bbx_iterator visits (node key range overlapping the
//                  box's key range, as the iterator tests it), optionally only occupied ones,
//                  compacted into the query output.
// No node is written in this pass: links are read plainly (see linkOf).
#define OCTOVK_NODES_READ_ONLY
#include "tree_search.glsl"
#include "block_key.glsl"

layout(push_constant) uniform PushBlock { LeafBoxesConstants pc; };

layout(std430, binding = kBindQueryIn) buffer QueryInBuf { BoxQuery box; };
layout(std430, binding = kBindQueryOut) buffer QueryOutBuf { LeafBox box_leaves[]; };

bool inBox(uvec3 prefix, uint depth, float log_odds) {
  if (box.occupied_only != 0u && log_odds < params.occupancy_log) return false;
  return nodeMeetsBox(prefix, depth, uvec3(box.min_x, box.min_y, box.min_z),
                      uvec3(box.max_x, box.max_y, box.max_z));
}

void emit(uvec3 key, uint depth, float log_odds) {
  if (pc.mode == kLeafBoxesInBox && !inBox(key, depth, log_odds)) return;
  // OcTreeBaseImpl::keyToCoord(key, depth), in double, then to float.
  uint shift = kTreeDepth - depth;
  double size = params.resolution * double(1u << shift);
  // Below the root: (floor((key - 32768) / 2^shift) + 0.5) * size, where the floor of the
  // division is an arithmetic shift of the integer; at depth 16 (shift 0, size = resolution)
  // this is keyToCoord(key) operation for operation. One formula keeps the SIMD lanes of leaves
  // at different depths together.
  vec3 centre = vec3(0.0);
  if (depth != 0u) {
    precise dvec3 c = (dvec3((ivec3(key) - ivec3(32768)) >> int(shift)) + 0.5lf) * size;
    centre = toFloat(c);
  }
  LeafBox leaf = LeafBox(centre.x, centre.y, centre.z, toFloat(size), log_odds);
  if (pc.mode == kLeafBoxesRebuild) LEAF_BOXES[atomicAdd(pool.leaf_count, 1u)] = leaf;
  else {
    // Every leaf is counted; those beyond the bound range are not written (the host asks again
    // in parts of the box when the count exceeds it).
    uint at = atomicAdd(counters.query_results, 1u);
    if (at < uint(box_leaves.length())) box_leaves[at] = leaf;
  }
}

void main() {
  uint b = invocationIndex();
  if (b >= pool.bump) return;
  if (b == 0u) {
    if (pool.root_exists != 0u && childBlock(kRootNode) == kNoChildren)
      emit(uvec3(0u), 0u, nodeLogOdds(kRootNode));
    return;
  }
  uint parent = BLOCK_PARENT[b];
  if (parent == kNoBlock) return;
  uint depth;
  uvec3 parent_key = parentKeyOfBlock(parent, depth);
  uint bit = 15u - depth;
  for (uint s = 0u; s < 8u; ++s) {
    uint child = b * 8u + s;
    if (!linkLiveLeaf(linkOf(child))) continue;
    uvec3 key = parent_key | (uvec3(s & 1u, (s >> 1) & 1u, (s >> 2) & 1u) << bit);
    emit(key, depth + 1u, nodeLogOdds(child));
  }
}
