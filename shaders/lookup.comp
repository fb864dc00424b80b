#version 450
#extension GL_GOOGLE_include_directive : require
// Point lookups: OctoMap's search(point) for each query point, on the tree as it is now.
// No node is written in this pass: links are read plainly (see linkOf).
#define OCTOVK_NODES_READ_ONLY
#include "tree_search.glsl"

layout(push_constant) uniform PushBlock { LookupConstants pc; };

layout(std430, binding = kBindQueryIn) buffer QueryInBuf { float query_points[]; };
layout(std430, binding = kBindQueryOut) buffer QueryOutBuf { LookupResult lookup_results[]; };

void main() {
  uint i = invocationIndex();
  if (i >= pc.point_count) return;
  // The points start pc.first_float floats into the input, the results pc.first_result entries
  // into the output (after the castRay queries of the same batch).
  uint first = pc.first_float + 3u * i;
  LookupResult r = LookupResult(kCellUnknown, 0.0, 0u, 0u);
  uvec3 k;
  if (coordToKeyChecked(query_points[first], k.x) && coordToKeyChecked(query_points[first + 1u], k.y) &&
      coordToKeyChecked(query_points[first + 2u], k.z)) {
    uint node, depth;
    if (searchNode(k, node, depth)) {
      float v = nodeLogOdds(node);
      r = LookupResult(v >= params.occupancy_log ? kCellOccupied : kCellFree, v, depth,
                       nodePayload(node));
    }
  }
  lookup_results[pc.first_result + i] = r;
}
