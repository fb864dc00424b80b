#version 460
#extension GL_GOOGLE_include_directive : require
// The boxes the ray-tracing backend of castRay (cast_ray_rt.comp) traces against, into the
// AccelHeader's buffer, compacted, each enlarged by a quarter cell (and a relative margin for
// the float arithmetic far from the origin) so that the acceleration structure's float test
// cannot miss a box that OctoMap's walk enters:
// kAccelBoxesOccupied: the occupied leaves of the leaf-box buffer (leaf_boxes.comp's rebuild).
// kAccelBoxesUnknown: the unknown regions, i.e. every missing child of a node that has children
//                     (a block's slots that are not live), one invocation per block.
// No node is written in this pass: links are read plainly (see linkOf).
#define OCTOVK_NODES_READ_ONLY
#include "common.glsl"
#include "block_key.glsl"

layout(push_constant) uniform PushBlock { AccelBoxesConstants pc; };

layout(buffer_reference, std430, buffer_reference_align = 8) buffer AccelRef {
  AccelHeader header;
  AccelBox boxes[];
};

float margin(vec3 centre, float size) {
  float m = max(abs(centre.x), max(abs(centre.y), abs(centre.z))) + size;
  return float(params.resolution) * 0.25 + m * (1.0 / 65536.0);
}

AccelBox enlarged(vec3 lo, vec3 hi, float m) {
  return AccelBox(lo.x - m, lo.y - m, lo.z - m, hi.x + m, hi.y + m, hi.z + m);
}

void main() {
  uint i = invocationIndex();
  AccelRef scene = AccelRef(pc.boxes);
  if (pc.mode == kAccelBoxesOccupied) {
    if (i >= pool.leaf_count) return;
    LeafBox leaf = leaf_boxes[i];
    if (leaf.log_odds < params.occupancy_log) return;
    vec3 c = vec3(leaf.center_x, leaf.center_y, leaf.center_z);
    float half_size = leaf.size * 0.5;
    uint at = atomicAdd(scene.header.occupied_count, 1u);
    scene.boxes[at] = enlarged(c - half_size, c + half_size, margin(c, leaf.size));
    return;
  }
  // kAccelBoxesUnknown: block 0 holds only the root (an empty map needs no box: castRay stops
  // at its origin's cell, or, ignoring unknown space, meets nothing).
  if (i >= pool.bump || i == 0u) return;
  uint parent = block_parent[i];
  if (parent == kNoBlock) return;
  uint depth;
  uvec3 parent_key = parentKeyOfBlock(parent, depth);
  uint bit = 15u - depth;
  double size = params.resolution * double(1u << bit);
  for (uint s = 0u; s < 8u; ++s) {
    if ((nodes[i * 8u + s].link & kFlagLive) != 0u) continue;
    uvec3 key = parent_key | (uvec3(s & 1u, (s >> 1) & 1u, (s >> 2) & 1u) << bit);
    // The region's lower corner, (key - 32768) * resolution, exact in double.
    dvec3 lo = dvec3(ivec3(key) - ivec3(32768)) * params.resolution;
    vec3 lo_f = vec3(lo);
    vec3 hi_f = vec3(lo + size);
    uint at = atomicAdd(scene.header.unknown_count, 1u);
    scene.boxes[scene.header.occupied_capacity + at] =
        enlarged(lo_f, hi_f, margin(0.5 * (lo_f + hi_f), float(size)));
  }
}
