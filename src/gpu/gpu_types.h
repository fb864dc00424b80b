// Structs and constants shared by the C++ host code and the GLSL compute shaders (internal: not
// installed). Included verbatim by both: every layout that crosses the host/device line is defined
// here once, or in the public octovk/device_types.h for the ones interop callers fill and read.
// Each struct's comment states its size ("N B."), each field, one per line, its size and offset
// ("4B (12)"), padding included: cmake/LayoutProbe.cmake reads the structs off this file (and
// octovk/device_types.h) to static_assert those and to generate the layout probe, with which
// tests/layout_test.cpp checks on the device that the GLSL side agrees.
#ifndef OCTOVK_GPU_TYPES_H
#define OCTOVK_GPU_TYPES_H

// The layouts a caller of the interop API needs (queries and their results) are public, in
// octovk/device_types.h, included here; everything else stays internal to the library.
#include "octovk/device_types.h"

#ifdef __cplusplus
#include <cstdint>
namespace octovk::gpu {
using uint = std::uint32_t;
using uint64_t = std::uint64_t;
#define OCTOVK_CONST static constexpr
#else
#define OCTOVK_CONST const
#endif

// Tree geometry, as OctoMap's 16-level OcTree.
OCTOVK_CONST uint kTreeDepth = 16u;
// The depth of the map's tiles (the store's unit, src/store/tiles.hpp; the groups of a scan
// applied in parts): the node at depth 12 and its subtree, 16^3 finest cells.
OCTOVK_CONST uint kTileDepth = 12u;
OCTOVK_CONST uint kTreeMaxVal = 32768u;

// Node pool: node index = block * 8 + slot. Block 0 holds the root in slot 0 (slots 1..7 unused).
OCTOVK_CONST uint kNoBlock = 0xFFFFFFFFu;
OCTOVK_CONST uint kRootNode = 0u;

// Bits of Node::link: the block of the node's 8 child slots, and per-node flags.
OCTOVK_CONST uint kBlockMask = 0x1FFFFFFFu;   // bits 0-28: block index of the children
OCTOVK_CONST uint kNoChildren = 0x1FFFFFFFu;  // block field of a node without children
// A node at the tile depth whose subtree is off the device (a map's working set of tiles,
// src/map/tile_working_set.hpp): it keeps its own data (the max of its subtree, its payload) and
// no children here; a scan that reaches it is refused until the host loaded the tile
// (kStatusTilesNeeded), and pruning never merges it. Only the host sets or clears it (upload).
OCTOVK_CONST uint kFlagEvicted = 0x20000000u;
OCTOVK_CONST uint kFlagTouched = 0x40000000u;  // on an updated path, listed for the prune pass
OCTOVK_CONST uint kFlagLive = 0x80000000u;     // the node exists (its parent has this child)
// Child bits of a node as the host tree (HostTree::Node::mask) gives them.
OCTOVK_CONST uint kChildMask = 0xFFu;

// The scan's cell set: a hash set of 4x4x4 bricks of cells. Keys are brick keys (cell key / 4,
// packed as x | y << 16 | z << 32; empty slots hold all ones); each brick slot has 4 flag words:
// words 0-1 one bit per cell of the brick that the scan touches, words 2-3 one bit per cell that
// is an end point (occupied wins). Cell index in the brick: x | y << 2 | z << 4 (low key bits);
// a cell's id is brick slot * 64 + index.
// Once list_cells has listed a brick's cells, words 0-1 hold instead the search of the tree
// down to the brick's node (depth 14), shared by its cells: word 0 the deepest node reached,
// word 1 its depth | kBrickFound | kBrickOpen (the brick's node exists: cells search on).
OCTOVK_CONST uint kCellsPerBrick = 64u;
OCTOVK_CONST uint kBrickFlagWords = 4u;
OCTOVK_CONST uint kBrickDepth = 14u;
OCTOVK_CONST uint kBrickFound = 0x100u;
OCTOVK_CONST uint kBrickOpen = 0x200u;

// Status bits in ScanCounters::status.
OCTOVK_CONST uint kStatusHashFull = 1u;
OCTOVK_CONST uint kStatusPoolFull = 2u;
OCTOVK_CONST uint kStatusRayCut = 8u;  // a ray walk was stopped by the device's loop limit
OCTOVK_CONST uint kStatusEndpointHashFull = 4u;  // the endpoint / prefix set of the scan is full
// Set by tree_gate: the scan was not applied (the map is as before it), because of one of the bits
// above, or because the pool or the touched lists lack room (the two bits below).
OCTOVK_CONST uint kStatusNotApplied = 16u;
OCTOVK_CONST uint kStatusPoolShort = 32u;   // fewer free blocks than new_blocks
OCTOVK_CONST uint kStatusListsShort = 64u;  // the touched lists' bound over params.touched_capacity
// Not applied because an earlier scan was not (PoolState::halted): scans queued behind a refused
// one leave the map alone until the host has grown what was short and replays them in order.
OCTOVK_CONST uint kStatusHalted = 128u;
// The change set (change detection on) might not have room for every cell the scan updates
// (at most 3/4 of its slots may be used): the scan is not applied; the host grows the set.
OCTOVK_CONST uint kStatusChangesShort = 256u;
// The scan reaches tiles whose subtree is off the device (kFlagEvicted): not applied; their nodes
// are in ScanCounters::needed_tiles, and the host loads them and runs the scan again.
OCTOVK_CONST uint kStatusTilesNeeded = 512u;
// More walks were left unfinished after a round than a list of saved walks holds
// (ScanParams::walk_capacity): not applied; the host grows the lists and runs the scan again.
OCTOVK_CONST uint kStatusWalksShort = 1024u;
// The scan's bricks list more cells (ScanCounters::cell_entries, counted in full) than the cell
// list holds (ScanParams::cell_capacity); set with kStatusHashFull, which stops the scan.
OCTOVK_CONST uint kStatusCellsShort = 2048u;
// Slots of ScanCounters::needed_tiles (a power of two): the evicted tiles one refusal names; a
// scan that reaches more is refused again after the host loaded these.
OCTOVK_CONST uint kNeededTileSlots = 64u;

OCTOVK_CONST uint kWorkgroupSize = 64u;
OCTOVK_CONST uint kLevelCount = 17u;  // depths 0..16

// One octree node. 8 B. A node has children exactly when its block field is not kNoChildren,
// and child i exists when slot i of that block has kFlagLive. kFlagTouched is clear between
// scans.
struct Node {
  float log_odds;  // 4B (0)
  uint link;       // 4B (4)  child block (kBlockMask bits) | kFlag* bits
};

// One leaf of the map, for renderers and queries. 20 B.
struct LeafBox {
  float center_x;  // 4B (0)
  float center_y;  // 4B (4)
  float center_z;  // 4B (8)
  float size;      // 4B (12) edge length in metres
  float log_odds;  // 4B (16)
};

// Persistent allocator state of the node pool. 32 B.
struct PoolState {
  uint bump;         // 4B (0)  next never-used block
  uint capacity;     // 4B (4)  blocks in the pool
  uint free_count;   // 4B (8)  entries on the free-block stack
  uint halted;       // 4B (12) 1 from a scan tree_gate refused until the host clears it: every
                     //         later scan is refused too (kStatusHalted)
  uint root_exists;  // 4B (16)
  uint leaf_count;   // 4B (20) entries written to the leaf-box buffer by the last rebuild
  uint live_nodes;   // 4B (24) nodes in the tree (maintained by the passes)
  uint pad0;         // 4B (28)
};

// Per-scan parameters, written once per scan. 136 B.
struct ScanParams {
  double resolution;         // 8B (0)
  double resolution_factor;  // 8B (8)
  double max_range;          // 8B (16) < 0: unlimited
  float origin_x;            // 4B (24)
  float origin_y;            // 4B (28)
  float origin_z;            // 4B (32)
  float prob_hit_log;        // 4B (36)
  float prob_miss_log;       // 4B (40)
  float clamp_min_log;       // 4B (44)
  float clamp_max_log;       // 4B (48)
  uint point_count;          // 4B (52)
  uint hash_capacity;        // 4B (56) power of two
  uint hash_log2;            // 4B (60)
  uint endpoint_capacity;    // 4B (64) power of two
  uint endpoint_log2;        // 4B (68)
  float rot_u;               // 4B (72) sensor rotation (OctoMap quaternion order u, x, y, z)
  float rot_x;               // 4B (76)
  float rot_y;               // 4B (80)
  float rot_z;               // 4B (84)
  uint touched_capacity;     // 4B (88) entries of the touched lists (all levels together)
  float trans_x;             // 4B (92) sensor translation
  float trans_y;             // 4B (96)
  float trans_z;             // 4B (100)
  float occupancy_log;       // 4B (104) occupancy threshold (isNodeOccupied: log-odds >= this)
  uint changes_log2;         // 4B (108) change detection: log2 of the change set's slots; 0: off
  uint cell_capacity;        // 4B (112) entries of the cell list and the active-cell list
  uint payload;              // 4B (116) kPayload*: what PAYLOAD holds per node
  uint stamp;                // 4B (120) kPayloadStamp: the scan's time stamp
  uint tile_group;           // 4B (124) a scan applied in groups of tiles: this group's index |
                             // (groups - 1) << 16; 0: every tile
  uint walk_capacity;        // 4B (128) entries of each list of walks saved between rounds
  uint pad0;                 // 4B (132)
};

// What a node holds besides its log-odds (MapParams::payload): PAYLOAD, one word per node.
OCTOVK_CONST uint kPayloadNone = 0u;
OCTOVK_CONST uint kPayloadColor = 1u;  // r | g << 8 | b << 16; white (0xFFFFFF): no colour
OCTOVK_CONST uint kPayloadStamp = 2u;  // whole seconds
OCTOVK_CONST uint kColorUnset = 0x00FFFFFFu;
OCTOVK_CONST uint kFoldEmpty = 0xFFFFFFFFu;  // an empty entry of the colour fold's table or list

// color_fold (kBindColorFold: a table of 2^table_log2 (node, first point) pairs, then per point
// of the scan its colour and its link, then the folded list: a FoldedNode per node whose colour
// the fold changed, counted in ScanCounters::folded_count). Where a driver ends loops early the
// points are folded in chunks of consecutive indices, one chunk after another, so that no node's
// list outgrows the loop budget. 16 B.
OCTOVK_CONST uint kColorFoldGroup = 0u;  // per point: its node found, the point pushed on its list
// Per table entry: the node's points in order, folded by averageNodeColor or integrateNodeColor.
OCTOVK_CONST uint kColorFoldAverage = 1u;
OCTOVK_CONST uint kColorFoldIntegrate = 2u;
struct ColorFoldConstants {
  uint mode;        // 4B (0)  kColorFold*
  uint table_log2;  // 4B (4)  the table's entries: 2^table_log2
  uint first;       // 4B (8)  the chunk's first point
  uint count;       // 4B (12) its points
};

// A node whose colour a scan's fold changed, and where it lies: the key of a point in it and its
// depth (a pruned leaf lies above the finest level). Its tile's ancestors need not be on the
// scan's updated paths (a leaf at the clamping bound takes no update, yet its colour changes):
// a store's capture reads the list beside the touched lists. 12 B.
struct FoldedNode {
  uint node;         // 4B (0)
  uint key_xy;       // 4B (4)  key x | key y << 16
  uint key_z_depth;  // 4B (8)  key z | depth << 16
};

// A store's capture after a scan, as a change of the host's copy of the pool (capture.comp): per
// entry of the scan's touched lists (the nodes on its updated paths, deepest level first, as the
// lists lie), the node, its children's block and their payload words. What a scan changes lies in
// such a node or in its children's block: updated leaves are children of nodes listed at depth
// 15, new nodes and merged ones children of listed nodes, inner values listed; a colour the fold
// changed is in its folded list, whose records follow. 120 B.
struct CaptureRecord {
  uint index;             // 4B (0)  the node (the entry of the touched lists)
  uint payload;           // 4B (4)  its payload word (0 in a map without payload)
  uint64_t node;          // 8B (8)  the Node's two words as one: log-odds bits | link << 32
  uint64_t children[8];   // 64B (16) its children's block (as `node`) when it has one
  uint child_payload[8];  // 32B (80) their payload words
  uint key_xy;            // 4B (112) a folded node's FoldedNode fields; 0 for a listed one
  uint key_z_depth;       // 4B (116)
};
// capture.comp's push constants. 16 B.
OCTOVK_CONST uint kNoFoldedList = 0xFFFFFFFFu;
struct CaptureConstants {
  uint64_t records;  // 8B (0)  device address of CaptureRecord[capacity] (host-visible staging)
  uint capacity;     // 4B (8)  records it holds: entries past it are not written
  uint folded_at;    // 4B (12) the word of COLOR_FOLD where the scan's folded list starts (its
                     //         records follow the touched lists'), else kNoFoldedList
};

// A node that gets a block of children in this scan: one per entry of the second set, at the
// entry's slot. Written by classify (node, source) and alloc (block). 12 B.
struct NewBlock {
  uint node;    // 4B (0)  the node, when it exists before alloc runs; else kNoBlock (it lies in
                //         the block of the entry one level up)
  uint source;  // 4B (4)  the pruned leaf whose value the block's 8 children take (expandNode),
                //         or kNoBlock: a node created in this scan (createNodeChild)
  uint block;   // 4B (8)  the block given to the node
};
// Per-cell state of the descent through the tree, one per active cell. 16 B.
struct ActiveCell {
  uint slot;    // 4B (0)  id of the cell in the cell set (brick slot * 64 + index)
  uint node;    // 4B (4)  deepest node on the path that existed before the scan
  uint parent;  // 4B (8)  its parent (kNoBlock for the root)
  uint depth;   // 4B (12) its depth
};

// Indirect dispatch arguments, as VkDispatchIndirectCommand. 12 B.
struct DispatchArgs {
  uint x;  // 4B (0)
  uint y;  // 4B (4)
  uint z;  // 4B (8)
};

// Counters of one scan, reset at its start. The host reads this struct back once per scan
// (with the PoolState right after it, in the readback region of its frame). 684 B.
struct ScanCounters {
  uint status;             // 4B (0)   kStatus* bits
  uint brick_entries;      // 4B (4)   distinct bricks in the cell set
  uint endpoint_entries;   // 4B (8)   distinct end cells (discretize)
  uint active_cells;       // 4B (12)  updated cells whose path needs nodes (those whose leaf
                           //          exists are counted in leaf_cells)
  uint skipped_nonfinite;  // 4B (16)  points with NaN or infinite coordinates
  uint skipped_outside;    // 4B (20)  points whose ray or end cell lies outside the map
  uint occupied_cells;     // 4B (24)
  uint free_cells;         // 4B (28)
  uint aborted;            // 4B (32)
  uint new_blocks;         // 4B (36)  distinct nodes that get a block of children this scan
  uint cell_entries;       // 4B (40)  distinct cells of the scan (the cell list)
  uint query_results;      // 4B (44)  entries written by a compacting query (leaves in a box)
  uint leaf_cells;         // 4B (48)  updated cells whose leaf exists (no descent needed)
  uint touched_count[kLevelCount];         // 68B (52)  nodes listed for the prune pass, per depth
  DispatchArgs touched_args[kLevelCount];  // 204B (120)
  uint walk_count[2];                      // 8B (324) unfinished ray walks, two lists (ping-pong)
  DispatchArgs walk_args[2];               // 24B (332)
  DispatchArgs cell_args;                  // 12B (356) groups over the cell list
  DispatchArgs brick_args;                 // 12B (368) groups over the cell set's bricks
  uint no_depth;  // 4B (380) depth-image pixels with d = 0 or non-finite d (written as NaN
                  //          points, so also counted in skipped_nonfinite)
  DispatchArgs block_args;   // 12B (384) groups over new_blocks (alloc, link); set by tree_gate
  DispatchArgs active_args;  // 12B (396) groups over the active cells (descend); set by tree_gate
  DispatchArgs clear_args;   // 12B (408) groups over max(brick_entries, new_blocks): the slots
                             //           clear_sets empties at the scan's end; set by tree_gate
  uint tiles_needed;         // 4B (420) distinct evicted tiles in needed_tiles (list_cells)
  uint needed_tiles[kNeededTileSlots];  // 256B (424) an open-addressed set of evicted tile
                                        //  nodes the scan reaches: node + 1, 0 = empty slot
  uint folded_count;                    // 4B (680) entries of color_fold's folded list (FoldedNode)
};

// A ray walk of the ray-key pass, saved between segments. 48 B.
struct WalkState {
  double t_max_x;  // 8B (0)
  double t_max_y;  // 8B (8)
  double t_max_z;  // 8B (16)
  float end_x;     // 4B (24) the ray's end point (its origin is the scan's)
  float end_y;     // 4B (28)
  float end_z;     // 4B (32)
  uint key_xy;     // 4B (36) current cell
  uint key_z;      // 4B (40)
  uint pad0;       // 4B (44)
};

// The camera of a depth image, at the start of the depth buffer (kBindDepth); the pixels follow
// from byte 32: uint16 (two per word, the first in the low half) or float32. 32 B.
OCTOVK_CONST uint kDepthUint16 = 0u;
OCTOVK_CONST uint kDepthFloat32 = 1u;
struct DepthCamera {
  float fx;           // 4B (0)
  float fy;           // 4B (4)
  float cx;           // 4B (8)
  float cy;           // 4B (12)
  float depth_scale;  // 4B (16) depth units per metre: z = d / depth_scale
  uint width;         // 4B (20)
  uint height;        // 4B (24)
  uint encoding;      // 4B (28) kDepthUint16 / kDepthFloat32
};

// A castRay walk between segments (see shaders/cast_ray.comp). The query output holds one per
// ray after the results, from the first whole RayState after them (castRaysResultBytes); element
// e of that array also holds entry e of the two lists of unfinished walks, which is not walk e's
// (so the fields are written one by one, never the whole struct). 48 B.
struct RayState {
  double t_max_x;      // 8B (0)
  double t_max_y;      // 8B (8)
  double t_max_z;      // 8B (16)
  uint key_x;          // 4B (24)
  uint key_y;          // 4B (28)
  uint key_z;          // 4B (32)
  uint done;           // 4B (36) 1: the result is written
  uint unfinished[2];  // 8B (40) entry e of list 0 and of list 1: the index of an unfinished ray
};

// The device probe (shaders/device_probe.comp, run when a Context is created): one case of the
// arithmetic check. 32 B.
struct ProbeCase {
  double a;  // 8B (0)
  double b;  // 8B (8)
  float fa;  // 4B (16)
  float fb;  // 4B (20)
  float fc;  // 4B (24)
  uint pad;  // 4B (28)
};

// What the device computed for one ProbeCase, compared bit for bit with the host. 64 B.
struct ProbeResult {
  double sum;         // 8B (0)  a + b
  double difference;  // 8B (8)  a - b
  double product;     // 8B (16) a * b
  double quotient;    // 8B (24) a / b
  double root;        // 8B (32) sqrt(|a|)
  double floor_a;     // 8B (40) floor(a)
  double rounded;     // 8B (48) roundedToFloat(a): a rounded to float, ties to even
  float float_madd;   // 4B (56) fa * fb + fc in float, not fused
  float float_div;    // 4B (60) divFloat(fa, fb)
};

// Cases of the device probe's arithmetic check (a multiple of the workgroup size).
OCTOVK_CONST uint kProbeCases = 4096u;

// Head of the probe's output (binding 15), followed by int(floor(a)) of each case (0 where it does
// not fit an int), then the ProbeResults. 16 B.
struct ProbeHeader {
  uint loop_iterations;  // 4B (0) least over the invocations of kProbeModeLoop
  uint pad0;             // 4B (4)
  uint pad1;             // 4B (8)
  uint pad2;             // 4B (12)
};

// Leaves-in-a-box query (OctoMap's leaf_bbx_iterator): keys of the box corners. 32 B.
struct BoxQuery {
  uint min_x;          // 4B (0)
  uint min_y;          // 4B (4)
  uint min_z;          // 4B (8)
  uint max_x;          // 4B (12)
  uint max_y;          // 4B (16)
  uint max_z;          // 4B (20)
  uint occupied_only;  // 4B (24)
  uint pad0;           // 4B (28)
};

// ---- change detection (OctoMap's changed keys) ----
// The change set (binding kBindChanges): a ChangeHeader, then 2^ScanParams::changes_log2
// ChangeSlots, an open-addressing hash set of finest-level keys. A slot, once claimed by a key,
// keeps it until the set is reset or rehashed; its state says whether the key is in OctoMap's
// KeyBoolMap now, and with which flag. Empty slots hold kEmptyChangeKey and kChangeNone (the
// whole buffer filled with 0xFF bytes).
OCTOVK_CONST uint kChangeFlipped = 0u;        // in the map as `false`: its occupancy flipped
OCTOVK_CONST uint kChangeCreated = 1u;        // in the map as `true`: its leaf was created
OCTOVK_CONST uint kChangeNone = 0xFFFFFFFFu;  // not in the map (never was, or flipped back)
// The change set's header. 16 B.
struct ChangeHeader {
  uint used;  // 4B (0)  slots claimed by a key (what limits the set's load)
  uint live;  // 4B (4)  keys in the map (numChangesDetected)
  uint pad0;  // 4B (8)
  uint pad1;  // 4B (12)
};
// One slot of the change set. 16 B.
struct ChangeSlot {
  uint64_t key;  // 8B (0)  packKey of the finest-level key; kEmptyChangeKey: free
  uint state;    // 4B (8)  kChange*
  uint pad0;     // 4B (12)
};

// ---- push constants ----
// Every pipeline layout has one 16-byte push-constant range. Each pass reads it as its own struct
// of four uints below (`layout(push_constant) uniform PushBlock { XConstants pc; };` in the pass),
// and the host pushes that struct when it records the pass. A pass that takes nothing declares no
// push block; the host pushes NoConstants (zeros) for it: tree_begin, alloc, tree_fixup, link,
// list_cells, classify.
#ifdef __cplusplus
// The push range as a whole (the pipeline layout's size, src/vk/device.cpp); no pass reads it as
// such, and every XConstants has its size.
struct PassConstants {
  uint words[4];  // 16B (0)
};
#endif

// Passes without constants. 16 B.
struct NoConstants {
  uint pad0;  // 4B (0)
  uint pad1;  // 4B (4)
  uint pad2;  // 4B (8)
  uint pad3;  // 4B (12)
};

// clear_sets. 16 B.
OCTOVK_CONST uint kClearScan = 0u;      // at a scan's end, the slots it filled in both sets
OCTOVK_CONST uint kClearEndCells = 1u;  // discretize's end cells, before classify reuses the set
struct ClearSetsConstants {
  uint mode;  // 4B (0)  kClearScan / kClearEndCells
  uint pad0;  // 4B (4)
  uint pad1;  // 4B (8)
  uint pad2;  // 4B (12)
};

// transform_points. 16 B.
struct TransformPointsConstants {
  uint point_count;  // 4B (0)
  uint pad0;         // 4B (4)
  uint pad1;         // 4B (8)
  uint pad2;         // 4B (12)
};

// discretize. 16 B.
struct DiscretizeConstants {
  uint point_count;  // 4B (0)
  uint pad0;         // 4B (4)
  uint pad1;         // 4B (8)
  uint pad2;         // 4B (12)
};

// unproject. 16 B.
struct UnprojectConstants {
  uint pixel_count;  // 4B (0)
  uint pad0;         // 4B (4)
  uint pad1;         // 4B (8)
  uint pad2;         // 4B (12)
};

// ray_keys. 16 B.
OCTOVK_CONST uint kRayKeysPoints = 0u;        // a ray to every point of the scan
OCTOVK_CONST uint kRayKeysEndCells = 1u;      // a ray to every distinct end cell (discretize)
OCTOVK_CONST uint kRayKeysContinue = 2u;      // continue the walks of list from_list
OCTOVK_CONST uint kRayKeysContinueLast = 3u;  // the same, last round: an unfinished walk is cut
struct RayKeysConstants {
  uint budget;       // 4B (0)  loop iterations a walk takes before it is saved
  uint point_count;  // 4B (4)  kRayKeysPoints: points of the scan
  uint mode;         // 4B (8)  kRayKeys*
  uint from_list;    // 4B (12) kRayKeysContinue*: the list (0, 1) of walks to continue
};

// descend, tree_gate: no constants (the counts are in ScanCounters).

// prune. 16 B.
struct PruneConstants {
  uint level;  // 4B (0)  depth of the nodes this dispatch prunes
  uint pad0;   // 4B (4)
  uint pad1;   // 4B (8)
  uint pad2;   // 4B (12)
};

// leaf_boxes. 16 B.
OCTOVK_CONST uint kLeafBoxesRebuild = 0u;  // every leaf into the leaf-box buffer
OCTOVK_CONST uint kLeafBoxesInBox = 1u;    // the leaves in the query's BoxQuery, compacted
struct LeafBoxesConstants {
  uint mode;  // 4B (0)  kLeafBoxes*
  uint pad0;  // 4B (4)
  uint pad1;  // 4B (8)
  uint pad2;  // 4B (12)
};

// lookup. 16 B.
struct LookupConstants {
  uint point_count;   // 4B (0)
  uint first_float;   // 4B (4)  the points' first float in the query input (after the rays)
  uint first_result;  // 4B (8)  their first LookupResult in the output (after the rays')
  uint pad0;          // 4B (12)
};

// cast_ray. 16 B.
struct CastRayConstants {
  uint budget;       // 4B (0)  loop iterations a walk takes before it is saved
  uint ray_count;    // 4B (4)
  uint resume;       // 4B (8)  0: start every ray; 1 + l: continue the walks listed in list l
  uint first_state;  // 4B (12) the RayState (element of the query output) of ray 0
};

// The ray-tracing backend of castRay (cast_ray_rt.comp): the boxes an acceleration structure is
// built over, in one buffer reached by device address: this header, then the AABBs of the
// occupied leaves (from the leaf-box buffer), each enlarged by a margin so that the hardware's
// float test cannot miss a box that OctoMap's walk enters. The list is sorted along a Morton curve
// (a counting sort on kAccelBuckets cells of the boxes' extent), because a builder may keep the
// order it is given (lavapipe's pairs neighbours in the array). After the sorted list: the same
// list unsorted, as accel_boxes writes it, then the sort's bucket counters (kAccelBuckets) and the
// sums of their chunks (kAccelChunks). No unknown region gets a box: castRay traces only the rays
// that ignore unknown space (cast_ray_rt.glsl). 64 B.
OCTOVK_CONST uint kAccelBucketBits = 7u;  // per axis
OCTOVK_CONST uint kAccelBuckets = 1u << (3u * kAccelBucketBits);
OCTOVK_CONST uint kAccelChunks = 2048u;  // the scan of the counters: chunks of this many
struct AccelHeader {
  uint64_t tlas;      // 8B (0)  device address of the top-level acceleration structure
  uint box_count;     // 4B (8)  boxes written (by accel_boxes)
  uint box_capacity;  // 4B (12) room for boxes
  uint lo_x;          // 4B (16) smallest cell key of the small boxes' centres (sort range)
  uint lo_y;          // 4B (20)
  uint lo_z;          // 4B (24)
  uint hi_x;          // 4B (28) largest
  uint hi_y;          // 4B (32)
  uint hi_z;          // 4B (36)
  uint bucket_bits;   // 4B (40) the sort's Morton bits per axis, 4..kAccelBucketBits
  uint pad0;          // 4B (44)
  uint pad1;          // 4B (48)
  uint pad2;          // 4B (52)
  uint pad3;          // 4B (56)
  uint pad4;          // 4B (60)
};
// One box, as VkAabbPositionsKHR (the acceleration-structure build reads it). 24 B.
struct AccelBox {
  float min_x;  // 4B (0)  NaN: an inactive box (the build skips it)
  float min_y;  // 4B (4)
  float min_z;  // 4B (8)
  float max_x;  // 4B (12)
  float max_y;  // 4B (16)
  float max_z;  // 4B (20)
};

// accel_boxes. 16 B.
OCTOVK_CONST uint kAccelBoxesOccupied = 0u;  // one invocation per leaf-box slot
OCTOVK_CONST uint kAccelBoxesCount = 1u;     // per unsorted box: count it in its bucket
OCTOVK_CONST uint kAccelBoxesChunks = 2u;    // per chunk of buckets: its sum
OCTOVK_CONST uint kAccelBoxesOffsets = 3u;   // per chunk: the buckets' first places
OCTOVK_CONST uint kAccelBoxesScatter = 4u;   // per unsorted box: into its bucket's place
struct AccelBoxesConstants {
  uint64_t boxes;  // 8B (0)  device address of the AccelHeader
  uint mode;       // 4B (8)  kAccelBoxes*
  uint pad0;       // 4B (12)
};

// cast_ray_rt. 16 B.
struct CastRayRtConstants {
  uint64_t boxes;  // 8B (0)  device address of the AccelHeader
  uint ray_count;  // 4B (8)  rays this dispatch walks,
  uint first_ray;  // 4B (12) from this one on
};

// list_changes. 16 B.
OCTOVK_CONST uint kListChangesHeader = 0u;  // one invocation: the output header's count to 0
OCTOVK_CONST uint kListChangesKeys = 1u;    // per slot: the keys in the set appended after it
struct ListChangesConstants {
  uint capacity;  // 4B (0)  slots of the change set
  uint mode;      // 4B (4)  kListChanges*
  uint pad1;      // 4B (8)
  uint pad2;      // 4B (12)
};

// rehash_changes: the keys of the old change set (at old_address, old_capacity slots) into the
// new one (kBindChanges, empty). 16 B.
struct RehashChangesConstants {
  uint old_address_lo;  // 4B (0)
  uint old_address_hi;  // 4B (4)
  uint old_capacity;    // 4B (8)
  uint pad0;            // 4B (12)
};

// clear_box. 16 B.
OCTOVK_CONST uint kClearBoxLeaves = 0u;  // the leaves in the BoxQuery to the lower clamping bound
OCTOVK_CONST uint kClearBoxInner = 1u;   // the nodes at `level` with children: their max
OCTOVK_CONST uint kClearBoxDepths = 2u;  // the live blocks listed by depth, for kClearBoxInner
// OcTreeStamped::degradeOutdatedNodes: every live occupied leaf with now - stamp > threshold
// (unsigned) takes one miss, keeping its stamp.
OCTOVK_CONST uint kClearBoxDegrade = 3u;
// kClearBoxInner whose nodes take the stamp `now` (degrade's updateInnerOccupancy); plain
// kClearBoxInner gives a stamped node its newest child's stamp.
OCTOVK_CONST uint kClearBoxInnerAt = 4u;
struct ClearBoxConstants {
  uint mode;       // 4B (0)  kClearBox*
  uint level;      // 4B (4)  kClearBoxInner: depth of the nodes updated
  uint now;        // 4B (8)  kClearBoxDegrade, kClearBoxInnerAt: the query time
  uint threshold;  // 4B (12) kClearBoxDegrade: the age (seconds) beyond which a leaf degrades
};

// keep_box. 16 B. Marks use kFlagTouched (clear between scans; keep_box clears what it set).
OCTOVK_CONST uint kKeepBoxMark = 0u;   // per block: the leaves in the BoxQuery and every node above
OCTOVK_CONST uint kKeepBoxSweep = 1u;  // per block: unmarked nodes deleted, their blocks freed
OCTOVK_CONST uint kKeepBoxUnmark = 2u;  // per block: the marks of its slots (and the root) cleared
struct KeepBoxConstants {
  uint mode;  // 4B (0)  kKeepBox*
  uint pad0;  // 4B (4)
  uint pad1;  // 4B (8)
  uint pad2;  // 4B (12)
};

// device_probe. 16 B.
OCTOVK_CONST uint kProbeModeArithmetic = 0u;  // per case, the operations, into ProbeResults
OCTOVK_CONST uint kProbeModeLoop = 1u;        // the iterations a loop really runs
// Tests only (deviceOccupancies): occupancyProbability (probability.glsl) of floats
// first ... first + case_count - 1 of the input (a float array), into a double array.
OCTOVK_CONST uint kProbeModeProbability = 2u;
struct DeviceProbeConstants {
  uint mode;             // 4B (0)  kProbeMode*
  uint case_count;       // 4B (4)  kProbeModeArithmetic: cases; kProbeModeProbability: values
  uint loop_iterations;  // 4B (8)  kProbeModeLoop: iterations the loop asks for
  uint first;            // 4B (12) kProbeModeProbability: the dispatch's first value
};

// Descriptor bindings: every pass sees the same set layout.
OCTOVK_CONST uint kBindParams = 0u;
OCTOVK_CONST uint kBindCounters = 1u;
OCTOVK_CONST uint kBindPool = 2u;
OCTOVK_CONST uint kBindPoints = 3u;
OCTOVK_CONST uint kBindCellSetKeys = 4u;
OCTOVK_CONST uint kBindCellSetFlags = 5u;
OCTOVK_CONST uint kBindNodes = 6u;
OCTOVK_CONST uint kBindBlockParents = 7u;  // per block, the node it hangs under (kNoBlock: free)
OCTOVK_CONST uint kBindFreeStack = 8u;
OCTOVK_CONST uint kBindActive = 9u;
OCTOVK_CONST uint kBindTouched = 10u;
OCTOVK_CONST uint kBindNewBlocks = 11u;  // NewBlock per slot of the second set
OCTOVK_CONST uint kBindLeafBoxes = 12u;
OCTOVK_CONST uint kBindEndpointKeys = 13u;
OCTOVK_CONST uint kBindQueryIn = 14u;
OCTOVK_CONST uint kBindQueryOut = 15u;
OCTOVK_CONST uint kBindWalks = 16u;
OCTOVK_CONST uint kBindSlots =
    17u;  // the slots filled in the cell set, then those of the second set
OCTOVK_CONST uint kBindCellList = 18u;   // ids of the scan's distinct cells
OCTOVK_CONST uint kBindDepth = 19u;      // a depth image: DepthCamera, then its pixels
OCTOVK_CONST uint kBindChanges = 20u;    // the changed keys: ChangeHeader, then ChangeSlots
OCTOVK_CONST uint kBindPayload = 21u;    // a word per node (ScanParams::payload), or one word
OCTOVK_CONST uint kBindColorFold = 22u;  // a colour scan's colours, links and table (color_fold)
OCTOVK_CONST uint kBindingCount = 23u;
// The map's arrays that can outgrow one descriptor's range (maxStorageBufferRange: 128 MiB on
// lavapipe, while a 0.02 m map's node pool alone takes 454 MiB) are not bound by descriptor:
// the shaders reach them by device address (GL_EXT_buffer_reference). Their addresses, indexed
// by binding, are in a table bound at kBindAddresses (uint64_t[kBindingCount]; 0 elsewhere).
// Params, counters, pool state and the two query bindings stay descriptors (small, or ranges
// of a caller's buffers).
OCTOVK_CONST uint kBindAddresses = 23u;
OCTOVK_CONST uint kAddressedBindings =
    (1u << kBindPoints) | (1u << kBindCellSetKeys) | (1u << kBindCellSetFlags) |
    (1u << kBindNodes) | (1u << kBindBlockParents) | (1u << kBindFreeStack) | (1u << kBindActive) |
    (1u << kBindTouched) | (1u << kBindNewBlocks) | (1u << kBindLeafBoxes) |
    (1u << kBindEndpointKeys) | (1u << kBindWalks) | (1u << kBindSlots) | (1u << kBindCellList) |
    (1u << kBindDepth) | (1u << kBindChanges) | (1u << kBindPayload) | (1u << kBindColorFold);

// Scans through ray tracing (MapParams::scan_rays = kRayTracing; scan_rays_rt.comp). Its boxes
// are written by accel_boxes in two more modes into a boxes buffer of the same layout
// (AccelHeader, sorted list, unsorted list, sort counters): every leaf a free update could change
// (log-odds above clamp_min_log: occupied leaves and free leaves not yet clamped) and the unknown
// regions; leaves clamped free get no box (a free update there is a no-op, OctoMap's early
// abort). The list is built at its capacity, the slots after its count empty boxes outside the
// map (kAccelBoxesTail).
OCTOVK_CONST uint kAccelBoxesScan = 5u;  // one invocation per pool block
OCTOVK_CONST uint kAccelBoxesTail = 6u;  // per box slot: after the count, empty
// scan_rays_rt. 16 B.
struct ScanRaysRtConstants {
  uint64_t boxes;    // 8B (0)  device address of the AccelHeader
  uint point_count;  // 4B (8)  kRayKeysPoints: points of the scan
  uint mode;         // 4B (12) kRayKeysPoints or kRayKeysEndCells (discretize)
};

// ---- the distance field (src/field/, shaders field_*.comp) ----
// A box of cells at the finest depth, key min_key + (x, y, z), cell index x + size_x * (y +
// size_y * z). Its arrays are reached by device address from the header (the header's own
// address is in each pass's push constants):
// - occupancy: one bit per cell, bit x % 32 of word x / 32 + words_per_row * (y + size_y * z):
//   the box's obstacles (field_raster from the tree, field_changes from the change set);
// - line_x: per cell, the x of the nearest obstacle on its x-line (field_nearest_x);
// - plane_xy: per cell, x | y << 16 of the nearest obstacle in its z-plane (field_edt, y);
// - sites: per cell, the cell index of the nearest obstacle of the box (field_edt, z);
// - envelope: field_edt's scratch, per cell one lower-envelope entry (t | v << 16, v's input);
// - dirty: three bitmaps of lines to redo in an incremental update: x-lines (bit y + size_y *
//   z), from word 0; y-lines (bit x + size_x * z), from word dirty_y; z-lines (bit x + size_x *
//   y), from word dirty_z.
// The squared distance of a cell is |cell - site|^2, computed where it is read.
OCTOVK_CONST uint kFieldNone = 0xFFFFFFFFu;    // no obstacle (line_x, plane_xy, sites)
OCTOVK_CONST uint kFieldNoSite = 0xFFFFFFFFu;  // sites: the box has no obstacle
OCTOVK_CONST uint kFieldStatusCut = 1u;        // a line's loop ended early (driver loop limit)
OCTOVK_CONST uint kFieldMaxAxisCells =
    16384u;  // squared distances and the passes' integers fit 31 bits
// The field's description on the device. 96 B.
struct FieldHeader {
  uint64_t occupancy;     // 8B (0)  address of uint[words_per_row * size_y * size_z]
  uint64_t line_x;        // 8B (8)  address of uint[cell count]
  uint64_t plane_xy;      // 8B (16) address of uint[cell count]
  uint64_t sites;         // 8B (24) address of uint[cell count]
  uint64_t envelope;      // 8B (32) address of uvec2[cell count]
  uint64_t dirty;         // 8B (40) address of the three dirty bitmaps
  uint min_key_x;         // 4B (48) key of cell (0, 0, 0)
  uint min_key_y;         // 4B (52)
  uint min_key_z;         // 4B (56)
  uint size_x;            // 4B (60) cells along each axis
  uint size_y;            // 4B (64)
  uint size_z;            // 4B (68)
  uint words_per_row;     // 4B (72) occupancy words per x-line: (size_x + 31) / 32
  uint unknown_occupied;  // 4B (76) 1: unknown cells count as occupied
  uint status;            // 4B (80) kFieldStatus* bits
  float max_distance_m;   // 4B (84) distances are capped here
  uint dirty_y;           // 4B (88) first word of the y-lines' dirty bitmap
  uint dirty_z;           // 4B (92) first word of the z-lines' dirty bitmap
};
// field_raster. 16 B.
struct FieldRasterConstants {
  uint64_t header;  // 8B (0)  device address of the FieldHeader
  uint word_count;  // 4B (8)  occupancy words of the box
  uint compare;     // 4B (12) 1: mark the x-lines whose words changed dirty (an update)
};
// field_changes. 16 B.
struct FieldChangesConstants {
  uint64_t header;  // 8B (0)  device address of the FieldHeader
  uint capacity;    // 4B (8)  slots of the change set
  uint pad0;        // 4B (12)
};
// field_nearest_x and field_edt. 16 B.
struct FieldEdtConstants {
  uint64_t header;  // 8B (0)  device address of the FieldHeader
  uint axis;        // 4B (8)  field_edt: 1 or 2, the lines run along y or z
  uint full;        // 4B (12) 1: every line (a build); 0: the dirty lines, marking the next axis's
};
// field_query. 16 B.
struct FieldQueryConstants {
  uint64_t header;   // 8B (0)  device address of the FieldHeader
  uint query_count;  // 4B (8)  spheres in the query input (4 floats each)
  uint pad0;         // 4B (12)
};

#ifdef __cplusplus
}  // namespace octovk::gpu
#undef OCTOVK_CONST
#endif

#endif  // OCTOVK_GPU_TYPES_H
