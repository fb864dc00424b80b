#version 450
#extension GL_GOOGLE_include_directive : require
// Empties the slots the sets' last use filled (listed in `slots`), so that each scan starts with
// empty sets without clearing whole tables.
// kClearPrevious: the previous scan's pc.bricks bricks and pc.endpoints second-set entries.
// kClearEndCells: this scan's end cells of discretize, before classify reuses the second set.
#include "common.glsl"

layout(push_constant) uniform PushBlock { ClearSetsConstants pc; };

void main() {
  uint i = invocationIndex();
  if (pc.mode == kClearEndCells) {
    if (i < counters.endpoint_entries) endpoint_keys[slots[params.hash_capacity + i]] = kEmptyKey;
    return;
  }
  if (i < pc.bricks) {
    uint s = slots[i];
    hash_keys[s] = kEmptyKey;
    for (uint w = 0u; w < kBrickFlagWords; ++w) hash_flags[s * kBrickFlagWords + w] = 0u;
  }
  if (i < pc.endpoints) endpoint_keys[slots[params.hash_capacity + i]] = kEmptyKey;
}
