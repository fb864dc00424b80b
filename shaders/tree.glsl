// Helpers of the tree passes.

uvec3 cellKey(uint slot) { return unpackKey(hash_keys[slot]); }

float cellUpdate(uint slot) {
  return (hash_flags[slot] & kHashFlagOccupied) != 0u ? params.prob_hit_log : params.prob_miss_log;
}

// Appends item to a per-level list and keeps its indirect dispatch arguments in step.
void appendTouched(uint level, uint node) {
  uint at = atomicAdd(counters.touched_count[level], 1u);
  touched[level * params.active_capacity + at] = node;
  if (at % kWorkgroupSize == 0u) atomicAdd(counters.touched_args[level].x, 1u);
}

void appendAlloc(uint level, uint node, uint cell) {
  uint at = atomicAdd(counters.alloc_count[level], 1u);
  alloc_list[level * params.active_capacity + at] = AllocRequest(node, cell);
  if (at % kWorkgroupSize == 0u) atomicAdd(counters.alloc_args[level].x, 1u);
}

// The node a cell has reached, resolving a child whose block was allocated by the last pass.
uint resolveNode(ActiveCell c) {
  return c.pending == kNoBlock ? c.node : nodes[c.node].children * 8u + c.pending;
}

// Lists the parent of `node` (at depth level + 1) once for the prune pass at `level`.
void listParent(uint level, uint node) {
  uint parent = block_meta[node / 8u].parent;
  if ((nodes[parent].mask & kFlagTouched) != 0u) return;
  uint old = atomicOr(nodes[parent].mask, kFlagTouched);
  if ((old & kFlagTouched) == 0u) appendTouched(level, parent);
}
