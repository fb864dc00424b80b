// The map's device buffers: the node pool, the per-scan scratch (cell sets, lists, points,
// walks), the query buffers and the leaf boxes; their sizes, their growth and the binding set
// every pass sees them through. One owner for all of them, so growth is in one place.
#pragma once

#include <array>
#include <cstddef>
#include <cstdint>
#include <string>
#include <vector>

#include "gpu/gpu_types.h"
#include "vk/device.hpp"

namespace octovk {

// Cell-list entries per brick slot of the cell set (rays touch 4-6 cells of most bricks they
// cross).
inline constexpr std::uint32_t kCellsPerBrickSlot = 4;
// Cell ids (brick slot * 64 + index) must fit 32 bits.
inline constexpr std::uint32_t kMaxHashLog2 = 26;
inline constexpr std::uint32_t kInitialBlocks = 1024;
inline constexpr std::uint32_t kInitialHashLog2 = 12;
// Scans the map keeps in flight (submitted, not yet waited for): each has its command buffer,
// its upload staging and its readback region.
inline constexpr std::uint32_t kFramesInFlight = 3;
// A frame's readback region: the scan's counters, then the pool state.
inline constexpr std::size_t kReadbackBytes = sizeof(gpu::ScanCounters) + sizeof(gpu::PoolState);

/// Smallest log2 with 2^log2 >= n.
std::uint32_t nextPow2Log2(std::size_t n);

/// Counters as a scan starts them: zero, with whole (x, 1, 1) dispatch arguments.
gpu::ScanCounters freshCounters();

/// Most blocks the pool may have for MapParams::max_nodes (0: 2^32 nodes).
std::uint32_t poolBlockLimit(std::size_t max_nodes);

/// A growth refused by the map's device-memory cap (MapParams::max_device_bytes): nothing was
/// allocated or changed. Its own type so that callers which reword allocation failures keep
/// this message, which names the cap.
class BudgetError : public Error {
 public:
  explicit BudgetError(const std::string& message)
      : Error(ErrorCode::kOutOfDeviceMemory, message) {}
};

/// The map's device bytes by use (OccupancyMap::DeviceBytes).
struct BufferBytes {
  std::size_t pool = 0, leaf_boxes = 0, scratch = 0, queries = 0, changes = 0, fields = 0;
  std::size_t total() const { return pool + leaf_boxes + scratch + queries + changes + fields; }
};

// The device-memory cap (MapParams::max_device_bytes) is on the bytes the map's buffers hold
// between calls: every growth checks, before allocating, that the buffers held after it (the
// replaced ones freed) stay within the cap, else throws BudgetError with nothing changed. While a
// buffer is replaced the old and the new one exist together for a moment (the new one is made
// first, so that a failure leaves the map as it was); that transient peak, and the staging of
// an explicit download()/upload(), are not counted.
class MapBuffers {
 public:
  /// Allocates the initial buffers; `block_limit` caps the pool (MapParams::max_nodes),
  /// `max_bytes` all buffers (MapParams::max_device_bytes, 0: no cap; at least initialBytes()).
  /// `payload`: a word per node beside the pool (kColor, kStamp), and for kColor the colour
  /// fold's buffer per scan.
  MapBuffers(vk::Device& device, vk::CommandStream& stream, std::uint32_t block_limit,
             std::size_t max_bytes = 0, Payload payload = Payload::kNone);

  /// Bytes of the buffers the constructor makes: the least a map with this pool limit holds.
  static std::size_t initialBytes(std::uint32_t block_limit, Payload payload = Payload::kNone);

