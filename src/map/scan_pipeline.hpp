// The scan pipeline: scans recorded and submitted back to back without waiting (each one
// submission; the device decides whether it fits, tree_gate), their results taken in order when
// their frame is needed again or at a synchronisation, and the rare scan the device refused run
// again, with everything behind it, once the growth policy has grown what was short. The
// blocking insert is a submit and a flush on the same path.
#pragma once

#include <cstddef>
#include <cstdint>
#include <deque>
#include <memory>
#include <optional>
#include <vector>

#include "map/capture_mirror.hpp"
#include "map/change_set.hpp"
#include "map/growth_policy.hpp"
#include "map/map_core.hpp"
#include "map/passes/passes.hpp"
#include "map/pool_capture.hpp"
#include "map/query_runner.hpp"
#include "map/ray_scene_cache.hpp"
#include "map/scan_source.hpp"
#include "map/tile_working_set.hpp"
#include "octovk/octovk.hpp"

namespace octovk {

/// Where a scan is on its way into the map (a scan in the map leaves the pipeline).
enum class ScanState : std::uint8_t {
  kEmpty,     ///< no points: nothing recorded; in the map once the scans before it are
  kInFlight,  ///< recorded and submitted; its result not taken yet
  kRefused    ///< the device did not apply it: recover() grows what was short and runs it again
};

/// Whose call a scan belongs to.
enum class ScanCaller : std::uint8_t {
  kSubmit,  ///< submit*: its statistics are queued for takeStats()
  kInsert   ///< the blocking call, which waits for it: its statistics are the call's result
};

/// Where a scan's input is while it may have to run again.
enum class ScanInput : std::uint8_t {
  kStaging,  ///< the host's points or pixels, in its frame's upload staging
  kCaller    ///< a caller's device buffer (interop)
};

/// What the device's tree_gate does with the next scan recorded.
enum class Gate : std::uint8_t {
  kOpen,   ///< takes it if it fits
  kHalted  ///< a scan was refused since the last submission: PoolState::halted may be set, and
           ///< refuses every scan until the next recording clears it
};

class ScanPipeline {
 public:
  ScanPipeline(MapCore& core, ChangeSet& changes, GrowthPolicy& growth, RaySceneCache& scenes,
               QueryRunner& queries, TileWorkingSet& tiles)
      : core_(core),
        changes_(changes),
        growth_(growth),
        scenes_(scenes),
        queries_(queries),
        tiles_(tiles) {}

  /// One scan, then the queries if any, waited for: submit() and flush(), then the growth
  /// ahead (best-effort); the scan's errors thrown with the map as before it.
  ScanStats insert(const ScanSource& source, const Eigen::Vector3f& origin, const Pose* pose,
                   const ScanOptions& options, const QueryRequest* queries = nullptr,
                   QueryResults* results = nullptr);
  /// Records and submits a scan without waiting for it (the host's points or pixels are copied
  /// into the frame's staging first); returns its ticket. Waits only where a frame is still
  /// busy or buffers must grow.
  std::uint64_t submit(const ScanSource& source, const Eigen::Vector3f& origin, const Pose* pose,
                       const ScanOptions& options);
  /// Waits for every submitted scan; a scan the device refused (and the ones behind it) run
  /// again after the host grew what was short. Throws where a scan cannot be inserted: the
  /// map then holds every scan before it, and it and the later ones are dropped.
  void flush();
  /// Statistics of the scans known to be in the map, in order, not taken before.
  std::vector<ScanStats> takeStats();
  /// Whether scan `ticket` is in the map (polls, does not wait).
  bool finished(std::uint64_t ticket);
  std::size_t inFlight() const noexcept { return pending_.size(); }
  /// The ticket of the last scan submitted (0: none yet).
  std::uint64_t lastTicket() const noexcept { return next_ticket_ - 1; }
  void setLeafBoxesEveryScan(bool every_scan) noexcept { leaf_boxes_every_scan_ = every_scan; }

