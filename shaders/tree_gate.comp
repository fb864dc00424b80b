#version 450
#extension GL_GOOGLE_include_directive : require
// Between classify and the tree passes, one invocation: does the scan fit? It does when no set
// overflowed and no walk was cut, the pool has a free block for each of classify's new blocks,
// the touched lists have room for the active cells, and no earlier scan was refused since the
// host last looked (PoolState::halted). Then the dispatch arguments of alloc, link and descend
// cover those counts; else they are zero, the scan is marked not applied, the pool halted, and
// tree_begin and tree_fixup do nothing either: the map stays as it was before the scan, and so
// it stays through every scan queued behind it. The host, reading the status at its next
// synchronisation, grows what was short and runs the refused scans again, in order. The host
// never has to look between the passes, nor between scans.
// Also sets clear_args, over the slots this scan filled in the sets (cleared at its end), and
// the count of early-aborted cells. With change detection on, the change set must have room for
// every updated cell (kStatusChangesShort otherwise). A scan that reaches a tile off the device
// (kStatusTilesNeeded, set by list_cells) is refused too: the host loads the tile first.
#include "bindings.glsl"

void setArgs(uint items, inout DispatchArgs args) {
  uint groups = (items + kWorkgroupSize - 1u) / kWorkgroupSize;
  args.x = min(groups, 65535u);
  args.y = groups == 0u ? 1u : (groups + 65534u) / 65535u;
  args.z = 1u;
}

void main() {
  if (invocationIndex() != 0u) return;
  uint status = counters.status;
  uint active_count = counters.active_cells + counters.leaf_cells;
  // Every listed cell that classify did not drop at the early abort is active (at the front of
  // `CELLS`) or has its leaf (at the back).
  counters.aborted = counters.free_cells + counters.occupied_cells - active_count;
  if (pool.halted != 0u) status |= kStatusHalted;
  if (counters.new_blocks > pool.capacity - pool.bump + pool.free_count)
    status |= kStatusPoolShort;
  // The touched lists: every node listed at depth 15 is the parent of an updated leaf in one of
  // the scan's bricks (8 such nodes a brick); at a depth d of 14 or less, the ancestor of one of
  // its bricks (a brick is the node at depth 14), at most 8^d. (GrowthPolicy's touchedBound.)
  uint bricks = counters.brick_entries;
  uint bound = min(active_count, 8u * bricks);
  for (uint d = 0u; d < kTreeDepth - 1u; ++d) bound += d < 10u ? min(bricks, 1u << (3u * d)) : bricks;
  if (uint64_t(bound) > uint64_t(params.touched_capacity)) status |= kStatusListsShort;
  // Change detection: room for every updated cell to claim a slot, the set at most 3/4 full.
  if (params.changes_log2 != 0u) {
    uint room = (1u << params.changes_log2) - (1u << params.changes_log2) / 4u;
    if (uint64_t(CHANGE_TABLE.header.used) + active_count > uint64_t(room))
      status |= kStatusChangesShort;
  }
  if ((status & (kStatusHashFull | kStatusEndpointHashFull | kStatusRayCut | kStatusPoolShort |
                 kStatusListsShort | kStatusHalted | kStatusChangesShort |
                 kStatusTilesNeeded | kStatusWalksShort)) != 0u) {
    status |= kStatusNotApplied;
    pool.halted = 1u;
    setArgs(0u, counters.block_args);
    setArgs(0u, counters.active_args);
  } else {
    setArgs(counters.new_blocks, counters.block_args);
    setArgs(active_count, counters.active_args);
  }
  setArgs(max(counters.brick_entries, counters.new_blocks), counters.clear_args);
  counters.status = status;
}