  // Growth. Each checks the cap first (BudgetError, nothing changed), makes all new buffers
  // before dropping an old one, so a failed allocation leaves the map as it was, then rebinds.
  /// The cell set: 2^log2 brick slots and 4 cell-list entries per slot (and the second set at
  /// least as large).
  void allocateHash(std::uint32_t log2);
  /// The cell set grown towards 2^log2 slots, as far as the map then holds at most half the
  /// cap (a first guess of a scan's size: never throws for the cap; the scan grows the set
  /// further if it needs to).
  void growHashToward(std::uint32_t log2);
  /// The second set (end cells, then new-block prefixes): 2^log2 entries.
  void allocateEndpoints(std::uint32_t log2);
  /// The touched lists, `entries` node indices for all levels together (touchedBound). With
  /// `keep_entries` (no scan in flight; at most `entries` and the old size) the old buffer's
  /// first entries are copied into the new one, which then holds the last scan's lists still
  /// (listsGeneration unchanged; records and waits); else the lists are new.
  void allocateLists(std::size_t entries, std::size_t keep_entries = 0);
  /// The pool with `blocks` blocks, keeping the tree and the leaf boxes when `copy_old` (records
  /// and waits).
  void allocatePool(std::uint32_t blocks, bool copy_old);
  /// Points, their staging (one per frame; with room for a colour per point in a colour map)
  /// and the walk lists, and a colour map's fold buffer, for at least `count` points.
  void ensurePoints(std::size_t count);
  /// The depth-image buffer (DepthCamera + pixels) of at least `bytes`, and each frame's upload
  /// staging as large.
  void ensureDepth(std::size_t bytes);
  /// Query input/output (and their staging) of at least these sizes.
  void ensureQueries(std::size_t in_bytes, std::size_t out_bytes);
  /// A new, empty change set of 2^log2 slots (filled with 0xFF bytes, its header zero), made
  /// under the cap (BudgetError, nothing changed) and bound in place of the old one, which is
  /// returned so that its keys can be moved over (rehash) before it is dropped; records and
  /// waits. log2 0: the idle one-slot set.
  vk::Buffer replaceChanges(std::uint32_t log2);
  /// Empties the change set in place (resetChangeDetection): records and waits.
  void resetChanges();
  /// Puts back the set replaceChanges returned (`log2` its size), dropping the current one.
  void restoreChanges(vk::Buffer old, std::uint32_t log2);
  /// allocatePool, but when `blocks` exceeds the cap and `min_blocks` fits, the pool gets the
  /// most blocks that fit instead (growth headroom cut to the cap, never below the need).
  void allocatePoolAtLeast(std::uint32_t blocks, std::uint32_t min_blocks, bool copy_old);
  /// Per-scan scratch (cell sets, lists, points, walks, depth image, upload staging) back to
  /// the constructor's sizes; the next scan grows it again. The sets are then cleared whole.
  /// The first `keep_list_entries` entries of the touched lists are kept (allocateLists), and
  /// `keep_fold_bytes` of the colour fold's buffer from `keep_fold_at` (its folded list) are
  /// copied to the start of the smaller one.
  void releaseScratch(std::size_t keep_list_entries = 0, std::size_t keep_fold_at = 0,
                      std::size_t keep_fold_bytes = 0);
  /// The most blocks the pool could have under the cap, the other buffers as they are (the
  /// largest size_t without a cap).
  std::size_t poolBlocksWithinCap() const;
  /// The leaf boxes (a LeafBox per node slot), made at the pool's size the first time a pass
  /// needs them (leaf boxes, castRay's scene, the edits' block lists) and grown with the pool
  /// from then on; a map that never asks for them does not hold them. Under the cap
  /// (BudgetError, nothing changed); nothing may be in flight. True when made now (their
  /// contents are then to be rebuilt).
  bool ensureLeafBoxes();
  /// The cell sets and touched lists alone back to the constructor's sizes (the points, walks
  /// and staging stay: scans waiting to run again read them): room for the pool under the cap.
  /// True when anything was released.
  bool releaseSetsAndLists(std::size_t keep_list_entries = 0);
  /// The query buffers (and their staging) back to the constructor's sizes.
  void releaseQueries();

  /// An empty tree in the pool and fresh counters (records and waits).
  void resetPool();
  /// Points every binding at its buffer (after a buffer is replaced, or after interop swapped
  /// the query bindings).
  void rebind();