  /// A store commits the map after every scan: from the next scan recorded on, each scan's
  /// submission ends by copying the pool and the touched lists to host staging (a capture, cut
  /// at `depth`), so that the commit neither waits for a submission of its own nor holds back
  /// the next scan. 0: none. Not while tiles may leave the device (TileWorkingSet::enabled):
  /// a scan's parts may then move tiles, which a copy of the pool does not see.
  void captureScans(unsigned depth) noexcept { capture_depth_ = depth; }
  /// Whether scan `ticket` brings a capture (captureScans was on when it was recorded, and it
  /// had points).
  bool capturing(std::uint64_t ticket) const noexcept;
  /// Waits for the scans up to `ticket` (not those after it) and returns the map as scan
  /// `ticket` left it, with the nodes at depths 0..depth that it changed when the tree was at
  /// version `since` before it (PoolCapture::incremental); nullopt when it brought none.
  std::optional<PoolCapture> takeCapture(std::uint64_t ticket, std::uint64_t since);

 private:
  /// A scan applied in groups of tiles (scan `ticket`; its parts are consecutive in the
  /// queue): what its parts applied before the current one did.
  struct PartTotals {
    std::uint64_t ticket = 0;
    std::size_t parts = 0;
    ScanStats sum;             ///< their counts and times, added up (addCounts)
    double fill = 0.0;         ///< the fullest part's fill of the sets or lists, of 1 (notePart)
    std::uint32_t fewest = 0;  ///< the fewest groups among the parts noted
  };
  /// Adds a part's counts and times (what ScanStats adds up over a scan's parts) to `into`.
  static void addCounts(ScanStats& into, const ScanStats& part) noexcept;
  /// How full a scan (or part) left what the device's checks allow: 3/4 of the cell set's and
  /// the second set's slots, the touched lists' entries (each of 1 when full).
  struct ScratchFill {
    double bricks, blocks, cells, cell_list;
  };
  ScratchFill scratchFill(const gpu::ScanCounters& counters) const noexcept;
  /// A scan submitted and not yet known to be in the map: what it needs to run again.
  struct PendingScan {
    ScanState state = ScanState::kEmpty;
    ScanCaller caller = ScanCaller::kSubmit;
    ScanInput input_at = ScanInput::kStaging;
    std::uint64_t ticket = 0;
    std::uint64_t serial = 0;         ///< its last submission
    std::uint32_t frame = 0;          ///< that submission's frame (readback region, timestamps)
    std::uint32_t staging_frame = 0;  ///< whose upload staging holds its input (kStaging)
    passes::RayKeysInput input;
    Eigen::Vector3f origin = Eigen::Vector3f::Zero();
    std::optional<Pose> pose;
    ScanOptions options;
    std::size_t count = 0;
    const QueryRequest* queries = nullptr;  // the blocking call's
    QueryResults* results = nullptr;
    ScanStats stats;
    bool noted_changes = false;   ///< recorded with change detection on (ChangeSet::scanNoted)
    std::uint64_t recording = 0;  ///< MapCore::scans_recorded at its last recording
    /// A scan applied in groups of tiles (its cells did not fit the scratch at once): this part
    /// marks the cells of the tiles whose hash is `group` modulo `groups`. The
    /// parts of one scan follow each other in the queue with its ticket; the last one
    /// (`closes_scan`) also folds the colours and runs the queries, and reports the statistics.
    std::uint32_t group = 0;
    std::uint32_t groups = 1;
    bool closes_scan = true;
    /// Its capture (captureScans), copied at the end of its last part's submission.
    std::shared_ptr<vk::Buffer> capture;
    passes::CaptureLayout capture_layout;
  };
  /// submit(); `caller` kInsert: the blocking call's scan, whose `queries` (staged here) run
  /// right after it in its submission.
  std::uint64_t enqueue(const ScanSource& source, const Eigen::Vector3f& origin, const Pose* pose,
                        const ScanOptions& options, ScanCaller caller, const QueryRequest* queries,
                        QueryResults* results);
  /// Builds the passes of a walked scan at once, on several threads (before the first scan).
  void buildScanPasses();
  /// Records and submits scan `p` (its queries, if any, after it): the one place a scan's
  /// passes are recorded.
  void record(PendingScan& p);
  /// Waits for the oldest scan in flight and takes its result; a refused one is run again with
  /// everything behind it (recover).
  void confirmOldest();
  /// Takes the result of the oldest scan in flight, which has completed: false (and the scan
  /// kRefused) if the device refused it.
  bool takeResult(PendingScan& p, const gpu::ScanCounters& counters, const gpu::PoolState& pool);
  /// Queues a finished scan's statistics for takeStats() (the newest kKeptStats).
  void keepStats(const ScanStats& stats) noexcept;
  /// The oldest scan was refused: waits for all, grows, runs them again in order, each waited.
  void recover(gpu::ScanCounters counters, gpu::PoolState pool);
  /// In recover: the oldest scan becomes `parts` parts, each a share of its tiles (refused, its
  /// growth refused; or halted, to start in parts); false when it cannot be split further.
  bool splitOldest(std::uint32_t parts);
  /// Into how many parts a refused scan whose scratch could not grow is split: from what its
  /// counts say it needed of the sets and lists (2 where classify stopped early).
  std::uint32_t partsNeeded(const gpu::ScanCounters& counters) const;
  /// How many groups of tiles a new scan of `count` points starts with: what the last scan
  /// applied in parts showed its points need, scaled to `count` (1 before any split).
  std::uint32_t groupsFor(std::size_t count) const;
  /// After a part of a scan applied in groups: how full it left the sets and lists; the scan's
  /// last part then estimates how many parts scans like it need.
  void notePart(const PendingScan& p, const gpu::ScanCounters& counters) noexcept;
  /// The oldest scan was refused for tiles off the device, or for pool room the cap does not
  /// allow: the working set loads or evicts tiles (TileWorkingSet). False where it cannot.
  bool rebalanceTiles(const gpu::ScanCounters& counters);
  /// Most groups a scan is split into (a group then holds a few tiles of any scan).
  static constexpr std::uint32_t kMaxTileGroups = 1u << 12;

