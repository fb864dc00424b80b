#version 450
#extension GL_GOOGLE_include_directive : require
// The change set's keys that are in OctoMap's KeyBoolMap, compacted into the query output (the
// map's, or a caller's range) after a ChangedKeysHeader holding their count: a dispatch of one
// invocation zeroes the count (kListChangesHeader), then one invocation per slot appends
// (kListChangesKeys), in no particular order (a set).
#include "bindings.glsl"
#include "change_set.glsl"

layout(push_constant) uniform PushBlock { ListChangesConstants pc; };

layout(std430, binding = kBindQueryOut) buffer QueryOutBuf {
  ChangedKeysHeader changed_header;
  ChangedKey changed[];
};

void main() {
  uint s = invocationIndex();
  if (pc.mode == kListChangesHeader) {
    if (s == 0u) changed_header.count = 0u;
    return;
  }
  if (s >= pc.capacity) return;
  uint state = CHANGE_TABLE.slot[s].state;
  if (state == kChangeNone) return;
  uvec3 k = unpackKey(CHANGE_TABLE.slot[s].key);
  changed[atomicAdd(changed_header.count, 1u)] =
      ChangedKey(k.x, k.y, k.z, state == kChangeCreated ? 1u : 0u);
}