  std::uint32_t blockLimit() const noexcept { return block_limit_; }
  std::uint32_t hashLog2() const noexcept { return hash_log2_; }
  std::uint32_t endpointLog2() const noexcept { return endpoint_log2_; }
  std::size_t listEntries() const noexcept { return list_entries_; }
  /// Entries of the cell list and the active-cell list: kCellsPerBrickSlot per slot of the cell
  /// set as it is made, or more (allocateCells).
  std::size_t cellEntries() const noexcept { return cell_entries_; }
  /// Lengthens the cell list and the active-cell list to `entries` (at most 2^32 - 1), the cell
  /// set as it is: where a scan's bricks hold more cells than the set was made for, and the cap
  /// has no room for a set four times larger. Under the cap (BudgetError, nothing changed);
  /// nothing may be in flight.
  void allocateCells(std::size_t entries);
  /// Counts the touched lists' allocations: lists read after a scan are that scan's only while
  /// this is what it was when the scan ran.
  std::uint64_t listsGeneration() const noexcept { return lists_generation_; }
  /// Counts the colour fold buffer's allocations: its folded list read after a scan is that
  /// scan's only while this is what it was when the scan ran.
  std::uint64_t foldGeneration() const noexcept { return fold_generation_; }
  std::uint32_t poolBlocks() const noexcept { return pool_blocks_; }
  std::size_t pointCapacity() const noexcept { return point_capacity_; }
  /// Entries of each list of walks saved between rounds (0 where the device does not end loops
  /// early: every walk is finished in one go).
  std::size_t walkCapacity() const noexcept { return walk_capacity_; }
  /// Grows the two lists of saved walks to `entries` each (at least), where the device ends
  /// loops early; under the cap (BudgetError, nothing changed); nothing may be in flight.
  void ensureWalks(std::size_t entries);
  /// log2 of the change set's slots (0 while change detection was never on).
  std::uint32_t changesLog2() const noexcept { return changes_log2_; }
  /// Whether the sets must be cleared whole before the next scan (new, or left in an unknown
  /// state by a failed scan); else only the slots the last scan filled are cleared.
  bool setsNeedFill() const noexcept { return sets_need_fill_; }
  void setSetsNeedFill(bool v) noexcept { sets_need_fill_ = v; }

  /// Bytes the map holds outside these buffers: castRay's and the traced scans' box buffers and
  /// acceleration structures (RayScene). Counted with the query buffers, under the cap; the
  /// map sets it whenever a scene grows or is dropped.
  void setSceneBytes(std::size_t bytes) noexcept { scene_bytes_ = bytes; }
  std::size_t sceneBytes() const noexcept { return scene_bytes_; }
  /// Bytes the map's distance fields hold (src/field/, each its own buffers): counted under the
  /// cap; a field checks its growth with checkBudget first, then notes what it freed and added.
  void noteFieldBytes(std::size_t freed, std::size_t added) noexcept {
    field_bytes_ = field_bytes_ - freed + added;
  }
  /// Whether the map may hold `added` more bytes once `freed` are released (no cap: always).
  bool fits(std::size_t freed, std::size_t added) const;
  /// Throws BudgetError naming `what` unless the growth fits the cap.
  void checkBudget(std::size_t freed, std::size_t added, const std::string& what) const;

  /// Every buffer of the map, staging included, and the scenes: what the cap limits.
  std::size_t deviceBytes() const { return bytesByUse().total(); }
  std::size_t poolBytes() const {
    return nodes.size() + block_parents.size() + free_stack.size() + payload.size();
  }
  Payload payloadKind() const noexcept { return payload_kind_; }
  /// The most points color_fold folds in one chunk on this device (walk_budget.hpp).
  std::size_t colorChunk() const noexcept;
  /// Bytes per point of the upload staging: x, y, z floats, and in a colour map a colour and a
  /// link word (color_fold's layout, copied as one range).
  std::size_t stagingBytesPerPoint() const noexcept {
    return 3 * sizeof(float) + (payload_kind_ == Payload::kColor ? 2 * sizeof(std::uint32_t) : 0);
  }
  BufferBytes bytesByUse() const;
  std::size_t maxBytes() const noexcept { return max_bytes_; }
  /// The upload staging of all frames.
  std::size_t uploadBytes() const {
    std::size_t n = 0;
    for (const vk::Buffer& u : uploads) n += u.size();
    return n;
  }

