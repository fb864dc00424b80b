#version 450
#extension GL_GOOGLE_include_directive : require
// Growth of the change set: the keys of the old set (pc: its address and slots) that are in the
// map are inserted with their state into the new, empty set (kBindChanges, 2^changes_log2
// slots), whose header counts them (used = live = the keys moved). Slots whose key left the map
// are dropped. Keys are distinct, so no two invocations insert the same one.
#include "bindings.glsl"
#include "change_set.glsl"

layout(push_constant) uniform PushBlock { RehashChangesConstants pc; };

void main() {
  uint s = invocationIndex();
  if (s >= pc.old_capacity) return;
  ChangeTableRef old = ChangeTableRef(uint64_t(pc.old_address_lo) | (uint64_t(pc.old_address_hi) << 32));
  uint state = old.slot[s].state;
  if (state == kChangeNone) return;
  uint t = findOrClaimChange(CHANGE_TABLE, old.slot[s].key, params.changes_log2);
  if (t == 0xFFFFFFFFu) {
    atomicOr(counters.status, kStatusChangesShort);  // never expected: the new set is larger
    return;
  }
  CHANGE_TABLE.slot[t].state = state;
  atomicAdd(CHANGE_TABLE.header.live, 1u);
}
