#version 450
#extension GL_GOOGLE_include_directive : require
// Between classify and the tree passes, one invocation: does the scan fit? It does when no set
// overflowed and no walk was cut, the pool has a free block for each of classify's new blocks,
// and the touched lists have room for the active cells. Then the dispatch arguments of alloc,
// link and descend cover those counts; else they are zero, the scan is marked not applied, and
// tree_begin and tree_fixup do nothing either: the map stays as it was before the scan, and the
// host, reading the status, grows what was short and runs the scan again. The host never has to
// look between the passes.
#include "common.glsl"

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
  if (counters.new_blocks > pool.capacity - pool.bump + pool.free_count)
    status |= kStatusPoolShort;
  if (active_count > params.active_capacity) status |= kStatusListsShort;
  if ((status & (kStatusHashFull | kStatusEndpointHashFull | kStatusRayCut | kStatusPoolShort |
                 kStatusListsShort)) != 0u) {
    status |= kStatusNotApplied;
    setArgs(0u, counters.block_args);
    setArgs(0u, counters.active_args);
  } else {
    setArgs(counters.new_blocks, counters.block_args);
    setArgs(active_count, counters.active_args);
  }
  counters.status = status;
}
