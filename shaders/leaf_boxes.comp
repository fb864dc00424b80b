#version 450
#extension GL_GOOGLE_include_directive : require
// Rebuilds the compact leaf-box buffer: every leaf's centre, edge length and log-odds, found by
// scanning the live blocks (block 0 stands for the root itself).
#include "common.glsl"

void emit(uvec3 key, uint depth, float log_odds) {
  // OcTreeBaseImpl::keyToCoord(key, depth), in double, then to float.
  uint shift = kTreeDepth - depth;
  double size = params.resolution * double(1u << shift);
  vec3 centre;
  if (depth == 0u) {
    centre = vec3(0.0);
  } else if (depth == kTreeDepth) {
    centre = vec3(float(keyToCoord(key.x)), float(keyToCoord(key.y)), float(keyToCoord(key.z)));
  } else {
    dvec3 k = dvec3(ivec3(key) - ivec3(32768));
    dvec3 c = (floor(k / double(1u << shift)) + 0.5lf) * size;
    centre = vec3(c);
  }
  uint at = atomicAdd(pool.leaf_count, 1u);
  leaf_boxes[at] = LeafBox(centre.x, centre.y, centre.z, float(size), log_odds);
}

void main() {
  uint b = invocationIndex();
  if (b >= pool.bump) return;
  if (b == 0u) {
    if (pool.root_exists != 0u && (nodes[kRootNode].mask & kChildMask) == 0u)
      emit(uvec3(32768u), 0u, nodes[kRootNode].log_odds);
    return;
  }
  BlockMeta meta = block_meta[b];
  if (meta.parent == kNoBlock) return;
  uint children = nodes[meta.parent].mask & kChildMask;
  uvec3 parent_key = uvec3(meta.key_xy & 0xFFFFu, meta.key_xy >> 16, meta.key_z);
  uint bit = 15u - meta.depth;
  for (uint s = 0u; s < 8u; ++s) {
    if ((children & (1u << s)) == 0u) continue;
    Node child = nodes[b * 8u + s];
    if ((child.mask & kChildMask) != 0u) continue;
    uvec3 key = parent_key | (uvec3(s & 1u, (s >> 1) & 1u, (s >> 2) & 1u) << bit);
    emit(key, meta.depth + 1u, child.log_odds);
  }
}
