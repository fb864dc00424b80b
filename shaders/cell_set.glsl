// The scan's two hash sets: bricks of cells (ray_keys marks the cells a ray crosses), and nodes
// (discretize's end cells, then the prefixes of nodes that get a block). Has mutable globals
// (probes_spent, the marked brick): only the passes that fill or read the sets include it.
#ifndef OCTOVK_CELL_SET_GLSL
#define OCTOVK_CELL_SET_GLSL

#include "keys.glsl"

const uint64_t kEmptyKey = 0xFFFFFFFFFFFFFFFFul;

// Slot of a brick key in the cell set: the 2x2x2 group of bricks around it hashes to 8 adjacent
// slots (one cache line of keys), so a ray's next brick, and the bricks of neighbouring rays,
// are mostly in a line already read.
uint brickSlot(uint64_t brick, uint log2cap) {
  uint64_t group = (brick >> 1) & 0x00007FFF7FFF7FFFul;
  uint local = uint(brick & 1ul) | uint((brick >> 15) & 2ul) | uint((brick >> 30) & 4ul);
  return (uint((group * 0x9E3779B97F4A7C15ul) >> (67u - log2cap)) << 3) | local;
}

// Slot of a key of the second set (a node's key and depth, see prefixKey): the 2x2x2 brick of
// nodes of the same depth around it hashes to 8 adjacent slots (one cache line of keys), so the
// nodes of neighbouring cells meet in the same lines.
uint endpointSlot(uint64_t k, uint log2cap) {
  uint depth = uint(k >> 48);
  uvec3 c = unpackKey(k) >> (kTreeDepth - depth);
  uint64_t node = packKey(c);
  uint64_t brick = ((node >> 1) & 0x00007FFF7FFF7FFFul) | (uint64_t(depth) << 47);
  uint local = (c.x & 1u) | ((c.y & 1u) << 1) | ((c.z & 1u) << 2);
  return (uint((brick * 0x9E3779B97F4A7C15ul) >> (67u - log2cap)) << 3) | local;
}

// Loop iterations spent probing the sets, for passes that must budget them (lavapipe ends an
// invocation's loops after 65535 iterations in total).
int probes_spent = 0;

// Inserts a brick key into the scan's cell set; returns its slot, or 0xFFFFFFFF when the set is
// full.
uint insertBrick(uint64_t brick) {
  uint cap = params.hash_capacity;
  uint mask = cap - 1u;
  uint s = brickSlot(brick, params.hash_log2);
  for (uint probe = 0u; probe < 4096u; ++probe) {
    ++probes_spent;
    // A read first (atomic load, no write): most lookups find their brick already there (rays
    // share the bricks near the sensor), and reading avoids a compare-and-swap on a hot slot.
    uint64_t seen = OCTOVK_LOAD(CELL_SET_KEYS[s]);
    if (seen == brick) return s;
    // Off the fast path: once the set is known to be too small the scan is redone with a larger
    // one, so stop rather than probe a crowded table.
    if (probe == 0u && (OCTOVK_LOAD(counters.status) & kStatusHashFull) != 0u) return 0xFFFFFFFFu;
    uint64_t prev = seen == kEmptyKey ? atomicCompSwap(CELL_SET_KEYS[s], kEmptyKey, brick) : seen;
    if (prev == kEmptyKey) {
      uint n = atomicAdd(counters.brick_entries, 1u);
      SLOTS[n] = s;
      if (n % kWorkgroupSize == 0u) OCTOVK_COVER_LIST(counters.brick_args, n + 1u);
      if (n >= cap - (cap >> 2)) atomicOr(counters.status, kStatusHashFull);
      return s;
    }
    if (prev == brick) return s;
    s = (s + 1u) & mask;
  }
  atomicOr(counters.status, kStatusHashFull);
  return 0xFFFFFFFFu;
}

// The brick the last markCell of this invocation found (a ray's next cells are mostly in it), and
// the cells marked in it that are not yet stored in its flag words. kOtherGroup: the brick's tile
// is not in the scan's group (a scan applied in groups of tiles): its cells are not marked.
const uint kOtherGroup = 0xFFFFFFFEu;
uvec3 marked_brick = uvec3(0xFFFFFFFFu);
uint marked_slot = 0u;
uvec2 marked_bits = uvec2(0u);

// Whether the tile of `brick` (the node at depth kTileDepth: 4x4x4 bricks) is in the scan's group
// (params.tile_group: the group's index | (groups - 1) << 16). A tile's group is a hash of its
// key modulo the number of groups, so every group has about its share of any scan's cells; each
// cell is in one group, and every group walks every ray, so each cell is marked, free or
// occupied, in exactly one group.
bool inTileGroup(uvec3 brick) {
  if (params.tile_group == 0u) return true;  // the whole scan at once
  uint groups = (params.tile_group >> 16) + 1u;
  uvec3 t = brick >> (kTreeDepth - kTileDepth - 2u);
  uint h = t.x * 0x9E3779B1u ^ t.y * 0x85EBCA77u ^ t.z * 0xC2B2AE3Du;
  h ^= h >> 15;
  h *= 0x2C1B3C6Du;
  h ^= h >> 13;
  return h % groups == (params.tile_group & 0xFFFFu);
}

