// The map's device buffers: the node pool, the per-scan scratch (cell sets, lists, points,
// walks), the query buffers and the leaf boxes; their sizes, their growth and the binding set
// every pass sees them through. One owner for all of them, so growth is in one place.
#pragma once

#include <cstddef>
#include <cstdint>

#include "octovk/gpu_types.h"
#include "vk/device.hpp"

namespace octovk {

// Cell-list entries per brick slot of the cell set (rays touch 4-6 cells of most bricks they
// cross).
inline constexpr std::uint32_t kCellsPerBrickSlot = 4;
// Cell ids (brick slot * 64 + index) must fit 32 bits.
inline constexpr std::uint32_t kMaxHashLog2 = 26;
inline constexpr std::uint32_t kInitialBlocks = 1024;
inline constexpr std::uint32_t kInitialHashLog2 = 12;

/// Smallest log2 with 2^log2 >= n.
std::uint32_t nextPow2Log2(std::size_t n);

/// Counters as a scan starts them: zero, with whole (x, 1, 1) dispatch arguments.
gpu::ScanCounters freshCounters();

class MapBuffers {
 public:
  /// Allocates the initial buffers; `block_limit` caps the pool (MapParams::max_nodes).
  MapBuffers(vk::Device& device, vk::CommandStream& stream, std::uint32_t block_limit);

  // Growth. Each makes all new buffers before dropping an old one, so a failed allocation
  // leaves the map as it was, then rebinds.
  /// The cell set: 2^log2 brick slots and 4 cell-list entries per slot.
  void allocateHash(std::uint32_t log2);
  /// The second set (end cells, then new-block prefixes): 2^log2 entries.
  void allocateEndpoints(std::uint32_t log2);
  /// The touched lists for `active_capacity` cells.
  void allocateLists(std::size_t active_capacity);
  /// The pool with `blocks` blocks, keeping the tree and the leaf boxes when `copy_old` (records
  /// and waits).
  void allocatePool(std::uint32_t blocks, bool copy_old);
  /// Points, their staging and the walk lists for at least `count` points.
  void ensurePoints(std::size_t count);
  /// The depth-image buffer (DepthCamera + pixels) of at least `bytes`, and upload staging as
  /// large.
  void ensureDepth(std::size_t bytes);
  /// Query input/output (and their staging) of at least these sizes.
  void ensureQueries(std::size_t in_bytes, std::size_t out_bytes);
  /// An empty tree in the pool and fresh counters (records and waits).
  void resetPool();
  /// Points every binding at its buffer (after a buffer is replaced, or after interop swapped
  /// the query bindings).
  void rebind();

  std::uint32_t blockLimit() const noexcept { return block_limit_; }
  std::uint32_t hashLog2() const noexcept { return hash_log2_; }
  std::uint32_t endpointLog2() const noexcept { return endpoint_log2_; }
  std::size_t activeCapacity() const noexcept { return active_capacity_; }
  std::uint32_t poolBlocks() const noexcept { return pool_blocks_; }
  std::size_t pointCapacity() const noexcept { return point_capacity_; }
  /// Whether the sets must be cleared whole before the next scan (new, or left in an unknown
  /// state by a failed scan); else only the slots the last scan filled are cleared.
  bool setsNeedFill() const noexcept { return sets_need_fill_; }
  void setSetsNeedFill(bool v) noexcept { sets_need_fill_ = v; }

  std::size_t deviceBytes() const;
  std::size_t poolBytes() const {
    return nodes.size() + block_parents.size() + free_stack.size();
  }

  vk::BindingSet bindings;
  vk::Buffer params, counters, pool, readback, points, upload;
  vk::Buffer hash_keys, hash_flags, cell_list, cells, endpoint_keys;
  vk::Buffer touched;
  vk::Buffer prefix_blocks;  // gpu::NewBlock per slot of the second set
  vk::Buffer nodes, block_parents, free_stack, leaf_boxes;
  vk::Buffer query_in, query_out, query_staging_in, query_staging_out;
  vk::Buffer walks;  // ray walks saved between segments (two lists of pointCapacity())
  vk::Buffer slots;  // filled slots of the cell set, then of the second set
  vk::Buffer depth;  // a depth image: gpu::DepthCamera, then its pixels

 private:
  void allocateSlots();

  vk::Device& device_;
  vk::CommandStream& stream_;
  std::uint32_t block_limit_;
  bool sets_need_fill_ = true;
  std::uint32_t hash_log2_ = 0, endpoint_log2_ = 0;
  std::size_t active_capacity_ = 0;
  std::uint32_t pool_blocks_ = 0;
  std::size_t point_capacity_ = 0;
};

}  // namespace octovk
