#version 450
#extension GL_GOOGLE_include_directive : require
// Lists the scan's distinct cells: for every brick of the cell set, the ids of its touched cells
// go to the cell list, which classify walks. The list's indirect dispatch arguments grow with it.
// Then the search of the tree that all cells of the brick share (OctoMap's search() down to the
// brick's node at depth 14) replaces the touched bits, so classify only searches the last levels.
// No node is written in this pass: links are read plainly (see linkOf).
#define OCTOVK_NODES_READ_ONLY
#include "common.glsl"

void main() {
  uint i = invocationIndex();
  if (i >= counters.brick_entries) return;
  uint slot = slots[i];
  uint lo = hash_flags[slot * kBrickFlagWords];
  uint hi = hash_flags[slot * kBrickFlagWords + 1u];
  uint count = uint(bitCount(lo) + bitCount(hi));
  uint at = atomicAdd(counters.cell_entries, count);
  uint end = at + count;
  // A list longer than its buffer: the scan is redone with larger sets.
  if (end > params.cell_capacity) {
    atomicOr(counters.status, kStatusHashFull);
    return;
  }
  if (count != 0u) OCTOVK_COVER_LIST(counters.cell_args, end);
  // The brick's occupied cells (their bits are a subset of the touched ones) and free cells.
  uint occupied = uint(bitCount(hash_flags[slot * kBrickFlagWords + 2u]) +
                       bitCount(hash_flags[slot * kBrickFlagWords + 3u]));
  if (occupied != 0u) atomicAdd(counters.occupied_cells, occupied);
  if (count != occupied) atomicAdd(counters.free_cells, count - occupied);

  // The shared part of search(), on the tree as it was before the scan, to the brick's depth.
  uvec3 k = unpackKey(hash_keys[slot]) << 2;
  uint n = kRootNode, parent = kNoBlock, depth = 0u;
  uint ended = kSearchMissing;  // no root
  if (pool.root_exists != 0u) ended = searchDown(k, kBrickDepth, n, parent, depth);
  bool found = ended != kSearchMissing;
  bool open = ended == kSearchOpen;
  hash_flags[slot * kBrickFlagWords] = n;
  hash_flags[slot * kBrickFlagWords + 1u] =
      depth | (found ? kBrickFound : 0u) | (open ? kBrickOpen : 0u);
  uint base = slot * kCellsPerBrick;
  while (lo != 0u) {
    int b = findLSB(lo);
    cell_list[at++] = base + uint(b);
    lo &= lo - 1u;
  }
  while (hi != 0u) {
    int b = findLSB(hi);
    cell_list[at++] = base + 32u + uint(b);
    hi &= hi - 1u;
  }
}
