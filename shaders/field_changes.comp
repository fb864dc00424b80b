#version 450
#extension GL_GOOGLE_include_directive : require
// The distance field's obstacles after scans (an incremental update): one invocation per slot of
// the map's change set. Every key a slot holds (in the set now, or flipped back since it was
// noted) whose cell is in the box is searched again (OctoMap's search and isNodeOccupied, as
// field_raster) and its occupancy bit set to the answer; where the bit flips, its x-line is
// marked dirty. Keys in the set are distinct, so each bit has one writer; the words are shared
// with other cells of the line: atomics.
// No node is written in this pass: links are read plainly (see linkOf).
#define OCTOVK_NODES_READ_ONLY
#include "tree_search.glsl"
#include "change_set.glsl"
#include "field.glsl"

layout(push_constant) uniform PushBlock { FieldChangesConstants pc; };

void main() {
  uint s = invocationIndex();
  if (s >= pc.capacity) return;
  uint64_t packed = CHANGE_TABLE.slot[s].key;
  if (packed == kEmptyChangeKey) return;
  FieldHeaderRef f = FieldHeaderRef(pc.header);
  uvec3 size = fieldSize(f);
  uvec3 k = unpackKey(packed);
  uvec3 lo = fieldMinKey(f);
  if (any(lessThan(k, lo)) || any(greaterThanEqual(k - lo, size))) return;
  uvec3 c = k - lo;
  bool occupied = f.h.unknown_occupied != 0u;
  if (pool.root_exists != 0u) {
    uint node = kRootNode, parent = kNoBlock, depth = 0u;
    if (searchDown(k, kTreeDepth, node, parent, depth) != kSearchMissing)
      occupied = nodeOccupied(node);
  }
  uint row = c.y + size.y * c.z;
  uint w = row * f.h.words_per_row + c.x / 32u;
  uint bit = 1u << (c.x % 32u);
  FieldWordsRef occ = FieldWordsRef(f.h.occupancy);
  uint before = occupied ? atomicOr(occ.v[w], bit) : atomicAnd(occ.v[w], ~bit);
  if (((before & bit) != 0u) != occupied) markFieldDirty(f, 0u, row);
}
