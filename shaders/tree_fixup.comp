#version 450
#extension GL_GOOGLE_include_directive : require
// After alloc: the blocks it took leave the free stack, then the never-used tail.
#include "bindings.glsl"

void main() {
  if (invocationIndex() != 0u) return;
  if ((counters.status & kStatusNotApplied) != 0u) return;  // see tree_gate
  uint popped = min(counters.new_blocks, pool.free_count);
  pool.free_count -= popped;
  pool.bump += counters.new_blocks - popped;
}
