#version 450
#extension GL_GOOGLE_include_directive : require
// A store's capture after a scan, as a change of the host's copy of the pool: for every entry of
// the scan's touched lists and of its colour fold's folded list, the node, its children's block
// and their payload words (CaptureRecord), into host-visible staging by device address. The host applies the records to
// its copy of the pool as it was before the scan (ScanPipeline's capture mirror), instead of
// copying the whole pool. Recorded after every pass of the scan: it writes no node.
#define OCTOVK_NODES_READ_ONLY
#include "bindings.glsl"
#include "node.glsl"

layout(buffer_reference, std430, buffer_reference_align = 8) buffer CaptureRecordsRef {
  CaptureRecord v[];
};
layout(push_constant) uniform PushBlock { CaptureConstants pc; };

void main() {
  // The lists lie one after another from the deepest level (touchedBase): entries 0..listed;
  // then the fold's list, if the scan folded colours.
  uint listed = 0u;
  for (uint l = 0u; l < kTreeDepth; ++l) listed += counters.touched_count[l];
  uint folded = pc.folded_at != kNoFoldedList ? counters.folded_count : 0u;
  // More entries than the staging holds (the host checks the counts and drops such a capture).
  uint total = min(listed + folded, pc.capacity);
  CaptureRecordsRef records = CaptureRecordsRef(pc.records);
  uint stride = gl_NumWorkGroups.x * gl_NumWorkGroups.y * gl_WorkGroupSize.x;
  for (uint r = invocationIndex(); r < total; r += stride) {
    CaptureRecord rec;
    uint n;
    if (r < listed) {
      n = TOUCHED[r];
      rec.key_xy = 0u;
      rec.key_z_depth = 0u;
    } else {
      uint at = pc.folded_at + 3u * (r - listed);
      n = COLOR_FOLD[at];
      rec.key_xy = COLOR_FOLD[at + 1u];
      rec.key_z_depth = COLOR_FOLD[at + 2u];
    }
    rec.index = n;
    rec.payload = nodePayload(n);
    rec.node = storedNode(n);
    uint block = rec.node.link & kBlockMask;
    for (uint s = 0u; s < 8u; ++s) {
      if (block != kNoChildren) {
        rec.children[s] = storedNode(block * 8u + s);
        rec.child_payload[s] = nodePayload(block * 8u + s);
      } else {
        rec.children[s] = Node(0.0, 0u);
        rec.child_payload[s] = 0u;
      }
    }
    records.v[r] = rec;
  }
}
