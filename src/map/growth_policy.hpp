// The growth policy: how large the map's scratch and pool grow, and when. Before a scan, what its
// size needs (points, depth image, a first guess of the cell set); after a refused scan, what the
// device found short; ahead of need, what the results of recent scans ask for (pool and list
// room for more scans like them, releasing the scratch after an outsized one). It decides;
// MapBuffers allocates (under the memory cap). Every growth runs with no scan in flight.
#pragma once

#include <array>
#include <cstddef>
#include <cstdint>

#include "map/change_set.hpp"
#include "map/map_core.hpp"

namespace octovk {

/// Whether a scan refused for a full cell set was refused for its cell lists alone: they were
/// shorter than its bricks' cells (kStatusCellsShort), while the set of 2^hash_log2 slots took
/// every brick (below its 3/4 fill), so that list_cells counted the cells in full.
bool onlyCellListsShort(const gpu::ScanCounters& counters, std::uint32_t hash_log2) noexcept;

class GrowthPolicy {
 public:
  GrowthPolicy(MapCore& core, ChangeSet& changes) : core_(core), changes_(changes) {}

  /// Whether a scan of `count` points (`depth_bytes` of depth image) needs anything to grow
  /// first, or growth asked for ahead is due: then the caller waits for the scans in flight and
  /// calls growFor.
  bool mustGrow(std::size_t count, std::size_t depth_bytes) const;
  /// Grows what was asked for ahead, then what the scan needs; nothing may be in flight.
  void growFor(std::size_t count, std::size_t depth_bytes);
  /// What the results of recent scans asked for ahead; nothing may be in flight. `pool`: the
  /// pool's state if known (else it is read); `release`: also release the scratch if asked for
  /// (not while refused scans wait in their staging to run again).
  void growAhead(const gpu::PoolState* pool = nullptr, bool release = true);
  /// growAhead after a blocking scan is in the map, best-effort: what fails (octovk::Error or
  /// std::bad_alloc) is asked for again by the next scan, which then reports it with the map
  /// unchanged.
  void growAheadBestEffort();
  /// Grows what a scan the device did not apply found short; throws (map unchanged) where it
  /// may not grow. A device's refusal of a growth (here and in growFor) says what the scan
  /// needed and what to change (split the scan, a max range, the cap).
  void growForRetry(const gpu::ScanCounters& counters, const gpu::PoolState& pool);
  /// Where a refused scan's growth failed: makes the pool's room for its new blocks (none if the
  /// pool was not short), exactly, under the cap releasing the cell sets and lists first if
  /// needed (the scan then runs in groups of tiles, each needing less). False when the room
  /// cannot be made.
  bool poolBeforeScratch(const gpu::ScanCounters& counters, const gpu::PoolState& pool);
  /// After a scan of `points` points is in the map (its counters, the pool after it): asks for
  /// room ahead for `scans_ahead` more scans like it. Allocates nothing, never throws.
  void noteApplied(const gpu::ScanCounters& counters, const gpu::PoolState& pool,
                   std::uint64_t scans_ahead, std::size_t points) noexcept;
  /// Releases the per-scan scratch and the query buffers now (OccupancyMap::trim); the next
  /// scan guesses the cell set afresh.
  void trim();

 private:
  /// Releases the per-scan scratch; the next scan guesses the cell set afresh.
  void releaseScratch();
  void growForRetryOf(const gpu::ScanCounters& counters, const gpu::PoolState& pool);
  /// After each successful scan of `points` points: whether to release the scratch (once no
  /// scan is in flight), because an outsized scan grew it, i.e. the largest scan since the
  /// scratch was last released had more than kOutsizedFactor times the points of the median of
  /// the last kScanHistory scans (this one included), and the scratch holds more than
  /// kAutoReleaseBytes. Deterministic: it depends only on the sequence of point counts.
  /// Allocates nothing: it runs after a scan is in the map, where nothing may fail.
  bool outsizedScan(std::size_t points) noexcept;
  static constexpr std::size_t kScanHistory = 8;
  static constexpr std::size_t kOutsizedFactor = 4;
  static constexpr std::size_t kAutoReleaseBytes = std::size_t{4} << 20;
  /// The touched lists and the pool grown toward a first guess for a scan of `count` points, as
  /// far as the memory cap allows.
  void guessListsAndPool(std::size_t count);
  /// Room in the pool for `blocks` more blocks; `ahead`: for later scans, never an error;
  /// `exact`: no growth headroom.
  void reservePool(std::uint64_t blocks, const gpu::PoolState& pool, bool ahead,
                   bool exact = false);

  MapCore& core_;
  ChangeSet& changes_;
  // Growth asked for by the results of recent scans, done at the next submit (after waiting).
  std::uint64_t ahead_blocks_ = 0;
  std::size_t ahead_entries_ = 0;
  bool release_scratch_ = false;
  std::uint32_t hash_guess_tried_ = 0;  // the largest first guess of the cell set tried
  std::array<std::size_t, kScanHistory> scan_points_{};  // the last scans, oldest first
  std::size_t scan_count_ = 0;                           // of them, up to kScanHistory
  std::size_t scratch_peak_points_ = 0;  // largest scan since the scratch was last released
};

}  // namespace octovk
