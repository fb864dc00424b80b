// Helpers of the tree passes: a cell of the cell set, its update and early abort, and the
// per-level lists of touched nodes the prune pass works through.
#ifndef OCTOVK_TREE_GLSL
#define OCTOVK_TREE_GLSL

#include "tree_search.glsl"

// Key of the cell with this id in the cell set (brick slot * 64 + index).
uvec3 cellKey(uint id) {
  uint index = id % kCellsPerBrick;
  return (unpackKey(CELL_SET_KEYS[id / kCellsPerBrick]) << 2) |
         uvec3(index & 3u, (index >> 2) & 3u, index >> 4);
}

bool cellOccupied(uint id) {
  uint index = id % kCellsPerBrick;
  uint word = (id / kCellsPerBrick) * kBrickFlagWords + 2u + (index >> 5);
  return (CELL_SET_FLAGS[word] & (1u << (index & 31u))) != 0u;
}

float cellUpdate(uint id) {
  return cellOccupied(id) ? params.prob_hit_log : params.prob_miss_log;
}

// OctoMap's early abort in updateNode: the node search() found (`value` its log-odds) is
// already at the clamping bound in the update's direction, so nothing changes.
bool earlyAbort(float update, float value) {
  return (update >= 0.0 && value >= params.clamp_max_log) ||
         (update <= 0.0 && value <= params.clamp_min_log);
}

// Where the list of `level` starts in TOUCHED: the levels lie one after another from the deepest
// (15, descend's), each list complete before the next one up is written (prune runs a level at a
// time, appending to the level above), so its start is the sum of the deeper levels' counts.
uint touchedBase(uint level) {
  uint base = 0u;
  for (uint l = level + 1u; l < kTreeDepth; ++l) base += counters.touched_count[l];
  return base;
}

// Appends item to the list of `level`, which starts at `base` (touchedBase), and keeps its
// indirect dispatch arguments in step.
void appendTouched(uint level, uint base, uint node) {
  uint at = atomicAdd(counters.touched_count[level], 1u);
  TOUCHED[base + at] = node;
  if (at % kWorkgroupSize == 0u) OCTOVK_COVER_LIST(counters.touched_args[level], at + 1u);
}

// Lists `parent` (at depth `level`, whose list starts at `base`) once for the prune pass there.
void listNode(uint level, uint base, uint parent) {
  if ((linkOf(parent) & kFlagTouched) != 0u) return;
  uint old = atomicOrLink(parent, kFlagTouched);
  if ((old & kFlagTouched) == 0u) appendTouched(level, base, parent);
}

// Lists the parent of `node` (at depth level + 1) once for the prune pass at `level`.
void listParent(uint level, uint base, uint node) {
  listNode(level, base, BLOCK_PARENT[node / 8u]);
}

#endif  // OCTOVK_TREE_GLSL
