// The host half of each stage: one function per stage that records its shaders' dispatches
// (shaders/<stage>.comp), in pipeline order; each shader is dispatched from exactly one of them.
// None submits or waits; the scan pipeline (map/scan_pipeline.cpp) and the other parts of the map
// decide what runs when.
#pragma once

#include <array>
#include <cstdint>
#include <span>
#include <string_view>
#include <vector>

#include "map/passes/recorder.hpp"
#include "octovk/octovk.hpp"
#include "vk/accel.hpp"
#include "vk/ray_pipeline.hpp"

namespace octovk::passes {

// ---- ray_keys.cpp: points to the cell set ----

/// How a scan's points come in and where the previous scan left the sets.
struct RayKeysInput {
  /// Where the points (x, y, z floats) or the depth image's pixels are: the map's upload buffer,
  /// or a caller's buffer (interop).
  VkBuffer source = VK_NULL_HANDLE;
  VkDeviceSize source_offset = 0;
  std::size_t bytes = 0;
  bool unproject = false;  ///< a depth image: `camera` is written before its pixels
  gpu::DepthCamera camera{};
  bool transform = false;   ///< points in the sensor frame: move them by the pose first
  bool discretize = false;  ///< insert one ray per distinct end cell (OctoMap's discretize)
  /// Empty the sets whole first (new buffers); else they are empty already (each scan empties
  /// the slots it filled at its end, recordClearSets).
  bool fill_sets = false;
  bool resume = false;  ///< clear PoolState::halted first: the host has handled a refused scan
  /// Continuation dispatches of the ray walk where the device limits loops (walkRounds(),
  /// map/walk_budget.hpp).
  std::uint32_t walk_rounds = 0;
  /// The rays are traced (ScanRays' ray tracing, recordScanRaysRt) instead of walked: stop
  /// after the input stages (upload, unproject, transform, discretize).
  bool trace = false;
  /// A colour per point was staged in the frame's upload buffer at `colors_offset` (ColorFold).
  bool colors = false;
  VkDeviceSize colors_offset = 0;
};
/// Uploads the parameters, fresh counters and the staged points (or depth image), then
/// unproject, transform, discretize and the ray walk (with its continuations) into the cell set.
void recordRayKeys(Recorder& r, const gpu::ScanParams& sp, const RayKeysInput& in);
/// What clear_sets empties.
enum class ClearSets : std::uint8_t {
  /// At a scan's end: the slots it filled in both sets (counts from its counters, so it needs no
  /// host decision and works whether or not the scan was applied).
  kScan,
  /// discretize's end cells (one per point at most, `points`) out of the second set, before
  /// classify reuses it for new-block prefixes.
  kEndCells
};
/// clear_sets.comp: the one function that records it (recordClassify asks for kEndCells).
void recordClearSets(Recorder& r, ClearSets which = ClearSets::kScan, std::uint32_t points = 0);

// ---- classify.cpp: the cells against the tree ----

/// Lists the distinct cells and classifies them (early abort, leaf exists, nodes to create,
/// new-block prefixes into the second set).
void recordClassify(Recorder& r, bool discretize, std::uint32_t points);

// ---- tree_update.cpp: the log-odds update ----

/// Decides on the device whether the scan fits (else it leaves the map as it was and marks the
/// scan kStatusNotApplied), then creates the blocks classify counted, links them, and updates
/// every active cell's leaf.
void recordTreeUpdate(Recorder& r);

// ---- prune.cpp ----

/// Inner-node values and pruning, level by level from the deepest, over the touched lists.
void recordPrune(Recorder& r);

// ---- color_fold.cpp ----

/// A colour scan's fold (ColorOcTree::averageNodeColor or, for ColorFold::kIntegrate,
/// integrateNodeColor per point, in order), after its tree passes: the scan's `count` colours
/// copied from `source` at `offset` (packed words), the table emptied, then color_fold's group
/// and fold modes. Nothing happens on the device for a refused scan.
void recordColorFold(Recorder& r, std::size_t count, ColorFold fold, VkBuffer source,
                     VkDeviceSize offset);
/// The word of the colour fold's buffer where the folded list (FoldedNode) of a scan of `count`
/// points starts.
std::uint32_t foldedListAt(const MapBuffers& buffers, std::size_t count);

// ---- leaf_boxes.cpp ----

/// Rebuilds the leaf-box buffer (centre, size, log-odds of every leaf) and PoolState::leaf_count.
void recordLeafBoxes(Recorder& r);
/// The leaves in `box` (OctoMap's leaf_bbx_iterator) compacted into the query output; their
/// count in ScanCounters::query_results.
void recordLeavesInBox(Recorder& r, const gpu::ScanParams& sp, const gpu::BoxQuery& box);

// ---- queries.cpp: search() and castRay ----

/// The first RayState after `results` results in the query output: castRay's walk states
/// follow the results there.
std::uint32_t firstRayState(std::size_t results);
/// Bytes of query output a batch needs: the results, then the castRay walk states.
std::size_t queryOutputBytes(std::size_t rays, std::size_t lookups);
/// Writes the rays (in `ray_order` where given: staged ray s is q.rays[ray_order[s]]), then the
/// lookup points, into the query staging buffer.
void stageQueries(MapBuffers& buffers, const QueryRequest& q,
                  std::span<const std::uint32_t> ray_order = {});
/// The order castRay's rays are staged in (ray indices) and how many stop at unknown space: those
/// rays first, then the ones that ignore it (the ray-tracing backend answers the two kinds with
/// two passes, each over its own range), and within each kind rays from nearby origins in nearby
/// directions next to each other, so that neighbouring invocations walk alike (a group of lanes
/// takes as long as its longest walk). stageQueries / collectQueries take the order; the answers
/// do not depend on it.
std::vector<std::uint32_t> rayOrder(std::span<const Ray> rays, double resolution,
                                    std::uint32_t& stop_rays);
/// A scene the traced passes trace through: its boxes buffer's address (an AccelHeader first),
/// and whether through a ray-tracing pipeline (the ray generation shaders cast_ray_rt.rgen,
/// scan_rays_rt.rgen) rather than ray queries (cast_ray_rt.comp, scan_rays_rt.comp). False
/// when there is none (castRay walks).
struct TraceScene {
  VkDeviceAddress boxes = 0;
  bool pipeline = false;
  explicit operator bool() const noexcept { return boxes != 0; }
};
/// The ray generation shaders of the traced passes' pipelines (TraceScene::pipeline).
inline constexpr std::string_view kCastRayRaygen = "cast_ray_rt.rgen";
inline constexpr std::string_view kScanRaygen = "scan_rays_rt.rgen";
/// The ray-tracing pipeline of the ray generation shader `raygen` (e.g. kCastRayRaygen) over
/// `items` invocations with the push constants `pc` its source declares (OCTOVK_RAY_CONSTANTS),
/// with the map's bindings: for pipelines what Recorder::dispatch is for compute passes.
template <typename Constants>
void traceRays(Recorder& r, std::string_view raygen, std::uint32_t items, const Constants& pc) {
  static_assert(sizeof(Constants) <= sizeof(gpu::PassConstants));
  r.device.rayPipeline(raygen).recordTrace(r.stream, r.buffers.bindings.handle(), items, &pc,
                                           sizeof(pc));
}
/// Copies the staged batch in, runs it and copies the results to the staging output. castRay
/// traces through `ray_scene` when there is one, with the rays staged in rayOrder's order
/// (`stop_rays` of the first kind).
void recordQueries(Recorder& r, const gpu::ScanParams& sp, const QueryRequest& q,
                   TraceScene ray_scene = {}, std::uint32_t stop_rays = 0);
/// castRay for `rays` queries at the start of the query input; results at the start of the
/// output, the walks' states from its RayState `first_state` on.
void recordCastRays(Recorder& r, std::uint32_t rays, std::uint32_t first_state);
/// search() for `points` points from float `first_float` of the query input; results from
/// entry `first_result` of the output.
void recordLookups(Recorder& r, std::uint32_t points, std::uint32_t first_result,
                   std::uint32_t first_float);
/// The results of a batch from the staging output (rays staged in `ray_order`, if given), into
/// `out`, whose vectors are resized to the batch (no allocation where they have that size
/// already: a scan's queries are collected after the scan is in the map).
void collectQueries(const MapBuffers& buffers, const QueryRequest& q,
                    std::span<const std::uint32_t> ray_order, QueryResults& out);

// ---- accel.cpp: castRay's ray-tracing backend ----

/// The geometry of a box buffer (its sorted boxes, after the header), with `count` boxes built.
vk::BoxGeometry boxGeometry(const vk::Buffer& boxes, std::uint32_t count);

/// Bytes of the boxes buffer for the capacities in `header` (its layout: gpu::AccelHeader).
std::size_t accelBoxesBytes(const gpu::AccelHeader& header);
/// Of which the counting sort's counters and chunk sums, at its end.
std::size_t accelSortBytes();
/// The part of them a sort on 2^(3 bucket_bits) buckets uses (from the same start).
std::size_t accelSortBytes(std::uint32_t bucket_bits);
/// Which boxes accel_boxes.comp writes: castRay's (the occupied leaves of the leaf-box buffer,
/// counted) or a traced scan's (every box a free update can change, at the list's capacity, the
/// tail inactive; a smaller sort).
enum class BoxesFor : std::uint8_t { kCastRay, kScan };
/// accel_boxes.comp, the one function that records it: resets `header`'s counts and extent at the
/// start of `boxes`, writes the boxes after it and sorts them along a Morton curve.
void recordBoxes(Recorder& r, const vk::Buffer& boxes, const gpu::AccelHeader& header,
                 BoxesFor target);
/// Writes `header` (capacities, zero counts) at the start of `boxes`, then the boxes the
/// acceleration structure is built over after it (accel_boxes.comp: the occupied leaves of the
/// leaf-box buffer, which must be current), sorted along a Morton curve, and copies the header
/// with the count to `readback`.
void recordAccelBoxes(Recorder& r, const gpu::ScanParams& sp, const vk::Buffer& boxes,
                      const gpu::AccelHeader& header, const vk::Buffer& readback);
/// Builds `scene` over the boxes `header` counts (as recordAccelBoxes left them) and writes the
/// top-level structure's address into the header.
void recordAccelBuild(Recorder& r, vk::BoxScene& scene, const vk::Buffer& boxes,
                      const gpu::AccelHeader& header);
/// castRay through `scene`, for the rays of the query input: cast_ray_jump over `stop` (first
/// ray, count) and the trace over `ignore`; each pass also skips the rays of the other kind, so
/// both ranges may be the whole batch. Results go to the rays' own places in the output.
struct RayRange {
  std::uint32_t first = 0, count = 0;
};
void recordCastRaysRt(Recorder& r, TraceScene scene, RayRange stop, RayRange ignore);

// ---- scan_rays_rt.cpp: scans through ray tracing ----

/// The capacity of a scan's boxes buffer for the map's pool: a box per slot (a leaf or an
/// unknown region) and the root.
gpu::AccelHeader scanSceneHeader(const MapBuffers& buffers);
/// Writes the boxes of the tree as the device holds it when this runs (accel_boxes.comp,
/// kAccelBoxesScan: leaves above clamp_min_log, unknown regions; sorted; the tails inactive)
/// into `boxes` and builds `scene` over the list at its capacity, so that nothing of the
/// tree's state is needed on the host; then the top-level structure's address into the header.
/// `params` must hold the map's parameters. Three timestamps: start, boxes done, build done.
void recordScanScene(Recorder& r, vk::BoxScene& scene, const vk::Buffer& boxes,
                     const gpu::AccelHeader& header);
/// scan_rays_rt (through `scene`) over the scan's points (or discretize's distinct end cells),
/// into the cell set.
void recordScanRaysRt(Recorder& r, TraceScene scene, std::uint32_t points, bool discretize);

// ---- changes.cpp: the change set (change detection) ----

/// list_changes.comp: the change set's keys into the query output (the map's, or the caller's
/// range bound there) after a ChangedKeysHeader holding their count; sets `sp` first.
void recordListChanges(Recorder& r, const gpu::ScanParams& sp);
/// rehash_changes.comp: the keys of the old set (`old_slots` slots at `old_set`) into the bound,
/// empty one; params must hold the new set's log2.
void recordRehashChanges(Recorder& r, VkDeviceAddress old_set, std::uint32_t old_slots);

// ---- clear_box.cpp: map surgery ----

/// octomap_server's clear_bbx: the leaves OctoMap's leaf_bbx_iterator visits for `box` (none when
/// null: a corner outside the map) get the lower clamping bound's log-odds, then every inner node
/// the maximum of its children, bottom-up (updateInnerOccupancy; nothing is pruned). Sets `sp`.
/// With `box` null it is updateInnerOccupancy alone, as keepBox ends.
void recordClearBox(Recorder& r, const gpu::ScanParams& sp, const gpu::BoxQuery* box);
/// OcTreeStamped::degradeOutdatedNodes at query time `now` (one miss on every occupied leaf older
/// than `threshold` seconds, stamps kept), then updateInnerOccupancy with inner stamps `now`.
void recordDegrade(Recorder& r, const gpu::ScanParams& sp, std::uint32_t now,
                   std::uint32_t threshold);

// ---- keep_box.cpp: map surgery ----

/// Keeping only a box: every node but the leaves OctoMap's leaf_bbx_iterator visits for `box`
/// (none when null: a corner outside the map) and the inner nodes above them is deleted, the
/// blocks of deleted nodes pushed on the free stack. Inner values are not updated: record
/// recordClearBox(r, sp, nullptr) after it. Sets `sp`.
void recordKeepBox(Recorder& r, const gpu::ScanParams& sp, const gpu::BoxQuery* box);

// ---- capture.cpp: a store's copy of the map after a scan ----

/// What recordCapture puts in a staging buffer, sized for the pool and the lists as they are when
/// recorded (a scan grows neither). Whole: the node pool, its payload and the touched lists.
/// As a change (`records` != 0): a gpu::CaptureRecord per entry of the touched lists, which the
/// host applies to its copy of the pool as it was before the scan.
struct CaptureLayout {
  std::size_t nodes = 0;  ///< pool nodes copied (the pool's capacity); 0 for a change
  std::size_t node_bytes = 0, payload_bytes = 0, touched_bytes = 0;
  std::size_t records = 0;  ///< room for records (the lists' entries); 0 for the whole pool
  /// The scan folds colours: its folded list's records follow the lists' (a change), or a
  /// whole capture cannot say which tiles the fold changed. Its points: where the list starts.
  bool folded = false;
  std::size_t points = 0;
  std::size_t bytes() const noexcept {
    return node_bytes + payload_bytes + touched_bytes + records * sizeof(gpu::CaptureRecord);
  }
};
/// The whole pool (`change` false), or the scan's change; `folded`: the scan (of `points`)
/// folds colours.
CaptureLayout captureLayout(const MapBuffers& buffers, Payload payload, bool change, bool folded,
                            std::size_t points);
/// After the passes recorded before it: copies what `layout` says into host-visible `staging`
/// (at least layout.bytes()), the map as the scan left it, read by the host once the submission
/// is done, while later scans change the pool. A change is gathered by capture.comp.
void recordCapture(Recorder& r, const CaptureLayout& layout, const vk::Buffer& staging);

// ---- readback.cpp ----

/// Copies the counters and the pool state to the recording frame's readback region.
void recordReadback(Recorder& r);
/// What recordReadback copied in frame `frame`, once that submission is done.
void readBack(const MapBuffers& buffers, std::uint32_t frame, gpu::ScanCounters& counters,
              gpu::PoolState& pool);

}  // namespace octovk::passes
