#version 450
#extension GL_GOOGLE_include_directive : require
// A store's capture after a scan, as a change of the host's copy of the pool: for every entry of
// the scan's touched lists and of its colour fold's folded list, the node, its children's block
// and their payload words (CaptureRecord), into host-visible staging by device address. The host
// applies the records to its copy of the pool as it was before the scan (ScanPipeline's capture
// mirror), instead of copying the whole pool. Recorded after every pass of the scan: it writes no
// node.
//
// A record's fields are written only where the host reads them (CaptureMirror::apply): the
// children and their payload words when the node has a block, the payload words in a map that
// has them, the key words in a folded list's record. The choices are loops, not branches:
// llvmpipe runs both sides of a branch for every group of lanes, masked, and a loop no lane
// enters not at all (the capture took 0.26 ms a scan on Mesa 22.3, most of it in untaken sides).
#define OCTOVK_NODES_READ_ONLY
#include "bindings.glsl"
#include "node.glsl"

layout(buffer_reference, std430, buffer_reference_align = 8) buffer CaptureRecordsRef {
  CaptureRecord v[];
};
layout(push_constant) uniform PushBlock { CaptureConstants pc; };

// Record r: node n, its children's block and the payload words. Nodes are copied as 64-bit
// words: llvmpipe reads and writes each lane's word on its own, so a record of 8 children is half
// the work it was as Node structs (the capture took 0.2 ms a scan on Mesa 22.3, most of it here).
void capture(CaptureRecordsRef records, uint r, uint n) {
  uint64_t node = storedNodeWord(n);
  records.v[r].index = n;
  records.v[r].node = node;
  uint block = uint(node >> 32) & kBlockMask;
  uint children = block != kNoChildren ? 8u : 0u;
  for (uint s = 0u; s < children; ++s) records.v[r].children[s] = storedNodeWord(block * 8u + s);
  for (uint p = hasPayload() ? 0u : 1u; p < 1u; ++p) {
    records.v[r].payload = nodePayload(n);
    for (uint s = 0u; s < children; ++s)
      records.v[r].child_payload[s] = nodePayload(block * 8u + s);
  }
}

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
  for (uint r = invocationIndex(); r < min(listed, total); r += stride)
    capture(records, r, TOUCHED[r]);
  for (uint r = listed + invocationIndex(); r < total; r += stride) {
    uint at = pc.folded_at + 3u * (r - listed);
    capture(records, r, COLOR_FOLD[at]);
    records.v[r].key_xy = COLOR_FOLD[at + 1u];
    records.v[r].key_z_depth = COLOR_FOLD[at + 2u];
  }
}