  vk::BindingSet bindings;
  vk::Buffer params, counters, pool, points;
  vk::Buffer readback;  // host-visible: kReadbackBytes per frame
  /// Host-visible staging of each frame's scan input (points or pixels): written by the host
  /// while earlier scans run, kept until the scan is known to be applied (a refused scan is run
  /// again from it).
  std::vector<vk::Buffer> uploads;
  vk::Buffer cell_set_keys, cell_set_flags, cell_list, cells, endpoint_keys;
  vk::Buffer touched;
  vk::Buffer prefix_blocks;  // gpu::NewBlock per slot of the second set
  vk::Buffer nodes, block_parents, free_stack, leaf_boxes;
  vk::Buffer query_in, query_out, query_staging_in, query_staging_out;
  vk::Buffer walks;       // ray walks saved between segments (two lists of walkCapacity())
  vk::Buffer slots;       // filled slots of the cell set, then of the second set
  vk::Buffer depth;       // a depth image: gpu::DepthCamera, then its pixels
  vk::Buffer changes;     // the change set: gpu::ChangeHeader, then gpu::ChangeSlots
  vk::Buffer payload;     // a word per pool node (MapParams::payload), else one small buffer
  vk::Buffer color_fold;  // a colour scan's colours, links and table (colorFoldBytes)

 private:
  /// (Re)makes the sets whose size differs from 2^hash_log2 / 2^endpoint_log2 and the slot
  /// lists (grown when short; resized exactly when `exact_slots`).
  /// The pool's buffers as they are: bytes per block (leaf boxes and payload as held), the bytes
  /// they hold, and the small buffers that stand in for leaf boxes or payload not held.
  struct PoolBytes {
    std::size_t block, held, small;
  };
  PoolBytes poolBytesNow() const;
  void allocateSets(std::uint32_t hash_log2, std::uint32_t endpoint_log2, bool exact_slots);
  /// Bytes freed and added by allocateSets with these arguments.
  /// Records the fills that make the change set empty: every slot 0xFF bytes (kEmptyChangeKey,
  /// kChangeNone), the header zero.
  void recordEmptyChanges();
  /// The cell lists' entries allocateSets makes with a set of 2^hash_log2 slots.
  std::size_t cellEntriesFor(std::uint32_t hash_log2) const noexcept;
  void setsDelta(std::uint32_t hash_log2, std::uint32_t endpoint_log2, bool exact_slots,
                 std::size_t& freed, std::size_t& added) const;

  vk::Device& device_;
  vk::CommandStream& stream_;
  std::uint32_t block_limit_;
  std::size_t max_bytes_ = 0;
  std::size_t scene_bytes_ = 0;
  std::size_t field_bytes_ = 0;
  bool sets_need_fill_ = true;
  std::uint32_t hash_log2_ = 0, endpoint_log2_ = 0;
  std::size_t list_entries_ = 0;
  std::size_t cell_entries_ = 0;
  std::uint64_t lists_generation_ = 0;
  std::uint64_t fold_generation_ = 0;
  std::uint32_t pool_blocks_ = 0;
  bool leaf_boxes_on_ = false;  // ensureLeafBoxes: the leaf boxes follow the pool
  std::size_t point_capacity_ = 0;
  std::size_t walk_capacity_ = 0;
  std::uint32_t changes_log2_ = 0;
  Payload payload_kind_ = Payload::kNone;
};

}  // namespace octovk
