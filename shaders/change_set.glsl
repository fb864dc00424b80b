// The change set: OctoMap's changed keys (KeyBoolMap, OccupancyOcTreeBase::updateNodeRecurs with
// change detection on), kept on the device. descend notes each leaf it updates; list_changes
// and rehash_changes read the slots. See "Change detection" in docs/architecture.md for the rules.
#ifndef OCTOVK_CHANGE_SET_GLSL
#define OCTOVK_CHANGE_SET_GLSL

#include "keys.glsl"

const uint64_t kEmptyChangeKey = 0xFFFFFFFFFFFFFFFFul;

// First slot of a key in a change set of 2^log2 slots (Fibonacci hashing of the packed key).
uint changeSlot(uint64_t key, uint log2) {
  return uint((key * 0x9E3779B97F4A7C15ul) >> (64u - log2));
}

// The slot holding `key` in the change set at `table` (2^log2 slots), claiming a free one for it
// if it has none; 0xFFFFFFFF when no slot was found within the probes (tree_gate keeps the set
// at most 3/4 full, so a probe sequence ends at a free slot long before that).
uint findOrClaimChange(ChangeTableRef table, uint64_t key, uint log2) {
  uint mask = (1u << log2) - 1u;
  uint s = changeSlot(key, log2);
  for (uint probe = 0u; probe < 4096u; ++probe) {
    uint64_t seen = OCTOVK_LOAD(table.slot[s].key);
    if (seen == kEmptyChangeKey) {
      seen = atomicCompSwap(table.slot[s].key, kEmptyChangeKey, key);
      if (seen == kEmptyChangeKey) {
        atomicAdd(table.header.used, 1u);
        return s;
      }
    }
    if (seen == key) return s;
    s = (s + 1u) & mask;
  }
  return 0xFFFFFFFFu;
}

// OctoMap's bookkeeping after updating the leaf of key `k` (not reached at the early abort):
// a created leaf enters as `true` unless the key is there already (std::unordered_map::insert
// keeps an entry); else a flip of isNodeOccupied enters it as `false`, erases a `false` entry
// (flipped back) and leaves a `true` one. Each key is updated at most once per scan, so the one
// invocation that updates it is the only one to touch its slot's state in the dispatch.
void noteChange(uvec3 k, bool created, bool flipped) {
  if (params.changes_log2 == 0u || (!created && !flipped)) return;
  uint s = findOrClaimChange(CHANGE_TABLE, packKey(k), params.changes_log2);
  if (s == 0xFFFFFFFFu) {
    atomicOr(counters.status, kStatusChangesShort);  // never expected; the host says so
    return;
  }
  uint state = CHANGE_TABLE.slot[s].state;
  uint next = state;
  if (created) {
    if (state == kChangeNone) next = kChangeCreated;
  } else if (state == kChangeNone) {
    next = kChangeFlipped;
  } else if (state == kChangeFlipped) {
    next = kChangeNone;
  }
  if (next == state) return;
  CHANGE_TABLE.slot[s].state = next;
  atomicAdd(CHANGE_TABLE.header.live, next == kChangeNone ? 0xFFFFFFFFu : 1u);
}

#endif  // OCTOVK_CHANGE_SET_GLSL
