#version 450
#extension GL_GOOGLE_include_directive : require
// Empties the slots a scan filled in the sets (listed in `SLOTS`), so that the next scan starts
// with empty sets without clearing whole tables. Counts come from the counters, so the host
// records this without knowing them:
// kClearScan: at the scan's end (indirect over clear_args), its brick_entries bricks and its
//             new_blocks second-set entries, whether or not the scan was applied.
// kClearEndCells: this scan's end cells of discretize, before classify reuses the second set.
#include "cell_set.glsl"

layout(push_constant) uniform PushBlock { ClearSetsConstants pc; };

void main() {
  uint i = invocationIndex();
  if (pc.mode == kClearEndCells) {
    if (i < counters.endpoint_entries) ENDPOINT_KEYS[SLOTS[params.hash_capacity + i]] = kEmptyKey;
    return;
  }
  if (i < counters.brick_entries) {
    uint s = SLOTS[i];
    CELL_SET_KEYS[s] = kEmptyKey;
    for (uint w = 0u; w < kBrickFlagWords; ++w) CELL_SET_FLAGS[s * kBrickFlagWords + w] = 0u;
  }
  if (i < counters.new_blocks) ENDPOINT_KEYS[SLOTS[params.hash_capacity + i]] = kEmptyKey;
}
