#version 450
#extension GL_GOOGLE_include_directive : require
// Lists the scan's distinct cells: for every brick of the cell set, the ids of its touched cells
// go to the cell list, which classify walks. The list's indirect dispatch arguments grow with it.
// Then the search of the tree that all cells of the brick share (OctoMap's search() down to the
// brick's node at depth 14) replaces the touched bits, so classify only searches the last levels;
// cells whose update would abort early (their node already at the clamping bound) are not
// listed at all.
// No node is written in this pass: links are read plainly (see linkOf).
#define OCTOVK_NODES_READ_ONLY
#include "tree_search.glsl"
#include "tree.glsl"

void main() {
  uint i = invocationIndex();
  if (i >= counters.brick_entries) return;
  uint slot = SLOTS[i];
  uint flags = slot * kBrickFlagWords;
  uint touched_lo = CELL_SET_FLAGS[flags], touched_hi = CELL_SET_FLAGS[flags + 1u];
  uint occupied_lo = CELL_SET_FLAGS[flags + 2u], occupied_hi = CELL_SET_FLAGS[flags + 3u];
  uvec2 marked = uvec2(touched_lo, touched_hi);
  uvec2 occupied_bits = uvec2(occupied_lo, occupied_hi);
  // The brick's occupied cells (their bits are a subset of the touched ones) and free cells.
  uint touched_count = uint(bitCount(marked.x) + bitCount(marked.y));
  uint occupied = uint(bitCount(occupied_bits.x) + bitCount(occupied_bits.y));
  if (occupied != 0u) atomicAdd(counters.occupied_cells, occupied);
  if (touched_count != occupied) atomicAdd(counters.free_cells, touched_count - occupied);

  // The shared part of search(), on the tree as it was before the scan, to the brick's depth.
  uvec3 k = unpackKey(CELL_SET_KEYS[slot]) << 2;
  uint n = kRootNode, parent = kNoBlock, depth = 0u;
  uint ended = kSearchMissing;  // no root
  if (pool.root_exists != 0u) ended = searchDown(k, kBrickDepth, n, parent, depth);
  bool found = ended != kSearchMissing;
  bool open = ended == kSearchOpen;

  // A tile off the device (its node kFlagEvicted, a leaf here): the scan is refused until the
  // host loaded it. Its node goes into the set of needed tiles (one slot per tile, found by
  // atomicCompSwap; a full set leaves the rest to the next refusal), and the brick lists nothing.
  if (found && !open && (linkOf(n) & kFlagEvicted) != 0u) {
    atomicOr(counters.status, kStatusTilesNeeded);
    uint start = (n * 2654435761u) >> 26;  // 64 slots (kNeededTileSlots)
    for (uint probe = 0u; probe < kNeededTileSlots; ++probe) {
      uint at = (start + probe) & (kNeededTileSlots - 1u);
      uint prev = atomicCompSwap(counters.needed_tiles[at], 0u, n + 1u);
      if (prev == 0u) atomicAdd(counters.tiles_needed, 1u);
      if (prev == 0u || prev == n + 1u) break;
    }
    marked = uvec2(0u);
    occupied_bits = uvec2(0u);
  }

  // The early abort, for the cells whose search ends in a node that exists: classify gets only
  // the others (after a few scans most cells of a map end here, and llvmpipe runs classify's
  // whole code for every group of cells). A leaf at or above the brick's depth holds every cell
  // of the brick; below it, each cell's search goes on from the brick's node.
  uvec2 keep = marked;
  float hit = params.prob_hit_log, miss = params.prob_miss_log;
  if (found && !open) {
    float value = nodeLogOdds(n);
    keep = (earlyAbort(miss, value) ? uvec2(0u) : marked & ~occupied_bits) |
           (earlyAbort(hit, value) ? uvec2(0u) : occupied_bits);
  } else if (found) {
    uvec2 rest = marked;
    while (rest != uvec2(0u)) {
      bool low = rest.x != 0u;
      uint b = uint(findLSB(low ? rest.x : rest.y));
      uvec2 bit = low ? uvec2(1u << b, 0u) : uvec2(0u, 1u << b);
      rest &= ~bit;
      uint index = (low ? 0u : 32u) + b;
      uvec3 cell = k | uvec3(index & 3u, (index >> 2) & 3u, index >> 4);
      uint cn = n, cp = parent, cd = depth;
      bool cell_found = searchDown(cell, kTreeDepth, cn, cp, cd) != kSearchMissing;
      float update = any(notEqual(occupied_bits & bit, uvec2(0u))) ? hit : miss;
      if (cell_found && earlyAbort(update, nodeLogOdds(cn))) keep &= ~bit;
    }
  }

  uint count = uint(bitCount(keep.x) + bitCount(keep.y));
  uint at = atomicAdd(counters.cell_entries, count);
  uint end = at + count;
  // A list longer than its buffer: the scan is redone with larger sets.
  if (end > params.cell_capacity) {
    atomicOr(counters.status, kStatusHashFull | kStatusCellsShort);
    return;
  }
  if (count != 0u) OCTOVK_COVER_LIST(counters.cell_args, end);

  CELL_SET_FLAGS[flags] = n;
  CELL_SET_FLAGS[flags + 1u] =
      depth | (found ? kBrickFound : 0u) | (open ? kBrickOpen : 0u);
  uint base = slot * kCellsPerBrick;
  while (keep.x != 0u) {
    int b = findLSB(keep.x);
    CELL_LIST[at++] = base + uint(b);
    keep.x &= keep.x - 1u;
  }
  while (keep.y != 0u) {
    int b = findLSB(keep.y);
    CELL_LIST[at++] = base + 32u + uint(b);
    keep.y &= keep.y - 1u;
  }
}
