#version 450
#extension GL_GOOGLE_include_directive : require
// After the descent: the blocks popped from the free stack leave it.
#include "common.glsl"

void main() {
  if (invocationIndex() != 0u) return;
  pool.free_count -= min(pool.pops, pool.free_count);
  pool.pops = 0u;
}