// Index of cell k in its 4x4x4 brick: x | y << 2 | z << 4 of the low key bits.
uint brickCellIndex(uvec3 k) { return (k.x & 3u) | ((k.y & 3u) << 2) | ((k.z & 3u) << 4); }

// Notes cell k of the current brick as marked (stored by flushMarks).
void noteMark(uvec3 k) {
  uint index = brickCellIndex(k);
  uint bit = 1u << (index & 31u);
  marked_bits |= index < 32u ? uvec2(bit, 0u) : uvec2(0u, bit);  // no dynamic index (see walk)
}

// Stores the pending marks of the current brick: one atomicOr per brick a ray crosses, not one
// per cell (none when neighbouring rays stored them already).
void flushMarks() {
  if (marked_slot == kOtherGroup) {
    marked_bits = uvec2(0u);
    return;
  }
  uint base = marked_slot * kBrickFlagWords;
  for (uint w = 0u; w < 2u; ++w) {
    uint bits = marked_bits[w];
    if (bits != 0u && (OCTOVK_LOAD(CELL_SET_FLAGS[base + w]) & bits) != bits)
      atomicOr(CELL_SET_FLAGS[base + w], bits);
  }
  marked_bits = uvec2(0u);
}

// Marks cell k in the scan's cell set (as occupied too when `occupied`). False when the set is
// full. The marks of a brick are stored when the ray leaves it; the invocation calls flushMarks()
// when it is done.
bool markCell(uvec3 k, bool occupied) {
  uvec3 brick = k >> 2;
  if (brick != marked_brick) {
    flushMarks();
    if (!inTileGroup(brick)) {
      marked_brick = brick;
      marked_slot = kOtherGroup;
      return true;
    }
    uint s = insertBrick(packKey(brick));
    if (s == 0xFFFFFFFFu) return false;
    marked_brick = brick;
    marked_slot = s;
  }
  if (marked_slot == kOtherGroup) return true;
  if (occupied) {
    uint index = brickCellIndex(k);
    uint word = marked_slot * kBrickFlagWords + (index >> 5);
    uint bit = 1u << (index & 31u);
    atomicOr(CELL_SET_FLAGS[word], bit);
    atomicOr(CELL_SET_FLAGS[word + 2u], bit);
  } else {
    noteMark(k);
  }
  return true;
}

// Inserts k into the second set (discretize's end cells, then the prefixes of nodes that get
// a block): 1 when inserted (at `slot`), 0 when present, 2 when the set is full.
uint insertEndpoint(uint64_t k, out uint slot) {
  uint cap = params.endpoint_capacity;
  if ((OCTOVK_LOAD(counters.status) & kStatusEndpointHashFull) != 0u) return 2u;
  uint s = endpointSlot(k, params.endpoint_log2);
  for (uint probe = 0u; probe < 4096u; ++probe) {
    uint64_t seen = OCTOVK_LOAD(ENDPOINT_KEYS[s]);
    if (seen == k) return 0u;
    uint64_t prev = seen == kEmptyKey ? atomicCompSwap(ENDPOINT_KEYS[s], kEmptyKey, k) : seen;
    slot = s;
    if (prev == kEmptyKey) return 1u;
    if (prev == k) return 0u;
    s = (s + 1u) & (cap - 1u);
  }
  atomicOr(counters.status, kStatusEndpointHashFull);
  return 2u;
}

// Key of the second set for the node at `depth` on the path of key k (the node that gets a block).
uint64_t prefixKey(uvec3 k, uint depth) {
  uint keep = depth == 0u ? 0u : (0xFFFFu << (kTreeDepth - depth)) & 0xFFFFu;
  return packKey(k & uvec3(keep)) | (uint64_t(depth) << 48);
}

// Slot of `key` in the second set, or kNoBlock when it is not there.
uint findEndpoint(uint64_t key) {
  uint cap = params.endpoint_capacity;
  uint s = endpointSlot(key, params.endpoint_log2);
  for (uint probe = 0u; probe < cap; ++probe) {
    uint64_t seen = OCTOVK_LOAD(ENDPOINT_KEYS[s]);
    if (seen == key) return s;
    if (seen == kEmptyKey) break;
    s = (s + 1u) & (cap - 1u);
  }
  return kNoBlock;
}

// Records the n-th entry of the second set, at `slot`; flags the set full beyond three quarters.
void countEndpointEntry(uint n, uint slot) {
  SLOTS[params.hash_capacity + n] = slot;
  uint cap = params.endpoint_capacity;
  if (n >= cap - (cap >> 2)) atomicOr(counters.status, kStatusEndpointHashFull);
}

#endif  // OCTOVK_CELL_SET_GLSL
