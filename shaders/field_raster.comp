#version 450
#extension GL_GOOGLE_include_directive : require
// The distance field's obstacles from the tree: one invocation per occupancy word, the
// 32 cells x = 32 w .. 32 w + 31 of one x-line. For each cell, OctoMap's search(key) and
// isNodeOccupied (log-odds >= the occupancy threshold); a cell search() does not find is
// unknown, an obstacle only with FieldHeader::unknown_occupied (DynamicEDTOctomap's
// treatUnknownAsOccupied). A search that ends at a leaf of depth d answers for every cell of the
// line whose key shares the leaf's d leading bits, and one that ends at a missing child of a
// node of depth d for those sharing d + 1 bits (all unknown): the next search is made only
// past them. Each word has one writer; the bits beyond size_x stay 0. With pc.compare (an
// update), a word that changed marks its x-line dirty.
// No node is written in this pass: links are read plainly (see linkOf).
#define OCTOVK_NODES_READ_ONLY
#include "tree_search.glsl"
#include "field.glsl"

layout(push_constant) uniform PushBlock { FieldRasterConstants pc; };

void main() {
  uint i = invocationIndex();
  if (i >= pc.word_count) return;
  FieldHeaderRef f = FieldHeaderRef(pc.header);
  uvec3 size = fieldSize(f);
  uint wpr = f.h.words_per_row;
  uint row = i / wpr;
  uint first = (i % wpr) * 32u;
  uint last = min(first + 32u, size.x);  // one past
  uvec3 k = fieldMinKey(f) + uvec3(first, row % size.y, row / size.y);
  bool unknown_occupied = f.h.unknown_occupied != 0u;
  uint word = 0u;
  uint x = first;
  while (x < last) {
    // search(k) for the cell at x; `cover`: how many leading key bits the answer holds for.
    bool occupied = unknown_occupied;
    uint cover = 0u;
    if (pool.root_exists != 0u) {
      uint node = kRootNode, parent = kNoBlock, depth = 0u;
      uint how = searchDown(k, kTreeDepth, node, parent, depth);
      if (how == kSearchMissing) {
        cover = depth + 1u;
      } else {
        cover = depth;
        occupied = nodeOccupied(node);
      }
    }
    // The cells up to the end of the answer's aligned run of keys along x.
    uint shift = kTreeDepth - cover;
    uint run_end_key = shift >= 16u ? 0x10000u : ((k.x >> shift) + 1u) << shift;
    uint end = min(last, x + (run_end_key - k.x));
    if (occupied) {
      uint lo = x - first, hi = end - first;  // bits lo .. hi - 1
      uint ones = hi - lo >= 32u ? 0xFFFFFFFFu : ((1u << (hi - lo)) - 1u);
      word |= ones << lo;
    }
    k.x += end - x;
    x = end;
  }
  FieldWordsRef occ = FieldWordsRef(f.h.occupancy);
  if (pc.compare == 0u) {
    occ.v[i] = word;
  } else if (occ.v[i] != word) {
    occ.v[i] = word;
    markFieldDirty(f, 0u, row);
  }
}
