#include "map/growth_policy.hpp"

#include <algorithm>
#include <exception>
#include <string>
#include <utility>

#include "map/buffer_sizes.hpp"
#include "map/change_set.hpp"

namespace octovk {

namespace {

// First guess of the cell set's size for a scan of `count` points: 4 brick slots (16 cells) per
// point (a 320x240 depth view at 0.05 m touches 0.6-1 million cells in about a quarter as many
// bricks), at most 2^20 brick slots; it grows (and the scan is redone) when a scan needs more,
// and keeps its size for the next scans.
std::uint32_t hashGuess(std::size_t count) {
  return std::min<std::uint32_t>(nextPow2Log2(count * 4), 20);
}

// First guess of the touched lists for a scan of `count` points: 32 entries per point (OctoMap's
// spherical sample at 0.05 m updates 13.7 cells per point, and the lists hold one to two entries
// per updated cell), at most 2^20 entries (4 MiB): a small scan into a fresh map then runs once
// instead of being refused for its lists and run again. Larger scans grow to what the device
// counted.
std::size_t listGuess(std::size_t count) {
  return std::size_t{1} << std::min<std::uint32_t>(nextPow2Log2(count * 32), 20);
}

// First guess of the pool's blocks for a scan of `count` points into a map with little room: three
// blocks per point (72 bytes each). A scan creates the whole path of blocks to every cell it
// updates before pruning frees most of them: the spherical sample at 0.05 m asks for 21,780 new
// blocks for 10,201 points, and keeps 2,990.
std::uint32_t poolGuess(std::size_t count) {
  return static_cast<std::uint32_t>(std::min<std::size_t>(count * 3, std::size_t{1} << 21));
}

// A scan's growth the device refused, said once: what needed the room and what to change.
class ScanOutOfMemory : public Error {
 public:
  ScanOutOfMemory(const Error& e, const std::string& what, std::size_t cap)
      : Error(ErrorCode::kOutOfDeviceMemory,
              "insertPointCloud: " + what + " needs more device memory than the device gave (" +
                  e.message() +
                  "); the map is unchanged. Split the scan into smaller ones or give it a max "
                  "range (ScanOptions::max_range_m)" +
                  (cap == 0 ? std::string(" (MapParams::max_device_bytes is not set: only the "
                                          "device limits the map)")
                            : ", or lower MapParams::max_device_bytes (now " + std::to_string(cap) +
                                  " bytes) to what the device holds"),
              0, e.detail()) {}
};

// Runs a growth for `what`; a device's refusal becomes a ScanOutOfMemory (the cap's refusals,
// BudgetError, name the cap already, and one already said passes as it is).
template <class F>
void growing(const MapCore& core, const std::string& what, F&& grow) {
  try {
    grow();
  } catch (const BudgetError&) {
    throw;
  } catch (const ScanOutOfMemory&) {
    throw;
  } catch (const Error& e) {
    if (e.code() != ErrorCode::kOutOfDeviceMemory) throw;
    throw ScanOutOfMemory(e, what, core.buffers.maxBytes());
  }
}

}  // namespace

bool onlyCellListsShort(const gpu::ScanCounters& counters, std::uint32_t hash_log2) noexcept {
  const std::size_t set_room = (std::size_t{1} << hash_log2) * 3 / 4;
  return (counters.status & gpu::kStatusHashFull) && (counters.status & gpu::kStatusCellsShort) &&
         counters.brick_entries < set_room;
}

bool GrowthPolicy::mustGrow(std::size_t count, std::size_t depth_bytes) const {
  const MapBuffers& b = core_.buffers;
  return count > b.pointCapacity() || depth_bytes > b.depth.size() ||
         depth_bytes > b.uploads[0].size() || hashGuess(count) > hash_guess_tried_ ||
         ahead_blocks_ > 0 || ahead_entries_ > 0 || release_scratch_;
}

void GrowthPolicy::growFor(std::size_t count, std::size_t depth_bytes) {
  growing(core_, "a scan of " + std::to_string(count) + " points", [&] {
    growAhead();
    core_.buffers.ensurePoints(count);
    if (depth_bytes > 0) core_.buffers.ensureDepth(depth_bytes);
    const std::uint32_t guess = hashGuess(count);
    if (guess > hash_guess_tried_) {
      core_.buffers.growHashToward(guess);  // as far as MapParams::max_device_bytes allows
      hash_guess_tried_ = guess;
      guessListsAndPool(count);
    }
  });
}

// Ahead of need, like growAhead: a guess the cap has no room for is dropped, and the scan that
// needs the room grows it after the device counted (or says the cap is too small).
void GrowthPolicy::guessListsAndPool(std::size_t count) {
  MapBuffers& buffers = core_.buffers;
  try {
    const std::size_t lists = listGuess(count);
    if (lists > buffers.listEntries()) buffers.allocateLists(lists);
    const std::uint32_t blocks =
        std::min<std::uint32_t>(poolGuess(count), static_cast<std::uint32_t>(buffers.blockLimit()));
    if (blocks > buffers.poolBlocks())
      buffers.allocatePoolAtLeast(blocks, buffers.poolBlocks(), /*copy_old=*/true);
  } catch (const Error&) {  // the cap (BudgetError) or the device: left to the scan's counts
  }
}

void GrowthPolicy::growAhead(const gpu::PoolState* pool, bool release) {
  if (ahead_blocks_ > 0) {
    const std::uint64_t blocks = std::exchange(ahead_blocks_, 0);
    reservePool(blocks, pool ? *pool : core_.readPool(), /*ahead=*/true);
  }
  if (ahead_entries_ > 0) {
    const std::size_t entries = std::exchange(ahead_entries_, 0);
    if (entries > core_.buffers.listEntries()) {
      try {
        // No scan is in flight: the last one's lists are copied (a store's next capture reads
        // them).
        core_.buffers.allocateLists(std::size_t{1} << nextPow2Log2(entries),
                                    core_.buffers.listEntries());
      } catch (const BudgetError&) {
        // ahead of need: the cap leaves no room, and the scan that needs it will say so
      }
    }
  }
  if (release && release_scratch_) {
    release_scratch_ = false;
    releaseScratch();
  }
}

void GrowthPolicy::growAheadBestEffort() {
  const std::uint64_t ahead_blocks = ahead_blocks_;
  const std::size_t ahead_entries = ahead_entries_;
  try {
    growAhead();
  } catch (const std::exception&) {  // octovk::Error or std::bad_alloc: asked for again
    ahead_blocks_ = std::max(ahead_blocks_, ahead_blocks);
    ahead_entries_ = std::max(ahead_entries_, ahead_entries);
  }
}

void GrowthPolicy::releaseScratch() {
  // The last scan's touched lists are kept where they fit the smaller buffer, and its colour
  // fold's folded list at the start of the smaller fold buffer: a store's next capture reads
  // them.
  MapCore::TouchedLists& lists = core_.touched;
  std::size_t used = 0;
  if (lists.generation == core_.buffers.listsGeneration())
    for (const std::uint32_t n : lists.counts) used += n;
  const bool fold = lists.folded > 0 && lists.fold_generation == core_.buffers.foldGeneration();
  const std::size_t fold_bytes = fold ? std::size_t{lists.folded} * sizeof(gpu::FoldedNode) : 0;
  core_.buffers.releaseScratch(used, std::size_t{lists.folded_at} * sizeof(std::uint32_t),
                               fold_bytes);
  if (fold) {
    lists.folded_at = 0;
    lists.fold_generation = core_.buffers.foldGeneration();
  }
  hash_guess_tried_ = 0;
  scratch_peak_points_ = 0;
}

void GrowthPolicy::trim() {
  releaseScratch();
  core_.buffers.releaseQueries();
}

bool GrowthPolicy::outsizedScan(std::size_t points) noexcept {
  if (scan_count_ == kScanHistory)
    std::move(scan_points_.begin() + 1, scan_points_.end(), scan_points_.begin());
  else
    ++scan_count_;
  scan_points_[scan_count_ - 1] = points;
  scratch_peak_points_ = std::max(scratch_peak_points_, points);
  std::array<std::size_t, kScanHistory> sorted = scan_points_;
  for (std::size_t i = 1; i < scan_count_; ++i)  // insertion sort of at most 8
    for (std::size_t j = i; j > 0 && sorted[j - 1] > sorted[j]; --j)
      std::swap(sorted[j - 1], sorted[j]);
  const std::size_t median = sorted[(scan_count_ - 1) / 2];  // the lower one of an even count
  return scratch_peak_points_ > kOutsizedFactor * median &&
         core_.buffers.bytesByUse().scratch > kAutoReleaseBytes;
}

void GrowthPolicy::noteApplied(const gpu::ScanCounters& counters, const gpu::PoolState& pool,
                               std::uint64_t scans_ahead, std::size_t points) noexcept {
  const std::uint64_t room = std::uint64_t{pool.capacity} - pool.bump + pool.free_count;
  const std::uint64_t want = std::uint64_t{counters.new_blocks} * scans_ahead;
  if (want > room) ahead_blocks_ = std::max(ahead_blocks_, want);
  const std::size_t entries = sizes::touchedBound(
      std::size_t{counters.active_cells} + counters.leaf_cells, counters.brick_entries);
  if (entries > core_.buffers.listEntries() / 2)
    ahead_entries_ = std::max(ahead_entries_, entries * 2);
  if (outsizedScan(points)) release_scratch_ = true;  // released once none is in flight
}

void GrowthPolicy::growForRetry(const gpu::ScanCounters& counters, const gpu::PoolState& pool) {
  growing(core_, "the scan", [&] { growForRetryOf(counters, pool); });
}

void GrowthPolicy::growForRetryOf(const gpu::ScanCounters& counters, const gpu::PoolState& pool) {
  MapBuffers& buffers = core_.buffers;
  const std::uint32_t status = counters.status;
  if (status & gpu::kStatusRayCut)
    throw Error(ErrorCode::kMissingFeature,
                "insertPointCloud: a ray crosses more cells than octovk walks on the device '" +
                    core_.device.info().name +
                    "' (about 196,000 steps); the map is unchanged. Use a coarser resolution "
                    "or a max range");
  // More walks were left unfinished than the lists hold: twice the lists, or what the rounds
  // counted (the last round of each list; a list cut short undercounts the rounds after it).
  if (status & gpu::kStatusWalksShort) {
    const std::size_t seen = std::max(counters.walk_count[0], counters.walk_count[1]);
    buffers.ensureWalks(std::min(buffers.pointCapacity(),
                                 std::max(2 * buffers.walkCapacity(), std::size_t{2} * seen)));
  }
  // A full set stopped classify early: its other counts are partial, so only the set grows.
  if (status & gpu::kStatusHashFull) {
    // Under the cap, where only the cell lists were short, they alone grow, to the cells
    // counted and an eighth more, when a set four times larger has no room (a dense scan lists
    // 25 cells a brick, the set is made for 4 a slot): memory goes where the counts say it is
    // short.
    if (onlyCellListsShort(counters, buffers.hashLog2()) && buffers.maxBytes() != 0 &&
        counters.cell_entries > buffers.cellEntries()) {
      try {
        if (buffers.hashLog2() + 2 <= kMaxHashLog2) {
          buffers.allocateHash(buffers.hashLog2() + 2);
          return;
        }
      } catch (const BudgetError&) {
      }
      const std::size_t cells = counters.cell_entries;
      buffers.allocateCells(cells + cells / 8);
      return;
    }
    if (buffers.hashLog2() + 2 > kMaxHashLog2)
      throw Error(ErrorCode::kOutOfDeviceMemory,
                  "insertPointCloud: a scan touches more than 2^25 bricks of 4x4x4 cells; the "
                  "map is unchanged. Split the scan");
    buffers.allocateHash(buffers.hashLog2() + 2);
    return;
  }
  if (status & gpu::kStatusEndpointHashFull) {
    if (buffers.endpointLog2() >= 30)
      throw Error(ErrorCode::kOutOfDeviceMemory,
                  "insertPointCloud: a scan creates more than 2^29 blocks; split the scan");
    try {
      buffers.allocateEndpoints(buffers.endpointLog2() + 2);
    } catch (const BudgetError&) {
      buffers.allocateEndpoints(buffers.endpointLog2() + 1);  // under the cap: half as much
    }
    return;
  }
  if (status & gpu::kStatusPoolShort) reservePool(counters.new_blocks, pool, /*ahead=*/false);
  const std::uint32_t active = counters.active_cells + counters.leaf_cells;
  if (status & gpu::kStatusListsShort)
    buffers.allocateLists(std::size_t{1}
                          << nextPow2Log2(sizes::touchedBound(active, counters.brick_entries)));
  // Change detection: room for every cell the scan updates, and as many again for the next
  // scans, so that the set does not grow one refused scan at a time.
  if (status & gpu::kStatusChangesShort)
    changes_.grow(std::uint64_t{changes_.header().used} + 2 * std::uint64_t{active});
}

bool GrowthPolicy::poolBeforeScratch(const gpu::ScanCounters& counters,
                                     const gpu::PoolState& pool) {
  if (!(counters.status & gpu::kStatusPoolShort)) return true;
  if (core_.buffers.maxBytes() == 0) return false;
  // No headroom: what is left stays for the parts' sets and lists. (The pool may have grown
  // already, before the lists' growth failed.)
  try {
    reservePool(counters.new_blocks, pool, /*ahead=*/false, /*exact=*/true);
    return true;
  } catch (const BudgetError&) {
  }
  if (!core_.buffers.releaseSetsAndLists()) return false;
  hash_guess_tried_ = 0;  // the next scan may guess the sets again, within the cap
  try {
    reservePool(counters.new_blocks, pool, /*ahead=*/false, /*exact=*/true);
    return true;
  } catch (const BudgetError&) {
    return false;  // the scan's new blocks do not fit even so: the map outgrows the cap
  }
}

// Makes room in the pool for `blocks` more blocks (exactly classify's count). Ahead of need (for
// the next scans) a refusal is not an error: the scan that needs the room will report it.
void GrowthPolicy::reservePool(std::uint64_t blocks, const gpu::PoolState& pool, bool ahead,
                               bool exact) {
  MapBuffers& buffers = core_.buffers;
  // The pool's size is the host's (a growth since `pool` was read back is in it).
  const std::uint64_t available =
      std::uint64_t{std::max(pool.capacity, buffers.poolBlocks())} - pool.bump + pool.free_count;
  if (blocks <= available) return;
  const std::uint64_t needed = std::uint64_t{pool.bump} + blocks - pool.free_count + 1;
  const std::uint64_t limit = buffers.blockLimit();
  if (needed > limit) {
    if (ahead) return;
    throw Error(ErrorCode::kOutOfDeviceMemory,
                "insertPointCloud: the scan needs a node pool of " + std::to_string(needed * 8) +
                    " nodes, over the limit of " + std::to_string(limit * 8) +
                    " (MapParams::max_nodes or 2^32); the map is unchanged");
  }
  std::uint64_t target =
      exact ? needed
            : std::min<std::uint64_t>(
                  limit, std::max<std::uint64_t>(needed, std::uint64_t{buffers.poolBlocks()} +
                                                             buffers.poolBlocks() / 2));
  // Under the cap the headroom takes at most half of what is left beyond the need: the rest stays
  // for the scans' sets and lists (a scan split in groups of tiles needs some for each part).
  const std::uint64_t within = buffers.poolBlocksWithinCap();
  if (target > needed && within > needed)
    target = std::min<std::uint64_t>(target, needed + (within - needed) / 2);
  try {
    buffers.allocatePoolAtLeast(static_cast<std::uint32_t>(target),
                                static_cast<std::uint32_t>(needed), /*copy_old=*/true);
  } catch (const BudgetError&) {
    if (ahead) return;
    throw;  // names the cap
  } catch (const Error& e) {
    if (ahead || e.code() != ErrorCode::kOutOfDeviceMemory) {
      if (ahead) return;
      throw;
    }
    throw ScanOutOfMemory(e, "the scan's node pool of " + std::to_string(target * 8) + " nodes",
                          buffers.maxBytes());
  }
}

}  // namespace octovk
