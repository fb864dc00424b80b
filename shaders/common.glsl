// Bindings and the portable map math shared by every pass. The C++ twin of the math is
// src/map/reference.hpp; both follow OctoMap 1.9.7 operation for operation (float where OctoMap
// uses float, double where it uses double) and `precise` keeps the compiler from fusing them.
#extension GL_EXT_shader_explicit_arithmetic_types_int64 : require
#extension GL_EXT_shader_atomic_int64 : require
#extension GL_EXT_buffer_reference : require
#extension GL_KHR_memory_scope_semantics : require

#include "octovk/gpu_types.h"
#include "exact.glsl"

layout(local_size_x = 64) in;

// Push constants: each pass declares its own block (gpu_types.h: one struct per pass).

layout(std430, binding = kBindParams) buffer ParamsBuf { ScanParams params; };
layout(std430, binding = kBindCounters) buffer CountersBuf { ScanCounters counters; };
layout(std430, binding = kBindPool) buffer PoolBuf { PoolState pool; };
// The map's arrays, by device address (see kAddressedBindings): `nodes[i]` reads
// NodesRef(address of binding kBindNodes).v[i]. No descriptor range limits them.
layout(std430, binding = kBindAddresses) restrict readonly buffer AddressBuf {
  uint64_t buffer_address[kBindingCount];
};
#define OCTOVK_ADDRESSED(Ref, Type, align) \
  layout(buffer_reference, std430, buffer_reference_align = align) buffer Ref { Type v[]; }
OCTOVK_ADDRESSED(PointsRef, float, 4);
OCTOVK_ADDRESSED(HashKeysRef, uint64_t, 8);
OCTOVK_ADDRESSED(HashFlagsRef, uint, 4);
OCTOVK_ADDRESSED(NodesRef, Node, 4);
OCTOVK_ADDRESSED(BlockParentsRef, uint, 4);
OCTOVK_ADDRESSED(FreeStackRef, uint, 4);
OCTOVK_ADDRESSED(ActiveRef, ActiveCell, 4);
OCTOVK_ADDRESSED(TouchedRef, uint, 4);
OCTOVK_ADDRESSED(NewBlocksRef, NewBlock, 4);
OCTOVK_ADDRESSED(LeafBoxesRef, LeafBox, 4);
OCTOVK_ADDRESSED(EndpointKeysRef, uint64_t, 8);
OCTOVK_ADDRESSED(WalksRef, WalkState, 8);
OCTOVK_ADDRESSED(SlotsRef, uint, 4);
OCTOVK_ADDRESSED(CellListRef, uint, 4);
#define points (PointsRef(buffer_address[kBindPoints]).v)
#define hash_keys (HashKeysRef(buffer_address[kBindHashKeys]).v)
#define hash_flags (HashFlagsRef(buffer_address[kBindHashFlags]).v)
#define nodes (NodesRef(buffer_address[kBindNodes]).v)
#define block_parent (BlockParentsRef(buffer_address[kBindBlockParents]).v)
#define free_stack (FreeStackRef(buffer_address[kBindFreeStack]).v)
#define cells (ActiveRef(buffer_address[kBindActive]).v)
#define touched (TouchedRef(buffer_address[kBindTouched]).v)
#define prefix_blocks (NewBlocksRef(buffer_address[kBindNewBlocks]).v)
#define leaf_boxes (LeafBoxesRef(buffer_address[kBindLeafBoxes]).v)
#define endpoint_keys (EndpointKeysRef(buffer_address[kBindEndpointKeys]).v)
#define walks (WalksRef(buffer_address[kBindWalks]).v)
#define slots (SlotsRef(buffer_address[kBindSlots]).v)
#define cell_list (CellListRef(buffer_address[kBindCellList]).v)
// A depth image: its camera, then its pixels as words (kBindDepth).
layout(buffer_reference, std430, buffer_reference_align = 4) buffer DepthRef {
  DepthCamera camera;
  uint words[];
};
#define depth_image (DepthRef(buffer_address[kBindDepth]))
// Query inputs and outputs (kBindQueryIn, kBindQueryOut): each query pass declares its own view
// of them.

const uint64_t kEmptyKey = 0xFFFFFFFFFFFFFFFFul;

// A relaxed atomic load. Every word that other invocations of the same dispatch may write is read
// this way (and written with atomics): under the Vulkan memory model a plain access racing with a
// write is a data race, whose result is undefined (a 64-bit key could be read torn). Relaxed is
// enough: no pass infers anything about other words from the value it reads.
#define OCTOVK_LOAD(word) \
  atomicLoad(word, gl_ScopeDevice, gl_StorageSemanticsBuffer, gl_SemanticsRelaxed)

// Keeps the indirect dispatch arguments `args` covering a list of `end` entries: groups of 64
// entries, at most 65535 groups in x (the limit every device has), then rows of them in y, as the
// host folds direct dispatches. Called by the entry that starts a group; atomicMax makes the
// order of the callers irrelevant.
#define OCTOVK_COVER_LIST(args, end)                                  \
  {                                                                   \
    uint groups_ = ((end) + kWorkgroupSize - 1u) / kWorkgroupSize;    \
    atomicMax(args.x, min(groups_, 65535u));                          \
    atomicMax(args.y, (groups_ + 65534u) / 65535u);                   \
  }

// Work item index of a 1-D workload folded into x and y (by the host, or OCTOVK_COVER_LIST).
uint invocationIndex() {
  return gl_GlobalInvocationID.x + gl_GlobalInvocationID.y * gl_NumWorkGroups.x * gl_WorkGroupSize.x;
}

// ---- keys (OcTreeBaseImpl::coordToKeyChecked / keyToCoord) ----

