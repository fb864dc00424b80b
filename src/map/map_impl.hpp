// OccupancyMap::Impl: owns the map's parts and answers the public operations by delegating to
// them, each first taking the results of the scans in flight (the scan pipeline's flush) where
// it reads or changes the map. The parts:
//   MapCore        (map_core.hpp)        device, parameters, stream, buffers, recorder; tree facts
//   RaySceneCache  (ray_scene_cache.hpp) castRay's and the traced scans' acceleration structures
//   GrowthPolicy   (growth_policy.hpp)   what grows when: before, after and ahead of scans
//   QueryRunner    (query_runner.hpp)    search, castRay, leaves in a box, interop batches
//   TreeTransfer   (tree_transfer.hpp)   download, upload, leaf boxes to the host
//   ChangeSet      (change_set.hpp)      change detection: the changed keys on the device
//   TreeEdits      (tree_edits.hpp)      map surgery: clearing a box
//   TileWorkingSet (tile_working_set.hpp) tiles moved off the device and back, under the cap
//   ScanPipeline   (scan_pipeline.hpp)   recording, submitting and confirming scans
#pragma once

#include <cstdint>
#include <cstring>
#include <memory>
#include <vector>

#include "map/change_set.hpp"
#include "map/growth_policy.hpp"
#include "map/map_core.hpp"
#include "map/query_runner.hpp"
#include "map/ray_scene_cache.hpp"
#include "map/scan_pipeline.hpp"
#include "map/scan_source.hpp"
#include "map/tile_working_set.hpp"
#include "map/tree_edits.hpp"
#include "map/tree_transfer.hpp"
#include "octovk/octovk.hpp"
#include "vk/device.hpp"

namespace octovk {

class OccupancyMap::Impl {
  // First, so destroyed last: every buffer, scene and stream below is released before the last
  // reference to the device can go (a Context may be destroyed before its maps).
  std::shared_ptr<vk::Device> device_owner_;

 public:
  using DeviceBytes = OccupancyMap::DeviceBytes;
  using ScanSource = octovk::ScanSource;
  Impl(Context& context, const MapParams& params);
  ~Impl();  // waits for the scans in flight (their results are dropped)

  // ---- scans (ScanPipeline) ----
  ScanStats insert(const ScanSource& source, const Eigen::Vector3f& origin, const Pose* pose,
                   const ScanOptions& options, const QueryRequest* queries = nullptr,
                   QueryResults* results = nullptr) {
    return scans_.insert(source, origin, pose, options, queries, results);
  }
  std::uint64_t submit(const ScanSource& source, const Eigen::Vector3f& origin, const Pose* pose,
                       const ScanOptions& options) {
    return scans_.submit(source, origin, pose, options);
  }
  void flush() { scans_.flush(); }
  std::vector<ScanStats> takeStats() { return scans_.takeStats(); }
  bool finished(std::uint64_t ticket) { return scans_.finished(ticket); }
  std::size_t scansInFlight() const { return scans_.inFlight(); }
  OccupancyMap::SyncCounts syncCounts() const {
    return {core_.stream.submissions(), core_.stream.blockingWaits()};
  }
  void setLeafBoxesEveryScan(bool every_scan) {
    if (every_scan) {
      scans_.flush();  // the buffer is made (and bound) with nothing in flight
      tiles_.requireResident("setLeafBoxesEveryScan");
      core_.ensureLeafBoxes();
    }
    scans_.setLeafBoxesEveryScan(every_scan);
  }

  // ---- queries (QueryRunner), each after the scans submitted before it ----
  QueryResults runQueries(const QueryRequest& queries);
  /// A castRay (rays) or lookup batch between ranges of the caller's buffers (interop).
  void queryOnDevice(bool rays, VkBuffer in, VkDeviceSize in_offset, VkDeviceSize in_size,
                     VkBuffer out, VkDeviceSize out_offset, VkDeviceSize out_size,
                     std::uint32_t count);
  std::vector<LeafBoxHost> leavesInBox(const Eigen::Vector3f& min, const Eigen::Vector3f& max,
                                       bool occupied_only);

