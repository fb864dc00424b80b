#version 450
#extension GL_GOOGLE_include_directive : require
// Lists the scan's distinct cells: for every brick of the cell set, the ids of its touched cells
// go to the cell list, which classify walks. The list's indirect dispatch arguments grow with it.
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
