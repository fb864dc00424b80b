#version 450
#extension GL_GOOGLE_include_directive : require
// The change set's keys that are in OctoMap's KeyBoolMap, compacted into the query output after
// a ChangedKeysHeader whose count is counters.query_results (the host copies it there): one
// invocation per slot, in no particular order (a set).
#include "bindings.glsl"
#include "change_set.glsl"

layout(push_constant) uniform PushBlock { ListChangesConstants pc; };

layout(std430, binding = kBindQueryOut) buffer QueryOutBuf {
  ChangedKeysHeader changed_header;
  ChangedKey changed[];
};

void main() {
  uint s = invocationIndex();
  if (s >= pc.capacity) return;
  uint state = change_table.slot[s].state;
  if (state == kChangeNone) return;
  uvec3 k = unpackKey(change_table.slot[s].key);
  changed[atomicAdd(counters.query_results, 1u)] =
      ChangedKey(k.x, k.y, k.z, state == kChangeCreated ? 1u : 0u);
}