  // ---- change detection (ChangeSet), each after the scans submitted before it ----
  void enableChangeDetection(bool on) {
    flush();
    changes_.enableByUser(on);
  }
  bool changeDetectionEnabled() const { return changes_.enabled(); }
  void resetChangeDetection() {
    flush();
    changes_.reset();
  }
  std::size_t numChangesDetected() {
    flush();
    return changes_.count();
  }
  std::vector<ChangedKey> changedKeys() {
    flush();
    return changes_.keys();
  }
  void changedKeysOnDevice(VkBuffer out, VkDeviceSize out_offset, VkDeviceSize out_size) {
    flush();
    changes_.onDevice(out, out_offset, out_size);
  }

  /// Signals a caller's semaphore (interop output) after everything submitted so far: an empty
  /// submission on the map's stream (nothing when `semaphore` is VK_NULL_HANDLE).
  void signal(VkSemaphore semaphore, std::uint64_t value) {
    if (semaphore == VK_NULL_HANDLE) return;
    core_.stream.begin(core_.buffers.bindings);
    core_.stream.signalAfterNextSubmit(semaphore, value);
    core_.stream.submit();
  }

  // ---- map surgery (TreeEdits), after the scans submitted before it ----
  void clearBox(const Eigen::Vector3f& min, const Eigen::Vector3f& max) {
    flush();
    tiles_.requireResident("clearBox");
    edits_.clearBox(min, max);
  }
  /// The root's payload word (0 without a root or a payload): OcTreeStamped's last update time.
  std::uint32_t rootPayload() {
    flush();
    if (core_.params.payload == Payload::kNone || core_.readPool().root_exists == 0) return 0;
    vk::Buffer staging(core_.device, sizeof(std::uint32_t), true);
    core_.stream.begin(core_.buffers.bindings);
    core_.stream.copy(core_.buffers.payload, staging, sizeof(std::uint32_t));
    core_.stream.submitAndWait();
    std::uint32_t word = 0;
    std::memcpy(&word, staging.mapped(), sizeof(word));
    return word;
  }
  void degradeOutdated(std::uint32_t now, std::uint32_t threshold) {
    flush();
    tiles_.requireResident("degradeOutdated");
    edits_.degrade(now, threshold);
  }
  void keepBox(const Eigen::Vector3f& min, const Eigen::Vector3f& max) {
    flush();
    tiles_.requireResident("keepBox");
    edits_.keepBox(min, max);
  }
  void compact() {
    flush();
    tiles_.requireResident("compact");
    transfer_.compact();
  }

  // ---- the tree (TreeTransfer, MapCore), each after the scans submitted before it ----
  HostTree download();
  void upload(const HostTree& tree);
  /// The pool and what changed near the root since version `since` (TreeTransfer::capture).
  PoolCapture capture(std::uint64_t since, unsigned depth) {
    flush();
    tiles_.noteCommittedPerScan();  // a store captures after every scan from now on
    return transfer_.capture(since, depth);
  }
  /// A store's capture after every scan from the next one recorded (ScanPipeline::captureScans).
  void captureScans(unsigned depth) noexcept { scans_.captureScans(depth); }
  /// The last scan submitted, when it brings a capture (ScanPipeline::capturing); else 0.
  std::uint64_t capturingTicket() const noexcept {
    const std::uint64_t last = scans_.lastTicket();
    return last != 0 && scans_.capturing(last) ? last : 0;
  }
  std::optional<PoolCapture> takeCapture(std::uint64_t ticket, std::uint64_t since) {
    return scans_.takeCapture(ticket, since);
  }
  /// The tree's version once the scans in flight are in (MapCore::tree_version).
  std::uint64_t treeVersion() {
    flush();
    return core_.tree_version;
  }
  std::vector<LeafBoxHost> downloadLeafBoxes();
  gpu::PoolState readPool();
  /// Nodes in the tree: the pool's and the spilled tiles' (OccupancyMap::nodeCount).
  std::size_t nodeCount();
  /// Leaves in the tree (OccupancyMap::leafCount).
  std::size_t leafCount();

