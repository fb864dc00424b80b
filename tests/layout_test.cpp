// Layout tests: the structs of gpu_types.h have the sizes and offsets their comments state (C++),
// and the GLSL side agrees: shaders/layout_probe.comp writes a marker into every field through
// the shared bindings, and each marker must land at the C++ offsetof.
#include <array>
#include <cstddef>
#include <cstdint>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <functional>
#include <initializer_list>
#include <iterator>
#include <regex>
#include <set>
#include <string>
#include <type_traits>
#include <utility>

#include "gpu/gpu_types.h"
#include "map/context_access.hpp"
#include "test_paths.hpp"
#include "test_support.hpp"
#include "vk/device.hpp"

namespace octovk {
namespace {

using namespace gpu;  // NOLINT(google-build-using-namespace): the test names every struct

// ---- C++ side: the byte offsets written in gpu_types.h's comments ------------------------------

static_assert(std::is_standard_layout_v<Node> && std::is_trivially_copyable_v<Node>);
static_assert(sizeof(Node) == 8);
static_assert(offsetof(Node, log_odds) == 0);
static_assert(offsetof(Node, link) == 4);
// The link's block field holds any block the pool can have (MapParams::max_nodes / 8 <= 2^29 - 1).
static_assert(kNoChildren == kBlockMask && (kBlockMask & (kFlagTouched | kFlagLive)) == 0);

static_assert(sizeof(LeafBox) == 20);
static_assert(offsetof(LeafBox, center_x) == 0);
static_assert(offsetof(LeafBox, center_y) == 4);
static_assert(offsetof(LeafBox, center_z) == 8);
static_assert(offsetof(LeafBox, size) == 12);
static_assert(offsetof(LeafBox, log_odds) == 16);

static_assert(sizeof(PoolState) == 32);
static_assert(offsetof(PoolState, bump) == 0);
static_assert(offsetof(PoolState, capacity) == 4);
static_assert(offsetof(PoolState, free_count) == 8);
static_assert(offsetof(PoolState, halted) == 12);
static_assert(offsetof(PoolState, root_exists) == 16);
static_assert(offsetof(PoolState, leaf_count) == 20);
static_assert(offsetof(PoolState, live_nodes) == 24);
static_assert(offsetof(PoolState, pad0) == 28);

static_assert(sizeof(ScanParams) == 120);
static_assert(offsetof(ScanParams, resolution) == 0);
static_assert(offsetof(ScanParams, resolution_factor) == 8);
static_assert(offsetof(ScanParams, max_range) == 16);
static_assert(offsetof(ScanParams, origin_x) == 24);
static_assert(offsetof(ScanParams, origin_y) == 28);
static_assert(offsetof(ScanParams, origin_z) == 32);
static_assert(offsetof(ScanParams, prob_hit_log) == 36);
static_assert(offsetof(ScanParams, prob_miss_log) == 40);
static_assert(offsetof(ScanParams, clamp_min_log) == 44);
static_assert(offsetof(ScanParams, clamp_max_log) == 48);
static_assert(offsetof(ScanParams, point_count) == 52);
static_assert(offsetof(ScanParams, hash_capacity) == 56);
static_assert(offsetof(ScanParams, hash_log2) == 60);
static_assert(offsetof(ScanParams, endpoint_capacity) == 64);
static_assert(offsetof(ScanParams, endpoint_log2) == 68);
static_assert(offsetof(ScanParams, rot_u) == 72);
static_assert(offsetof(ScanParams, rot_x) == 76);
static_assert(offsetof(ScanParams, rot_y) == 80);
static_assert(offsetof(ScanParams, rot_z) == 84);
static_assert(offsetof(ScanParams, active_capacity) == 88);
static_assert(offsetof(ScanParams, trans_x) == 92);
static_assert(offsetof(ScanParams, trans_y) == 96);
static_assert(offsetof(ScanParams, trans_z) == 100);
static_assert(offsetof(ScanParams, occupancy_log) == 104);
static_assert(offsetof(ScanParams, changes_log2) == 108);
static_assert(offsetof(ScanParams, cell_capacity) == 112);
static_assert(offsetof(ScanParams, pad0) == 116);

static_assert(sizeof(ChangeHeader) == 16);
static_assert(offsetof(ChangeHeader, used) == 0);
static_assert(offsetof(ChangeHeader, live) == 4);
static_assert(sizeof(ChangeSlot) == 16);
static_assert(offsetof(ChangeSlot, key) == 0);
static_assert(offsetof(ChangeSlot, state) == 8);
static_assert(sizeof(gpu::ChangedKey) == 16);
static_assert(offsetof(gpu::ChangedKey, created) == 12);
static_assert(sizeof(ChangedKeysHeader) == 16);
static_assert(sizeof(ListChangesConstants) == 16);
static_assert(sizeof(RehashChangesConstants) == 16);
static_assert(sizeof(KeepBoxConstants) == 16);

static_assert(sizeof(AccelHeader) == 64);
static_assert(offsetof(AccelHeader, tlas) == 0);
static_assert(offsetof(AccelHeader, box_count) == 8);
static_assert(offsetof(AccelHeader, box_capacity) == 12);
static_assert(offsetof(AccelHeader, lo_x) == 16);
static_assert(offsetof(AccelHeader, hi_x) == 28);
static_assert(offsetof(AccelHeader, bucket_bits) == 40);
static_assert(offsetof(AccelHeader, pad4) == 60);
// AccelBox is what the acceleration-structure build reads: VkAabbPositionsKHR.
static_assert(sizeof(AccelBox) == 24 && offsetof(AccelBox, min_x) == 0 &&
              offsetof(AccelBox, max_x) == 12 && offsetof(AccelBox, max_z) == 20);
static_assert(sizeof(AccelBoxesConstants) == 16 && offsetof(AccelBoxesConstants, boxes) == 0 &&
              offsetof(AccelBoxesConstants, mode) == 8);
static_assert(sizeof(CastRayRtConstants) == 16 && offsetof(CastRayRtConstants, boxes) == 0 &&
              offsetof(CastRayRtConstants, ray_count) == 8 &&
              offsetof(CastRayRtConstants, first_ray) == 12);
static_assert(kAccelBuckets % kAccelChunks == 0);
static_assert(sizeof(ScanRaysRtConstants) == 16 && offsetof(ScanRaysRtConstants, boxes) == 0 &&
              offsetof(ScanRaysRtConstants, point_count) == 8 &&
              offsetof(ScanRaysRtConstants, mode) == 12);

static_assert(sizeof(NewBlock) == 12);
// The distance field (src/field/, shaders/field_*.comp).
static_assert(sizeof(FieldHeader) == 96 && offsetof(FieldHeader, line_x) == 8 &&
              offsetof(FieldHeader, dirty) == 40 && offsetof(FieldHeader, min_key_x) == 48 &&
              offsetof(FieldHeader, size_x) == 60 && offsetof(FieldHeader, words_per_row) == 72 &&
              offsetof(FieldHeader, status) == 80 && offsetof(FieldHeader, max_distance_m) == 84 &&
              offsetof(FieldHeader, dirty_z) == 92);
static_assert(sizeof(FieldRasterConstants) == 16 &&
              offsetof(FieldRasterConstants, word_count) == 8 &&
              offsetof(FieldRasterConstants, compare) == 12);
static_assert(sizeof(FieldChangesConstants) == 16 &&
              offsetof(FieldChangesConstants, capacity) == 8);
static_assert(sizeof(FieldEdtConstants) == 16 && offsetof(FieldEdtConstants, axis) == 8 &&
              offsetof(FieldEdtConstants, full) == 12);
static_assert(sizeof(FieldQueryConstants) == 16 && offsetof(FieldQueryConstants, query_count) == 8);
static_assert(sizeof(DistanceResult) == 32 && offsetof(DistanceResult, obstacle_x) == 4 &&
              offsetof(DistanceResult, gradient_x) == 16 &&
              offsetof(DistanceResult, squared_cells) == 28);
static_assert(offsetof(NewBlock, node) == 0);
static_assert(offsetof(NewBlock, source) == 4);
static_assert(offsetof(NewBlock, block) == 8);

static_assert(sizeof(ActiveCell) == 16);
static_assert(offsetof(ActiveCell, slot) == 0);
static_assert(offsetof(ActiveCell, node) == 4);
static_assert(offsetof(ActiveCell, parent) == 8);
static_assert(offsetof(ActiveCell, depth) == 12);

// VkDispatchIndirectCommand is three uint32 x, y, z.
static_assert(sizeof(DispatchArgs) == 12);
static_assert(offsetof(DispatchArgs, x) == 0);
static_assert(offsetof(DispatchArgs, y) == 4);
static_assert(offsetof(DispatchArgs, z) == 8);
static_assert(sizeof(DispatchArgs) == sizeof(VkDispatchIndirectCommand));

static_assert(kLevelCount == 17);
static_assert(sizeof(ScanCounters) == 420);
static_assert(offsetof(ScanCounters, status) == 0);
static_assert(offsetof(ScanCounters, brick_entries) == 4);
static_assert(offsetof(ScanCounters, endpoint_entries) == 8);
static_assert(offsetof(ScanCounters, active_cells) == 12);
static_assert(offsetof(ScanCounters, skipped_nonfinite) == 16);
static_assert(offsetof(ScanCounters, skipped_outside) == 20);
static_assert(offsetof(ScanCounters, occupied_cells) == 24);
static_assert(offsetof(ScanCounters, free_cells) == 28);
static_assert(offsetof(ScanCounters, aborted) == 32);
static_assert(offsetof(ScanCounters, new_blocks) == 36);
static_assert(offsetof(ScanCounters, cell_entries) == 40);
static_assert(offsetof(ScanCounters, query_results) == 44);
static_assert(offsetof(ScanCounters, leaf_cells) == 48);
static_assert(offsetof(ScanCounters, touched_count) == 52);
static_assert(offsetof(ScanCounters, touched_args) == 120);
static_assert(offsetof(ScanCounters, walk_count) == 324);
static_assert(offsetof(ScanCounters, walk_args) == 332);
static_assert(offsetof(ScanCounters, cell_args) == 356);
static_assert(offsetof(ScanCounters, brick_args) == 368);
static_assert(offsetof(ScanCounters, no_depth) == 380);
static_assert(offsetof(ScanCounters, block_args) == 384);
static_assert(offsetof(ScanCounters, active_args) == 396);
static_assert(offsetof(ScanCounters, clear_args) == 408);
static_assert(offsetof(ScanCounters, clear_args) + sizeof(DispatchArgs) == sizeof(ScanCounters));
static_assert(offsetof(ScanCounters, block_args) % 4 == 0);

static_assert(sizeof(DepthCamera) == 32);
static_assert(offsetof(DepthCamera, fx) == 0);
static_assert(offsetof(DepthCamera, fy) == 4);
static_assert(offsetof(DepthCamera, cx) == 8);
static_assert(offsetof(DepthCamera, cy) == 12);
static_assert(offsetof(DepthCamera, depth_scale) == 16);
static_assert(offsetof(DepthCamera, width) == 20);
static_assert(offsetof(DepthCamera, height) == 24);
static_assert(offsetof(DepthCamera, encoding) == 28);
// The host reads ScanCounters and PoolState back in one buffer, the PoolState right after.
static_assert(sizeof(ScanCounters) % alignof(PoolState) == 0);
// Indirect dispatch arguments must be 4-byte aligned inside the buffer.
static_assert(offsetof(ScanCounters, touched_args) % 4 == 0);
static_assert(offsetof(ScanCounters, walk_args) % 4 == 0);
static_assert(offsetof(ScanCounters, cell_args) % 4 == 0);
static_assert(offsetof(ScanCounters, brick_args) % 4 == 0);

static_assert(sizeof(LookupResult) == 16);
static_assert(offsetof(LookupResult, state) == 0);
static_assert(offsetof(LookupResult, log_odds) == 4);
static_assert(offsetof(LookupResult, depth) == 8);
static_assert(offsetof(LookupResult, pad0) == 12);

static_assert(sizeof(RayQuery) == 40);
static_assert(offsetof(RayQuery, max_range) == 0);
static_assert(offsetof(RayQuery, origin_x) == 8);
static_assert(offsetof(RayQuery, origin_y) == 12);
static_assert(offsetof(RayQuery, origin_z) == 16);
static_assert(offsetof(RayQuery, direction_x) == 20);
static_assert(offsetof(RayQuery, direction_y) == 24);
static_assert(offsetof(RayQuery, direction_z) == 28);
static_assert(offsetof(RayQuery, ignore_unknown) == 32);
static_assert(offsetof(RayQuery, pad0) == 36);

static_assert(sizeof(RayResult) == 16);
static_assert(offsetof(RayResult, hit) == 0);
static_assert(offsetof(RayResult, end_x) == 4);
static_assert(offsetof(RayResult, end_y) == 8);
static_assert(offsetof(RayResult, end_z) == 12);

static_assert(sizeof(WalkState) == 48);
static_assert(offsetof(WalkState, t_max_x) == 0);
static_assert(offsetof(WalkState, t_max_y) == 8);
static_assert(offsetof(WalkState, t_max_z) == 16);
static_assert(offsetof(WalkState, end_x) == 24);
static_assert(offsetof(WalkState, end_y) == 28);
static_assert(offsetof(WalkState, end_z) == 32);
static_assert(offsetof(WalkState, key_xy) == 36);
static_assert(offsetof(WalkState, key_z) == 40);
static_assert(offsetof(WalkState, pad0) == 44);

static_assert(sizeof(RayState) == 48);
static_assert(offsetof(RayState, t_max_x) == 0);
static_assert(offsetof(RayState, t_max_y) == 8);
static_assert(offsetof(RayState, t_max_z) == 16);
static_assert(offsetof(RayState, key_x) == 24);
static_assert(offsetof(RayState, key_y) == 28);
static_assert(offsetof(RayState, key_z) == 32);
static_assert(offsetof(RayState, done) == 36);
static_assert(offsetof(RayState, unfinished) == 40);
static_assert(sizeof(RayState::unfinished) == 8);

static_assert(sizeof(BoxQuery) == 32);
static_assert(offsetof(BoxQuery, min_x) == 0);
static_assert(offsetof(BoxQuery, min_y) == 4);
static_assert(offsetof(BoxQuery, min_z) == 8);
static_assert(offsetof(BoxQuery, max_x) == 12);
static_assert(offsetof(BoxQuery, max_y) == 16);
static_assert(offsetof(BoxQuery, max_z) == 20);
static_assert(offsetof(BoxQuery, occupied_only) == 24);
static_assert(offsetof(BoxQuery, pad0) == 28);

// Push constants: the pipeline layout's 16-byte range, and each pass's view of it.
static_assert(sizeof(PassConstants) == 16);
static_assert(offsetof(PassConstants, words) == 0);

static_assert(sizeof(NoConstants) == 16);
static_assert(offsetof(NoConstants, pad0) == 0);
static_assert(offsetof(NoConstants, pad1) == 4);
static_assert(offsetof(NoConstants, pad2) == 8);
static_assert(offsetof(NoConstants, pad3) == 12);

static_assert(sizeof(ClearSetsConstants) == 16);
static_assert(offsetof(ClearSetsConstants, mode) == 0);
static_assert(offsetof(ClearSetsConstants, pad0) == 4);
static_assert(offsetof(ClearSetsConstants, pad1) == 8);
static_assert(offsetof(ClearSetsConstants, pad2) == 12);

static_assert(sizeof(TransformPointsConstants) == 16);
static_assert(offsetof(TransformPointsConstants, point_count) == 0);
static_assert(offsetof(TransformPointsConstants, pad0) == 4);
static_assert(offsetof(TransformPointsConstants, pad1) == 8);
static_assert(offsetof(TransformPointsConstants, pad2) == 12);

static_assert(sizeof(DiscretizeConstants) == 16);
static_assert(offsetof(DiscretizeConstants, point_count) == 0);
static_assert(offsetof(DiscretizeConstants, pad0) == 4);
static_assert(offsetof(DiscretizeConstants, pad1) == 8);
static_assert(offsetof(DiscretizeConstants, pad2) == 12);

static_assert(sizeof(RayKeysConstants) == 16);
static_assert(offsetof(RayKeysConstants, budget) == 0);
static_assert(offsetof(RayKeysConstants, point_count) == 4);
static_assert(offsetof(RayKeysConstants, mode) == 8);
static_assert(offsetof(RayKeysConstants, from_list) == 12);

static_assert(sizeof(UnprojectConstants) == 16);
static_assert(offsetof(UnprojectConstants, pixel_count) == 0);
static_assert(offsetof(UnprojectConstants, pad0) == 4);
static_assert(offsetof(UnprojectConstants, pad1) == 8);
static_assert(offsetof(UnprojectConstants, pad2) == 12);

static_assert(sizeof(PruneConstants) == 16);
static_assert(offsetof(PruneConstants, level) == 0);
static_assert(offsetof(PruneConstants, pad0) == 4);
static_assert(offsetof(PruneConstants, pad1) == 8);
static_assert(offsetof(PruneConstants, pad2) == 12);

static_assert(sizeof(LeafBoxesConstants) == 16);
static_assert(offsetof(LeafBoxesConstants, mode) == 0);
static_assert(offsetof(LeafBoxesConstants, pad0) == 4);
static_assert(offsetof(LeafBoxesConstants, pad1) == 8);
static_assert(offsetof(LeafBoxesConstants, pad2) == 12);

static_assert(sizeof(LookupConstants) == 16);
static_assert(offsetof(LookupConstants, point_count) == 0);
static_assert(offsetof(LookupConstants, first_float) == 4);
static_assert(offsetof(LookupConstants, first_result) == 8);
static_assert(offsetof(LookupConstants, pad0) == 12);

static_assert(sizeof(CastRayConstants) == 16);
static_assert(offsetof(CastRayConstants, budget) == 0);
static_assert(offsetof(CastRayConstants, ray_count) == 4);
static_assert(offsetof(CastRayConstants, resume) == 8);
static_assert(offsetof(CastRayConstants, first_state) == 12);

static_assert(sizeof(DeviceProbeConstants) == 16);
static_assert(offsetof(DeviceProbeConstants, mode) == 0);
static_assert(offsetof(DeviceProbeConstants, case_count) == 4);
static_assert(offsetof(DeviceProbeConstants, loop_iterations) == 8);
static_assert(offsetof(DeviceProbeConstants, pad0) == 12);

// The public mirrors of device structs that are copied byte for byte.
static_assert(sizeof(OccupancyMap::LeafBoxHost) == sizeof(LeafBox));
static_assert(offsetof(OccupancyMap::LeafBoxHost, center) == offsetof(LeafBox, center_x));
static_assert(offsetof(OccupancyMap::LeafBoxHost, size) == offsetof(LeafBox, size));
static_assert(offsetof(OccupancyMap::LeafBoxHost, log_odds) == offsetof(LeafBox, log_odds));

static_assert(kBindingCount == 21);
static_assert(kBindParams == 0 && kBindCounters == 1 && kBindPool == 2 && kBindPoints == 3 &&
              kBindCellSetKeys == 4 && kBindCellSetFlags == 5 && kBindNodes == 6 &&
              kBindBlockParents == 7 && kBindFreeStack == 8 && kBindActive == 9 &&
              kBindTouched == 10 && kBindNewBlocks == 11 && kBindLeafBoxes == 12 &&
              kBindEndpointKeys == 13 && kBindQueryIn == 14 && kBindQueryOut == 15 &&
              kBindWalks == 16 && kBindSlots == 17 && kBindCellList == 18 && kBindDepth == 19 &&
              kBindChanges == 20 && kBindAddresses == 21);

TEST(Layout, HostSizesAndOffsets) {
  // The static_asserts above hold at compile time; the same facts at run time, for the report.
  EXPECT_EQ(sizeof(Node), 8u);
  EXPECT_EQ(sizeof(LeafBox), 20u);
  EXPECT_EQ(sizeof(PoolState), 32u);
  EXPECT_EQ(sizeof(ScanParams), 120u);
  EXPECT_EQ(sizeof(ActiveCell), 16u);
  EXPECT_EQ(sizeof(NewBlock), 12u);
  EXPECT_EQ(sizeof(DispatchArgs), 12u);
  EXPECT_EQ(sizeof(ScanCounters), 420u);
  EXPECT_EQ(sizeof(DepthCamera), 32u);
  EXPECT_EQ(sizeof(WalkState), 48u);
  EXPECT_EQ(sizeof(PassConstants), 16u);
  EXPECT_EQ(sizeof(LookupResult), 16u);
  EXPECT_EQ(sizeof(RayQuery), 40u);
  EXPECT_EQ(sizeof(RayResult), 16u);
  EXPECT_EQ(sizeof(BoxQuery), 32u);
  EXPECT_EQ(sizeof(RayState), 48u);
  EXPECT_EQ(offsetof(ScanCounters, clear_args) + sizeof(DispatchArgs), sizeof(ScanCounters));
  EXPECT_EQ(offsetof(ScanParams, pad0) + 4, sizeof(ScanParams));
}

// ---- GLSL side: run the probe shader and find each marker --------------------------------------

enum class Kind { kUint, kFloat, kDouble, kUint64 };

struct Field {
  std::string name;
  std::uint32_t binding;
  std::size_t offset;
  Kind kind;
  std::uint32_t id;
};

// The probe's markers (shaders/layout_probe.comp).
std::uint32_t markerUint(std::uint32_t id) { return 0xC0DE0000u + id; }
float markerFloat(std::uint32_t id) { return static_cast<float>(id) + 0.5f; }
double markerDouble(std::uint32_t id) { return static_cast<double>(id) + 0.25; }
std::uint64_t markerUint64(std::uint32_t id) { return 0xC0DE0000C0DE0000ull + id; }

// A member of a struct the probe writes: its name, offset and kind.
struct Member {
  const char* name;
  std::size_t offset;
  Kind kind;
};
#define OCTOVK_MEMBER(Struct, member, kind) \
  Member { #member, offsetof(Struct, member), kind }

// The members of a struct (`name`) at byte `at` of `binding`, markers id, id + 1, ... in the
// table's order: one table per struct, the probe's marker ids following it.
void addStruct(std::vector<Field>& f, const std::string& name, std::uint32_t binding,
               std::size_t at, std::uint32_t id, std::initializer_list<Member> members) {
  for (const Member& m : members) {
    std::string field_name = name;
    field_name += "::";
    field_name += m.name;
    f.push_back({field_name, binding, at + m.offset, m.kind, id++});
  }
}

// "[i]", built without operator+ on a literal (GCC 12 warns falsely on that).
std::string subscript(std::uint32_t i) {
  std::string s = "[";
  s += std::to_string(i);
  s += ']';
  return s;
}

// The x, y, z fields of the DispatchArgs called `name` at `offset` in ScanCounters, markers
// id, id + 1, id + 2.
void addDispatchArgs(std::vector<Field>& f, const std::string& name, std::size_t offset,
                     std::uint32_t id) {
  f.push_back({"ScanCounters::" + name + ".x", kBindCounters, offset + offsetof(DispatchArgs, x),
               Kind::kUint, id});
  f.push_back({"ScanCounters::" + name + ".y", kBindCounters, offset + offsetof(DispatchArgs, y),
               Kind::kUint, id + 1});
  f.push_back({"ScanCounters::" + name + ".z", kBindCounters, offset + offsetof(DispatchArgs, z),
               Kind::kUint, id + 2});
}

// Push-constant structs the probe writes out (NoConstants and one per pass that takes constants).
constexpr std::uint32_t kProbedConstants = 11;

// The four fields of a push-constant struct (`name`) that the probe's query output holds at `at`,
// markers id .. id + 3.
void addConstants(std::vector<Field>& f, const char* name, std::size_t at, std::uint32_t id,
                  const std::array<std::pair<const char*, std::size_t>, 4>& fields) {
  for (std::uint32_t i = 0; i < 4; ++i) {
    std::string field_name = name;
    field_name += "::";
    field_name += fields[i].first;
    f.push_back({field_name, kBindQueryOut, at + fields[i].second, Kind::kUint, id + i});
  }
}
// Push-constant struct number `index` (in gpu_types.h's order) of the probe's query output.
#define OCTOVK_CONSTANTS(f, at, index, Struct, a, b, c, d)                       \
  static_assert(sizeof(Struct) == sizeof(PassConstants));                        \
  addConstants(f, #Struct, (at) + (index) * sizeof(Struct), 1100 + 10 * (index), \
               {{{#a, offsetof(Struct, a)},                                      \
                 {#b, offsetof(Struct, b)},                                      \
                 {#c, offsetof(Struct, c)},                                      \
                 {#d, offsetof(Struct, d)}}})

std::vector<Field> probedFields() {
  constexpr Kind U = Kind::kUint, F = Kind::kFloat, D = Kind::kDouble, U64 = Kind::kUint64;
  std::vector<Field> f;
  addStruct(
      f, "ScanParams", kBindParams, 0, 100,
      {OCTOVK_MEMBER(ScanParams, resolution, D),    OCTOVK_MEMBER(ScanParams, resolution_factor, D),
       OCTOVK_MEMBER(ScanParams, max_range, D),     OCTOVK_MEMBER(ScanParams, origin_x, F),
       OCTOVK_MEMBER(ScanParams, origin_y, F),      OCTOVK_MEMBER(ScanParams, origin_z, F),
       OCTOVK_MEMBER(ScanParams, prob_hit_log, F),  OCTOVK_MEMBER(ScanParams, prob_miss_log, F),
       OCTOVK_MEMBER(ScanParams, clamp_min_log, F), OCTOVK_MEMBER(ScanParams, clamp_max_log, F),
       OCTOVK_MEMBER(ScanParams, point_count, U),   OCTOVK_MEMBER(ScanParams, hash_capacity, U),
       OCTOVK_MEMBER(ScanParams, hash_log2, U),     OCTOVK_MEMBER(ScanParams, endpoint_capacity, U),
       OCTOVK_MEMBER(ScanParams, endpoint_log2, U), OCTOVK_MEMBER(ScanParams, rot_u, F),
       OCTOVK_MEMBER(ScanParams, rot_x, F),         OCTOVK_MEMBER(ScanParams, rot_y, F),
       OCTOVK_MEMBER(ScanParams, rot_z, F),         OCTOVK_MEMBER(ScanParams, active_capacity, U),
       OCTOVK_MEMBER(ScanParams, trans_x, F),       OCTOVK_MEMBER(ScanParams, trans_y, F),
       OCTOVK_MEMBER(ScanParams, trans_z, F),       OCTOVK_MEMBER(ScanParams, occupancy_log, F),
       OCTOVK_MEMBER(ScanParams, changes_log2, U),  OCTOVK_MEMBER(ScanParams, cell_capacity, U),
       OCTOVK_MEMBER(ScanParams, pad0, U)});
  addStruct(
      f, "ScanCounters", kBindCounters, 0, 200,
      {OCTOVK_MEMBER(ScanCounters, status, U), OCTOVK_MEMBER(ScanCounters, brick_entries, U),
       OCTOVK_MEMBER(ScanCounters, endpoint_entries, U),
       OCTOVK_MEMBER(ScanCounters, active_cells, U),
       OCTOVK_MEMBER(ScanCounters, skipped_nonfinite, U),
       OCTOVK_MEMBER(ScanCounters, skipped_outside, U),
       OCTOVK_MEMBER(ScanCounters, occupied_cells, U), OCTOVK_MEMBER(ScanCounters, free_cells, U),
       OCTOVK_MEMBER(ScanCounters, aborted, U), OCTOVK_MEMBER(ScanCounters, new_blocks, U),
       OCTOVK_MEMBER(ScanCounters, cell_entries, U), OCTOVK_MEMBER(ScanCounters, query_results, U),
       OCTOVK_MEMBER(ScanCounters, leaf_cells, U), OCTOVK_MEMBER(ScanCounters, no_depth, U)});
  addStruct(f, "DepthCamera", kBindDepth, 0, 810,
            {OCTOVK_MEMBER(DepthCamera, fx, F), OCTOVK_MEMBER(DepthCamera, fy, F),
             OCTOVK_MEMBER(DepthCamera, cx, F), OCTOVK_MEMBER(DepthCamera, cy, F),
             OCTOVK_MEMBER(DepthCamera, depth_scale, F), OCTOVK_MEMBER(DepthCamera, width, U),
             OCTOVK_MEMBER(DepthCamera, height, U), OCTOVK_MEMBER(DepthCamera, encoding, U),
             Member{"words[0]", sizeof(DepthCamera), U}});
  addStruct(f, "PoolState", kBindPool, 0, 600,
            {OCTOVK_MEMBER(PoolState, bump, U), OCTOVK_MEMBER(PoolState, capacity, U),
             OCTOVK_MEMBER(PoolState, free_count, U), OCTOVK_MEMBER(PoolState, halted, U),
             OCTOVK_MEMBER(PoolState, root_exists, U), OCTOVK_MEMBER(PoolState, leaf_count, U),
             OCTOVK_MEMBER(PoolState, live_nodes, U), OCTOVK_MEMBER(PoolState, pad0, U)});
  // Two elements of each array of structs.
  for (std::uint32_t e = 0; e < 2; ++e) {
    const std::string at = subscript(e);
    addStruct(f, "Node" + at, kBindNodes, e * sizeof(Node), 700 + 5 * e,
              {OCTOVK_MEMBER(Node, log_odds, F), OCTOVK_MEMBER(Node, link, U)});
    addStruct(f, "ActiveCell" + at, kBindActive, e * sizeof(ActiveCell), 720 + 5 * e,
              {OCTOVK_MEMBER(ActiveCell, slot, U), OCTOVK_MEMBER(ActiveCell, node, U),
               OCTOVK_MEMBER(ActiveCell, parent, U), OCTOVK_MEMBER(ActiveCell, depth, U)});
    addStruct(f, "NewBlock" + at, kBindNewBlocks, e * sizeof(NewBlock), 730 + 5 * e,
              {OCTOVK_MEMBER(NewBlock, node, U), OCTOVK_MEMBER(NewBlock, source, U),
               OCTOVK_MEMBER(NewBlock, block, U)});
    addStruct(f, "LeafBox" + at, kBindLeafBoxes, e * sizeof(LeafBox), 740 + 10 * e,
              {OCTOVK_MEMBER(LeafBox, center_x, F), OCTOVK_MEMBER(LeafBox, center_y, F),
               OCTOVK_MEMBER(LeafBox, center_z, F), OCTOVK_MEMBER(LeafBox, size, F),
               OCTOVK_MEMBER(LeafBox, log_odds, F)});
  }
  // Element 1 of each plain array.
  f.push_back({"points[1]", kBindPoints, 1 * sizeof(float), F, 800});
  f.push_back({"cell_set_keys[1]", kBindCellSetKeys, 1 * sizeof(std::uint64_t), U64, 801});
  f.push_back({"cell_set_flags[1]", kBindCellSetFlags, 1 * sizeof(std::uint32_t), U, 802});
  f.push_back({"free_stack[1]", kBindFreeStack, 1 * sizeof(std::uint32_t), U, 803});
  f.push_back({"endpoint_keys[1]", kBindEndpointKeys, 1 * sizeof(std::uint64_t), U64, 804});
  f.push_back({"slots[1]", kBindSlots, 1 * sizeof(std::uint32_t), U, 805});
  f.push_back({"cell_list[1]", kBindCellList, 1 * sizeof(std::uint32_t), U, 806});
  f.push_back({"block_parent[1]", kBindBlockParents, 1 * sizeof(std::uint32_t), U, 807});
  addDispatchArgs(f, "cell_args", offsetof(ScanCounters, cell_args), 390);
  addDispatchArgs(f, "brick_args", offsetof(ScanCounters, brick_args), 393);
  addDispatchArgs(f, "block_args", offsetof(ScanCounters, block_args), 396);
  addDispatchArgs(f, "clear_args", offsetof(ScanCounters, clear_args), 216);
  f.push_back(
      {"ScanCounters::active_args.x", kBindCounters, offsetof(ScanCounters, active_args), U, 399});
  f.push_back({"ScanCounters::active_args.y", kBindCounters,
               offsetof(ScanCounters, active_args) + 4, U, 214});
  f.push_back({"ScanCounters::active_args.z", kBindCounters,
               offsetof(ScanCounters, active_args) + 8, U, 215});
  for (std::uint32_t w = 0; w < 2; ++w) {
    const std::string at = subscript(w);
    f.push_back({"ScanCounters::walk_count" + at, kBindCounters,
                 offsetof(ScanCounters, walk_count) + w * sizeof(std::uint32_t), U, 370 + w});
    addDispatchArgs(f, "walk_args" + at,
                    offsetof(ScanCounters, walk_args) + w * sizeof(DispatchArgs), 380 + 3 * w);
    addStruct(f, "WalkState" + at, kBindWalks, w * sizeof(WalkState), 1000 + 10 * w,
              {OCTOVK_MEMBER(WalkState, t_max_x, D), OCTOVK_MEMBER(WalkState, t_max_y, D),
               OCTOVK_MEMBER(WalkState, t_max_z, D), OCTOVK_MEMBER(WalkState, end_x, F),
               OCTOVK_MEMBER(WalkState, end_y, F), OCTOVK_MEMBER(WalkState, end_z, F),
               OCTOVK_MEMBER(WalkState, key_xy, U), OCTOVK_MEMBER(WalkState, key_z, U),
               OCTOVK_MEMBER(WalkState, pad0, U)});
  }

  // The probe's views of the query bindings: RayQuery[2], BoxQuery, RayState[2]; LookupResult[2]
  // then RayResult[2].
  const std::size_t box_at = 2 * sizeof(RayQuery);
  const std::size_t states_at = box_at + sizeof(BoxQuery);
  const std::size_t ray_results_at = 2 * sizeof(LookupResult);
  for (std::uint32_t e = 0; e < 2; ++e) {
    const std::string at = subscript(e);
    addStruct(f, "RayQuery" + at, kBindQueryIn, e * sizeof(RayQuery), 900 + 10 * e,
              {OCTOVK_MEMBER(RayQuery, max_range, D), OCTOVK_MEMBER(RayQuery, origin_x, F),
               OCTOVK_MEMBER(RayQuery, origin_y, F), OCTOVK_MEMBER(RayQuery, origin_z, F),
               OCTOVK_MEMBER(RayQuery, direction_x, F), OCTOVK_MEMBER(RayQuery, direction_y, F),
               OCTOVK_MEMBER(RayQuery, direction_z, F), OCTOVK_MEMBER(RayQuery, ignore_unknown, U),
               OCTOVK_MEMBER(RayQuery, pad0, U)});
    addStruct(f, "RayState" + at, kBindQueryIn, states_at + e * sizeof(RayState), 960 + 10 * e,
              {OCTOVK_MEMBER(RayState, t_max_x, D), OCTOVK_MEMBER(RayState, t_max_y, D),
               OCTOVK_MEMBER(RayState, t_max_z, D), OCTOVK_MEMBER(RayState, key_x, U),
               OCTOVK_MEMBER(RayState, key_y, U), OCTOVK_MEMBER(RayState, key_z, U),
               OCTOVK_MEMBER(RayState, done, U),
               Member{"unfinished[0]", offsetof(RayState, unfinished), U},
               Member{"unfinished[1]", offsetof(RayState, unfinished) + sizeof(std::uint32_t), U}});
    addStruct(f, "LookupResult" + at, kBindQueryOut, e * sizeof(LookupResult), 930 + 5 * e,
              {OCTOVK_MEMBER(LookupResult, state, U), OCTOVK_MEMBER(LookupResult, log_odds, F),
               OCTOVK_MEMBER(LookupResult, depth, U), OCTOVK_MEMBER(LookupResult, pad0, U)});
    addStruct(f, "RayResult" + at, kBindQueryOut, ray_results_at + e * sizeof(RayResult),
              940 + 5 * e,
              {OCTOVK_MEMBER(RayResult, hit, U), OCTOVK_MEMBER(RayResult, end_x, F),
               OCTOVK_MEMBER(RayResult, end_y, F), OCTOVK_MEMBER(RayResult, end_z, F)});
  }
  addStruct(f, "BoxQuery", kBindQueryIn, box_at, 920,
            {OCTOVK_MEMBER(BoxQuery, min_x, U), OCTOVK_MEMBER(BoxQuery, min_y, U),
             OCTOVK_MEMBER(BoxQuery, min_z, U), OCTOVK_MEMBER(BoxQuery, max_x, U),
             OCTOVK_MEMBER(BoxQuery, max_y, U), OCTOVK_MEMBER(BoxQuery, max_z, U),
             OCTOVK_MEMBER(BoxQuery, occupied_only, U), OCTOVK_MEMBER(BoxQuery, pad0, U)});

  // Every pass's push-constant struct, after the RayResults in the probe's output view.
  const std::size_t constants_at = ray_results_at + 2 * sizeof(RayResult);
  OCTOVK_CONSTANTS(f, constants_at, 0, NoConstants, pad0, pad1, pad2, pad3);
  OCTOVK_CONSTANTS(f, constants_at, 1, ClearSetsConstants, mode, pad0, pad1, pad2);
  OCTOVK_CONSTANTS(f, constants_at, 2, TransformPointsConstants, point_count, pad0, pad1, pad2);
  OCTOVK_CONSTANTS(f, constants_at, 3, DiscretizeConstants, point_count, pad0, pad1, pad2);
  OCTOVK_CONSTANTS(f, constants_at, 4, RayKeysConstants, budget, point_count, mode, from_list);
  OCTOVK_CONSTANTS(f, constants_at, 5, UnprojectConstants, pixel_count, pad0, pad1, pad2);
  OCTOVK_CONSTANTS(f, constants_at, 6, PruneConstants, level, pad0, pad1, pad2);
  OCTOVK_CONSTANTS(f, constants_at, 7, LeafBoxesConstants, mode, pad0, pad1, pad2);
  OCTOVK_CONSTANTS(f, constants_at, 8, LookupConstants, point_count, first_float, first_result,
                   pad0);
  OCTOVK_CONSTANTS(f, constants_at, 9, CastRayConstants, budget, ray_count, resume, first_state);
  OCTOVK_CONSTANTS(f, constants_at, 10, DeviceProbeConstants, mode, case_count, loop_iterations,
                   pad0);

  for (std::uint32_t l = 0; l < kLevelCount; ++l) {
    const std::string at = subscript(l);
    const std::size_t u = sizeof(std::uint32_t);
    f.push_back({"ScanCounters::touched_count" + at, kBindCounters,
                 offsetof(ScanCounters, touched_count) + l * u, U, 340 + l});
    addDispatchArgs(f, "touched_args" + at,
                    offsetof(ScanCounters, touched_args) + l * sizeof(DispatchArgs), 500 + 3 * l);
  }
  return f;
}

// Where, if anywhere, a marker landed in the buffer (to say how an offset is off).
std::string findMarker(const unsigned char* bytes, std::size_t size, const void* marker,
                       std::size_t marker_size) {
  for (std::size_t at = 0; at + marker_size <= size; at += 4)
    if (std::memcmp(bytes + at, marker, marker_size) == 0)
      return "found at byte " + std::to_string(at);
  return "not found in the buffer";
}

TEST(Layout, ShaderWritesEveryFieldAtTheHostOffset) {
  OCTOVK_REQUIRE_CONTEXT(ctx);
  vk::Device& device = ContextAccess::device(ctx);
  const vk::Pass& probe = device.pass("layout_probe");
  ASSERT_NE(probe.pipeline, VK_NULL_HANDLE);

  // Single structs get exactly their size; arrays four elements.
  std::array<std::size_t, kBindingCount> sizes{};
  sizes[kBindParams] = sizeof(ScanParams);
  sizes[kBindCounters] = sizeof(ScanCounters);
  sizes[kBindPool] = sizeof(PoolState);
  sizes[kBindPoints] = 4 * sizeof(float);
  sizes[kBindCellSetKeys] = 4 * sizeof(std::uint64_t);
  sizes[kBindCellSetFlags] = 4 * sizeof(std::uint32_t);
  sizes[kBindNodes] = 4 * sizeof(Node);
  sizes[kBindBlockParents] = 4 * sizeof(std::uint32_t);
  sizes[kBindFreeStack] = 4 * sizeof(std::uint32_t);
  sizes[kBindActive] = 4 * sizeof(ActiveCell);
  sizes[kBindTouched] = 8 * sizeof(std::uint32_t);
  sizes[kBindNewBlocks] = 4 * sizeof(NewBlock);
  sizes[kBindLeafBoxes] = 4 * sizeof(LeafBox);
  sizes[kBindEndpointKeys] = 4 * sizeof(std::uint64_t);
  sizes[kBindQueryIn] = 2 * sizeof(RayQuery) + sizeof(BoxQuery) + 2 * sizeof(RayState);
  sizes[kBindQueryOut] =
      2 * sizeof(LookupResult) + 2 * sizeof(RayResult) + kProbedConstants * sizeof(PassConstants);
  sizes[kBindWalks] = 2 * sizeof(WalkState);
  sizes[kBindSlots] = 4 * sizeof(std::uint32_t);
  sizes[kBindCellList] = 4 * sizeof(std::uint32_t);
  sizes[kBindDepth] = sizeof(DepthCamera) + 4 * sizeof(std::uint32_t);
  sizes[kBindChanges] = sizeof(ChangeHeader) + 4 * sizeof(ChangeSlot);

  std::vector<vk::Buffer> buffers;
  buffers.reserve(kBindingCount);
  std::array<const vk::Buffer*, kBindingCount> bound{};
  for (std::uint32_t b = 0; b < kBindingCount; ++b) {
    buffers.emplace_back(device, sizes[b], /*host_visible=*/true);
    std::memset(buffers[b].mapped(), 0xFF, buffers[b].size());
    bound[b] = &buffers[b];
  }
  vk::BindingSet bindings(device);
  bindings.update(bound);

  // The probe's push block is a RayKeysConstants.
  const RayKeysConstants pc{0x11111111u, 0x22222222u, 0x33333333u, 0x44444444u};
  vk::CommandStream stream(device);
  stream.begin(bindings);
  stream.dispatch(probe, 1, &pc, sizeof(pc));
  stream.barrier();
  stream.submitAndWait();

  const std::vector<Field> fields = probedFields();
  EXPECT_EQ(fields.size(), 25u + 13u + 8u + 28u + 5u + 2u * (9u + 9u + 4u + 4u) + 8u +
                               2u * (4u + 9u) + 4u * kLevelCount + 1u /* slots */ +
                               3u /* cell_args */ + 2u /* ScanParams */ +
                               5u /* brick_args, cell_list, block_parent */ + 1u /* no_depth */ +
                               9u /* DepthCamera, its first word */ +
                               9u /* block_args, active_args, clear_args */ +
                               4u * kProbedConstants /* push-constant structs */);
  for (const Field& f : fields) {
    const auto* bytes = static_cast<const unsigned char*>(buffers[f.binding].mapped());
    const std::size_t size = buffers[f.binding].size();
    unsigned char expected[8];
    std::size_t n = 4;
    switch (f.kind) {
      case Kind::kUint: {
        const std::uint32_t m = markerUint(f.id);
        std::memcpy(expected, &m, 4);
        break;
      }
      case Kind::kFloat: {
        const float m = markerFloat(f.id);
        std::memcpy(expected, &m, 4);
        break;
      }
      case Kind::kDouble: {
        const double m = markerDouble(f.id);
        std::memcpy(expected, &m, 8);
        n = 8;
        break;
      }
      case Kind::kUint64: {
        const std::uint64_t m = markerUint64(f.id);
        std::memcpy(expected, &m, 8);
        n = 8;
        break;
      }
    }
    ASSERT_LE(f.offset + n, size) << f.name;
    EXPECT_EQ(std::memcmp(bytes + f.offset, expected, n), 0)
        << f.name << ": the shader's marker is not at the C++ offset " << f.offset << " ("
        << findMarker(bytes, size, expected, n) << ")";
  }

  // Every byte of the single-struct buffers was written: the GLSL structs have no field the C++
  // side lacks, nor padding the C++ side does not name.
  for (std::uint32_t b :
       {kBindParams, kBindCounters, kBindPool, kBindQueryIn, kBindQueryOut, kBindWalks}) {
    const auto* bytes = static_cast<const unsigned char*>(buffers[b].mapped());
    for (std::size_t at = 0; at + 4 <= sizes[b]; at += 4) {
      std::uint32_t word;
      std::memcpy(&word, bytes + at, 4);
      EXPECT_NE(word, 0xFFFFFFFFu) << "binding " << b << ": byte " << at << " never written";
    }
  }

  // Push constants as the shader saw them (the four words in order), and the constants it shares
  // with the host.
  const auto* touched = static_cast<const std::uint32_t*>(buffers[kBindTouched].mapped());
  EXPECT_EQ(touched[0], pc.budget);
  EXPECT_EQ(touched[1], pc.point_count);
  EXPECT_EQ(touched[2], pc.mode);
  EXPECT_EQ(touched[3], pc.from_list);
  EXPECT_EQ(touched[4], kWorkgroupSize) << "the shaders' local size differs from kWorkgroupSize";
  EXPECT_EQ(touched[5], kLevelCount);
  EXPECT_EQ(touched[6], kTreeDepth);
  EXPECT_EQ(touched[7], kNoBlock);
}

}  // namespace
}  // namespace octovk

namespace octovk {
namespace {

// docs/architecture.md's table of buffers states each element's size ("| 1 | `counters` |
// `ScanCounters`: ... | 408 B |"): every row naming a host/device struct must give its sizeof,
// and the readback figure must be ScanCounters + PoolState, so the newcomer's map cannot drift
// from the code (it had: ScanCounters was documented as 408 B while the code said 420).
TEST(Layout, ArchitectureDocSizesAreTheCode) {
  std::ifstream in(OCTOVK_PATH(OCTOVK_SOURCE_DIR) + "/docs/architecture.md");
  ASSERT_TRUE(in.is_open()) << "cannot read docs/architecture.md";
  const std::vector<std::pair<std::string, std::size_t>> sizes = {
      {"ScanParams", sizeof(gpu::ScanParams)},  {"ScanCounters", sizeof(gpu::ScanCounters)},
      {"PoolState", sizeof(gpu::PoolState)},    {"Node", sizeof(gpu::Node)},
      {"ActiveCell", sizeof(gpu::ActiveCell)},  {"NewBlock", sizeof(gpu::NewBlock)},
      {"LeafBox", sizeof(gpu::LeafBox)},        {"WalkState", sizeof(gpu::WalkState)},
      {"DepthCamera", sizeof(gpu::DepthCamera)}};
  // A table row: "| binding | `buffer` | ... `Struct` ... | N B..." (the first struct named).
  const std::regex row(
      R"(^\| [0-9, ]+ \| `[a-z_]+` \| [^|`]*`([A-Z][A-Za-z]+)`[^|]*\| ([0-9]+) B)");
  const std::regex readback(R"(\(`ScanCounters` \+ `PoolState`, ([0-9]+) bytes)");
  std::size_t rows = 0;
  bool readback_seen = false;
  for (std::string line; std::getline(in, line);) {
    std::smatch m;
    if (std::regex_search(line, m, row)) {
      for (const auto& [name, size] : sizes) {
        if (m[1] != name) continue;
        ++rows;
        EXPECT_EQ(std::stoul(m[2]), size) << "docs/architecture.md gives `" << name << "` as "
                                          << m[2] << " B; sizeof says " << size << ":\n"
                                          << line;
      }
    }
    if (std::regex_search(line, m, readback)) {
      readback_seen = true;
      EXPECT_EQ(std::stoul(m[1]), sizeof(gpu::ScanCounters) + sizeof(gpu::PoolState)) << line;
    }
  }
  EXPECT_EQ(rows, sizes.size()) << "a struct's row is missing from the buffer table";
  EXPECT_TRUE(readback_seen) << "the readback size is no longer stated";
}

// The names and counts docs/architecture.md gives exist in the code: every `kConstant` it names
// is defined somewhere in src/, shaders/, include/ or python/src/, every shader file it names is in
// shaders/, and its binding count and address-table binding are gpu_types.h's (it had named a
// kLengthMargin that never existed, 21 bindings where the layout has 22, and the table at 20).
TEST(Layout, ArchitectureDocNamesWhatExists) {
  namespace fs = std::filesystem;
  const fs::path root = OCTOVK_PATH(OCTOVK_SOURCE_DIR);
  std::ifstream in(root / "docs/architecture.md");
  ASSERT_TRUE(in.is_open()) << "cannot read docs/architecture.md";
  const std::string doc((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
  std::string code;
  for (const char* dir : {"src", "shaders", "include", "python/src"})
    for (const auto& entry : fs::recursive_directory_iterator(root / dir))
      if (entry.is_regular_file()) {
        std::ifstream f(entry.path());
        code.append(std::istreambuf_iterator<char>(f), std::istreambuf_iterator<char>());
      }
  const auto each = [&](const std::regex& re, const std::function<void(const std::string&)>& f) {
    for (std::sregex_iterator it(doc.begin(), doc.end(), re), end; it != end; ++it) f((*it)[1]);
  };
  std::set<std::string> defined;  // every kName token of the code
  const std::regex constant("\\bk[A-Z][A-Za-z0-9_]*");
  for (std::sregex_iterator it(code.begin(), code.end(), constant), end; it != end; ++it)
    defined.insert(it->str());
  std::size_t constants = 0, shaders = 0;
  each(std::regex("`(k[A-Z][A-Za-z0-9_]*)`"), [&](const std::string& name) {
    ++constants;
    EXPECT_TRUE(defined.count(name))
        << "docs/architecture.md names `" << name << "`, which the code does not define";
  });
  each(std::regex("`([a-z0-9_]+[.](glsl|comp))`"), [&](const std::string& file) {
    ++shaders;
    EXPECT_TRUE(fs::exists(root / "shaders" / file))
        << "docs/architecture.md names `" << file << "`, which is not in shaders/";
  });
  EXPECT_GT(constants, 20u);
  EXPECT_GT(shaders, 20u);
  std::size_t counts = 0;
  each(std::regex("([0-9]+) storage-buffer bindings"), [&](const std::string& n) {
    ++counts;
    EXPECT_EQ(std::stoul(n), gpu::kBindingCount + 1) << "the map's bindings and the address table";
  });
  each(std::regex("`kBindAddresses` \\(([0-9]+)\\)"), [&](const std::string& n) {
    ++counts;
    EXPECT_EQ(std::stoul(n), gpu::kBindAddresses);
  });
  EXPECT_EQ(counts, 2u) << "the binding count or the address table's binding is no longer stated";
}

// A node's fields are reached through shaders/node.glsl alone, so that a payload (colour, time
// stamp) is added there and not in every pass: no other shader names NODES, the pool's array
// (bindings.glsl defines it; layout_probe.comp writes every field of every layout).
TEST(Layout, ShadersReachNodesThroughNodeGlsl) {
  namespace fs = std::filesystem;
  const fs::path dir = OCTOVK_PATH(OCTOVK_SOURCE_DIR) + "/shaders";
  const std::regex names_nodes("\\bNODES\\b");
  std::size_t files = 0;
  for (const auto& entry : fs::directory_iterator(dir)) {
    const std::string name = entry.path().filename().string();
    if (name == "node.glsl" || name == "bindings.glsl" || name == "layout_probe.comp") continue;
    ++files;
    std::ifstream in(entry.path());
    std::size_t number = 0;
    for (std::string line; std::getline(in, line);) {
      ++number;
      const std::string code = line.substr(0, line.find("//"));
      EXPECT_FALSE(std::regex_search(code, names_nodes))
          << "shaders/" << name << ":" << number << " reaches a node's fields directly; use "
          << "node.glsl's accessors (nodeData, setNodeData, linkOf, ...):\n"
          << line;
    }
  }
  EXPECT_GT(files, 30u);
}

}  // namespace
}  // namespace octovk
