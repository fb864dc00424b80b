// The base of every pass: the extensions, the shared types (gpu_types.h), the exact float
// arithmetic (exact.glsl), the workgroup size, the bindings (params, counters, pool by
// descriptor; the map's arrays by device address), relaxed atomic loads, the cover of an
// indirect dispatch list and the 1-D work item index. No map math: keys.glsl, cell_set.glsl and
// tree_search.glsl build on it. The C++ twin of the map math is src/map/reference.hpp; both follow
// OctoMap 1.9.7 operation for operation (float where OctoMap uses float, double where it uses
// double) and `precise` keeps the compiler from fusing them.
#ifndef OCTOVK_BINDINGS_GLSL
#define OCTOVK_BINDINGS_GLSL

#extension GL_EXT_shader_explicit_arithmetic_types_int64 : require
#extension GL_EXT_shader_atomic_int64 : require
#extension GL_EXT_buffer_reference : require
#extension GL_KHR_memory_scope_semantics : require

#include "gpu/gpu_types.h"
#include "exact.glsl"

layout(local_size_x = 64) in;

// Push constants: each pass declares its own block (gpu_types.h: one struct per pass).

layout(std430, binding = kBindParams) buffer ParamsBuf { ScanParams params; };
layout(std430, binding = kBindCounters) buffer CountersBuf { ScanCounters counters; };
layout(std430, binding = kBindPool) buffer PoolBuf { PoolState pool; };
// The map's arrays, by device address (see kAddressedBindings): `NODES[i]` reads
// NodesRef(address of binding kBindNodes).v[i]. No descriptor range limits them. Nodes are
// read and written only through node.glsl.
layout(std430, binding = kBindAddresses) restrict readonly buffer AddressBuf {
  uint64_t buffer_address[kBindingCount];
};
#define OCTOVK_ADDRESSED(Ref, Type, align) \
  layout(buffer_reference, std430, buffer_reference_align = align) buffer Ref { Type v[]; }
OCTOVK_ADDRESSED(PointsRef, float, 4);
OCTOVK_ADDRESSED(CellSetKeysRef, uint64_t, 8);
OCTOVK_ADDRESSED(CellSetFlagsRef, uint, 4);
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
OCTOVK_ADDRESSED(PayloadRef, uint, 4);
OCTOVK_ADDRESSED(ColorFoldRef, uint, 4);
#define POINTS (PointsRef(buffer_address[kBindPoints]).v)
#define CELL_SET_KEYS (CellSetKeysRef(buffer_address[kBindCellSetKeys]).v)
#define CELL_SET_FLAGS (CellSetFlagsRef(buffer_address[kBindCellSetFlags]).v)
#define NODES (NodesRef(buffer_address[kBindNodes]).v)
#define BLOCK_PARENT (BlockParentsRef(buffer_address[kBindBlockParents]).v)
#define FREE_STACK (FreeStackRef(buffer_address[kBindFreeStack]).v)
#define CELLS (ActiveRef(buffer_address[kBindActive]).v)
#define TOUCHED (TouchedRef(buffer_address[kBindTouched]).v)
#define PREFIX_BLOCKS (NewBlocksRef(buffer_address[kBindNewBlocks]).v)
#define LEAF_BOXES (LeafBoxesRef(buffer_address[kBindLeafBoxes]).v)
#define ENDPOINT_KEYS (EndpointKeysRef(buffer_address[kBindEndpointKeys]).v)
#define WALKS (WalksRef(buffer_address[kBindWalks]).v)
#define SLOTS (SlotsRef(buffer_address[kBindSlots]).v)
#define CELL_LIST (CellListRef(buffer_address[kBindCellList]).v)
// A node's payload word (node.glsl alone reads and writes it; only where params.payload says so).
#define PAYLOAD (PayloadRef(buffer_address[kBindPayload]).v)
#define COLOR_FOLD (ColorFoldRef(buffer_address[kBindColorFold]).v)
// A depth image: its camera, then its pixels as words (kBindDepth).
layout(buffer_reference, std430, buffer_reference_align = 4) buffer DepthRef {
  DepthCamera camera;
  uint words[];
};
#define DEPTH_IMAGE (DepthRef(buffer_address[kBindDepth]))
// The change set (kBindChanges): its header, then its slots (change_set.glsl).
layout(buffer_reference, std430, buffer_reference_align = 16) buffer ChangeTableRef {
  ChangeHeader header;
  ChangeSlot slot[];
};
#define CHANGE_TABLE (ChangeTableRef(buffer_address[kBindChanges]))
// Query inputs and outputs (kBindQueryIn, kBindQueryOut): each query pass declares its own view
// of them.


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

#endif  // OCTOVK_BINDINGS_GLSL