  // ---- the working set of tiles (TileWorkingSet) ----
  void spillTilesTo(std::shared_ptr<TileSpill> spill) {
    flush();
    tiles_.setSpill(std::move(spill));
  }
  std::size_t spilledTiles() {
    flush();
    return tiles_.spilledTiles();
  }
  OccupancyMap::SpillCounts spillCounts() {
    flush();
    return tiles_.counts();
  }
  /// A store commits the map after every scan (StoreAccess::attach).
  void noteCommittedPerScan() noexcept { tiles_.noteCommittedPerScan(); }
  std::vector<std::pair<std::uint64_t, HostTree>> takeDirtyTiles() {
    flush();
    return tiles_.takeDirty();
  }
  /// Throws kInvalidArgument naming `call` while tiles are off the device (after flush()).
  void requireResident(const char* call) {
    flush();
    tiles_.requireResident(call);
  }
  /// Rebuilds the leaf boxes if scans were inserted without rebuilding them.
  void refreshLeafBoxes();

  // ---- memory and backends ----
  /// Every buffer and both scenes (MapBuffers counts the scenes, RaySceneCache::noteSceneBytes).
  std::size_t deviceBytes() const { return core_.buffers.deviceBytes(); }
  std::size_t poolBytes() const { return core_.buffers.poolBytes(); }
  DeviceBytes deviceBytesByUse() const;
  /// Releases the per-scan scratch, the query buffers and the scenes (OccupancyMap::trim).
  void trim();
  /// The map's buffers for a distance field (src/field/): after flush(), the field reads the node
  /// pool (`pool`, `nodes`) and counts its bytes under the cap (checkBudget, noteFieldBytes). It
  /// records on its own command stream; nothing else is shared.
  MapBuffers& fieldBuffers() { return core_.buffers; }
  // A distance field follows the map through the change set (after flush()); the policy is
  // the change set's (change_set.hpp).
  using FieldTracking = ChangeSet::FieldTracking;
  FieldTracking fieldTracking() const { return changes_.fieldTracking(); }
  void enableChangesForField() { changes_.followByField(); }
  void releaseChangesForField() { changes_.unfollowByField(); }
  bool resetChangesForField() { return changes_.resetForField(); }
  /// The map's log-odds parameters (the occupancy threshold isNodeOccupied compares with).
  const ref::LogOddsParams& logOdds() const { return core_.logs; }
  /// castRay's backend on this map (kWalk or kRayTracing) and its build statistics.
  OccupancyMap::CastRayInfo castRayInfo() const { return scenes_.castRayInfo(); }

  const MapParams& params() const { return core_.params; }
  vk::Device& device() { return core_.device; }
  /// The device's owner: a distance field holds it so that its buffers can go after the map.
  const std::shared_ptr<vk::Device>& deviceOwner() const { return device_owner_; }
  /// Where this Impl lives, while it lives: ~Impl sets it to null. A distance field reaches its
  /// map through it, so that it follows the map through moves and refuses once the map is gone.
  std::shared_ptr<Impl*> link() const { return link_; }

 private:
  std::shared_ptr<Impl*> link_ = std::make_shared<Impl*>(this);
  // In dependency order: each part refers only to parts declared before it.
  MapCore core_;
  ChangeSet changes_;
  RaySceneCache scenes_;
  GrowthPolicy growth_;
  QueryRunner queries_;
  TreeTransfer transfer_;
  TileWorkingSet tiles_;
  TreeEdits edits_;
  ScanPipeline scans_;
};

}  // namespace octovk
