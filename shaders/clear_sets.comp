#version 450
#extension GL_GOOGLE_include_directive : require
// Empties the slots the sets' last use filled (listed in `slots`), so that each scan starts with
// empty sets without clearing whole tables.
// mode 0: the previous scan's pc.count bricks and pc.offset second-set entries.
// mode 1: this scan's end cells of discretize, before classify reuses the second set.
#include "common.glsl"

void main() {
  uint i = invocationIndex();
  if (pc.mode == 1u) {
    if (i < counters.endpoint_entries) endpoint_keys[slots[params.hash_capacity + i]] = kEmptyKey;
    return;
  }
  if (i < pc.count) {
    uint s = slots[i];
    hash_keys[s] = kEmptyKey;
    for (uint w = 0u; w < kBrickFlagWords; ++w) hash_flags[s * kBrickFlagWords + w] = 0u;
  }
  if (i < pc.offset) endpoint_keys[slots[params.hash_capacity + i]] = kEmptyKey;
}