bool coordToKeyChecked(float coord, out uint key) {
  precise double scaled = floor(params.resolution_factor * double(coord));
  key = 0u;
  // Also rejects NaN; the range test comes before the int conversion, which is undefined beyond it.
  if (!(scaled >= -32768.0lf && scaled < 32768.0lf)) return false;
  key = uint(int(scaled) + 32768);
  return true;
}

double keyToCoord(uint key) {
  precise double c = (double(int(key) - 32768) + 0.5lf) * params.resolution;
  return c;
}

uint64_t packKey(uvec3 k) {
  return uint64_t(k.x) | (uint64_t(k.y) << 16) | (uint64_t(k.z) << 32);
}

uvec3 unpackKey(uint64_t k) {
  return uvec3(uint(k & 0xFFFFul), uint((k >> 16) & 0xFFFFul), uint((k >> 32) & 0xFFFFul));
}

// Index of the child at depth+1 on the path of key k from a node at `depth` (computeChildIdx).
uint childIndex(uvec3 k, uint depth) {
  uint bit = 15u - depth;
  return ((k.x >> bit) & 1u) | (((k.y >> bit) & 1u) << 1) | (((k.z >> bit) & 1u) << 2);
}

// ---- the scan's two hash sets: bricks of cells, and nodes (end cells for discretize) ----

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
    uint64_t seen = OCTOVK_LOAD(hash_keys[s]);
    if (seen == brick) return s;
    // Off the fast path: once the set is known to be too small the scan is redone with a larger
    // one, so stop rather than probe a crowded table.
    if (probe == 0u && (OCTOVK_LOAD(counters.status) & kStatusHashFull) != 0u) return 0xFFFFFFFFu;
    uint64_t prev = seen == kEmptyKey ? atomicCompSwap(hash_keys[s], kEmptyKey, brick) : seen;
    if (prev == kEmptyKey) {
      uint n = atomicAdd(counters.brick_entries, 1u);
      slots[n] = s;
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
// the cells marked in it that are not yet stored in its flag words.
uvec3 marked_brick = uvec3(0xFFFFFFFFu);
uint marked_slot = 0u;
uvec2 marked_bits = uvec2(0u);

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
  uint base = marked_slot * kBrickFlagWords;
  for (uint w = 0u; w < 2u; ++w) {
    uint bits = marked_bits[w];
    if (bits != 0u && (OCTOVK_LOAD(hash_flags[base + w]) & bits) != bits)
      atomicOr(hash_flags[base + w], bits);
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
    uint s = insertBrick(packKey(brick));
    if (s == 0xFFFFFFFFu) return false;
    marked_brick = brick;
    marked_slot = s;
  }
  if (occupied) {
    uint index = brickCellIndex(k);
    uint word = marked_slot * kBrickFlagWords + (index >> 5);
    uint bit = 1u << (index & 31u);
    atomicOr(hash_flags[word], bit);
    atomicOr(hash_flags[word + 2u], bit);
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
    uint64_t seen = OCTOVK_LOAD(endpoint_keys[s]);
    if (seen == k) return 0u;
    uint64_t prev = seen == kEmptyKey ? atomicCompSwap(endpoint_keys[s], kEmptyKey, k) : seen;
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
    uint64_t seen = OCTOVK_LOAD(endpoint_keys[s]);
    if (seen == key) return s;
    if (seen == kEmptyKey) break;
    s = (s + 1u) & (cap - 1u);
  }
  return kNoBlock;
}

// Records the n-th entry of the second set, at `slot`; flags the set full beyond three quarters.
void countEndpointEntry(uint n, uint slot) {
  slots[params.hash_capacity + n] = slot;
  uint cap = params.endpoint_capacity;
  if (n >= cap - (cap >> 2)) atomicOr(counters.status, kStatusEndpointHashFull);
}

// ---- the tree ----

// Node n's link word. Read atomically: classify prepares child slots and the descent and the
// prune pass set flags while other invocations search through the same nodes.
// A pass that writes no node (OCTOVK_NODES_READ_ONLY, defined before including this file) has no
// racing writer and reads links plainly.
#ifdef OCTOVK_NODES_READ_ONLY
uint linkOf(uint n) { return nodes[n].link; }
#else
uint linkOf(uint n) { return OCTOVK_LOAD(nodes[n].link); }
#endif

// The block of node n's children, or kNoChildren.
uint childBlock(uint n) { return linkOf(n) & kBlockMask; }

// How a walk down the tree along a key's path ended (searchDown).
const uint kSearchOpen = 0u;     // reached the depth it was asked to stop at
const uint kSearchLeaf = 1u;     // at a node without children: search() finds it
const uint kSearchMissing = 2u;  // at a node with other children but not this one: not found

// OctoMap's search() from `node` at `depth` along k's path, down to at most depth `until`:
// steps into the child on the path while it exists; `parent` follows.
uint searchDown(uvec3 k, uint until, inout uint node, inout uint parent, inout uint depth) {
  for (; depth < until; ++depth) {
    uint block = childBlock(node);
    if (block == kNoChildren) return kSearchLeaf;
    uint child = block * 8u + childIndex(k, depth);
    if ((linkOf(child) & kFlagLive) == 0u) return kSearchMissing;
    parent = node;
    node = child;
  }
  return kSearchOpen;
}

// OcTreeBaseImpl::search(key): the deepest existing node on the key's path. Returns false when
// the path ends at a node that has other children but not this one (or there is no root).
// `node` and `depth` are the deepest node reached either way.
bool searchNode(uvec3 k, out uint node, out uint depth) {
  node = kRootNode;
  depth = 0u;
  if (pool.root_exists == 0u) return false;
  uint parent = kNoBlock;
  return searchDown(k, kTreeDepth, node, parent, depth) != kSearchMissing;
}