  MapCore& core_;
  ChangeSet& changes_;
  GrowthPolicy& growth_;
  RaySceneCache& scenes_;
  QueryRunner& queries_;
  TileWorkingSet& tiles_;
  std::deque<PendingScan> pending_;       // submitted, in order
  std::deque<ScanStats> finished_stats_;  // in the map, not taken yet (the newest kKeptStats)
  ScanStats blocking_stats_;              // the last blocking call's scan (its result)
  static constexpr std::size_t kKeptStats = 4096;
  std::uint64_t next_ticket_ = 1;
  std::size_t last_nodes_ = 0;  // nodes after the last scan taken
  Gate gate_ = Gate::kOpen;
  PartTotals parts_;  // of the scan applied in groups of tiles whose parts are being taken
  // Parts the last scan applied in groups needed (estimated from its fill), and its points.
  std::uint32_t split_groups_ = 1;
  std::size_t split_points_ = 0;
  bool leaf_boxes_every_scan_ = false;  // a setting (setLeafBoxesEveryScan), not a state
  /// The capture of scan `p` (applied whole), kept for takeCapture: its staging read (a change's
  /// records copied out, the staging free again).
  void keepCapture(const PendingScan& p, const gpu::ScanCounters& counters,
                   const gpu::PoolState& pool);
  /// Host-visible staging of at least `bytes` that no capture holds.
  std::shared_ptr<vk::Buffer> captureStaging(std::size_t bytes);
  unsigned capture_depth_ = 0;                                // captureScans
  CaptureMirror captures_;                                    // by ticket, and the host's copy
  std::vector<std::shared_ptr<vk::Buffer>> capture_buffers_;  // for reuse
  /// A scan's capture is its change when the capture before it is the last scan recorded and
  /// nothing but scans changed the tree since (MapCore::tree_version counts every change,
  /// scan_changes_ the scans'): the recording and that count at the last capture recorded.
  std::uint64_t capture_recording_ = 0;
  std::uint64_t capture_others_ = ~std::uint64_t{0};
  std::uint64_t scan_changes_ = 0;
};

}  // namespace octovk
