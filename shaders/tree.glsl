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

// Lists `parent` (at depth `level`) once for the prune pass at that level.
void listNode(uint level, uint parent) {
  if ((nodes[parent].mask & kFlagTouched) != 0u) return;
  uint old = atomicOr(nodes[parent].mask, kFlagTouched);
  if ((old & kFlagTouched) == 0u) appendTouched(level, parent);
}

// Lists the parent of `node` (at depth level + 1) once for the prune pass at `level`.
void listParent(uint level, uint node) { listNode(level, block_meta[node / 8u].parent); }
