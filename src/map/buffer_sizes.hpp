// Bytes of the map's buffers by size parameter: shared by MapBuffers' growth, the device-memory
// cap's checks and MapParams::minDeviceBytes(). Plain arithmetic, no Vulkan (the file readers'
// fuzzers link buffer_sizes.cpp without a device).
#pragma once

#include <algorithm>
#include <cstddef>
#include <cstdint>

#include "gpu/gpu_types.h"
#include "map/map_buffers.hpp"

namespace octovk::sizes {

constexpr std::size_t kInitialListEntries = 16384;  // the touched lists, all levels together
constexpr std::size_t kSmallBuffer = 16;  // points, walks, upload, depth before the first scan
constexpr std::size_t kSmallQuery = 64;   // each query buffer and its staging

// The cell list and the active-cell list, `entries` each.
inline std::size_t cellBytes(std::size_t entries) {
  return entries * (sizeof(std::uint32_t) + sizeof(gpu::ActiveCell));
}
// The cell set of 2^log2 brick slots (keys, flags), with the cell lists it is made with
// (kCellsPerBrickSlot entries a slot; MapBuffers::allocateCells may lengthen them).
inline std::size_t brickBytes(std::uint32_t log2) {
  const std::size_t cap = std::size_t{1} << log2;
  return cap * sizeof(std::uint64_t) + cap * gpu::kBrickFlagWords * sizeof(std::uint32_t);
}
inline std::size_t hashBytes(std::uint32_t log2) {
  return brickBytes(log2) + cellBytes((std::size_t{1} << log2) * kCellsPerBrickSlot);
}
inline std::size_t endpointBytes(std::uint32_t log2) {
  return (std::size_t{1} << log2) * (sizeof(std::uint64_t) + sizeof(gpu::NewBlock));
}
inline std::size_t slotBytes(std::uint32_t hash_log2, std::uint32_t endpoint_log2) {
  return ((std::size_t{1} << hash_log2) + (std::size_t{1} << endpoint_log2)) *
         sizeof(std::uint32_t);
}
inline std::size_t listBytes(std::size_t entries) { return entries * sizeof(std::uint32_t); }
// What the touched lists of a scan can hold at most (tree_gate.comp checks the same bound): at
// depth 15 the parents of its updated leaves, at most 8 in each of its bricks; at a depth d of 14
// or less, ancestors of its bricks (a brick is the node at depth 14), at most 8^d.
inline std::size_t touchedBound(std::size_t active, std::size_t bricks) {
  std::size_t bound = std::min(active, 8 * bricks);
  for (std::size_t d = 0; d + 1 < gpu::kTreeDepth; ++d)
    bound += d < 10 ? std::min(bricks, std::size_t{1} << (3 * d)) : bricks;
  return bound;
}
// Nodes, block parents and free stack of one block.
constexpr std::size_t kBlockBytes = 8 * sizeof(gpu::Node) + 2 * sizeof(std::uint32_t);
// A block's leaf boxes, once the map has them (MapBuffers::ensureLeafBoxes).
constexpr std::size_t kLeafBoxBlockBytes = 8 * sizeof(gpu::LeafBox);
// A block's payload words (MapParams::payload other than kNone).
constexpr std::size_t kPayloadBlockBytes = 8 * sizeof(std::uint32_t);
inline std::size_t blockBytes(bool payload, bool leaf_boxes) {
  return kBlockBytes + (payload ? kPayloadBlockBytes : 0) + (leaf_boxes ? kLeafBoxBlockBytes : 0);
}
// A colour scan's fold buffer (color_fold.comp) for `count` points folded in chunks of at most
// `chunk`: a table of (node, head) pairs with 2^colorTableLog2 entries, then a colour and a link
// per point, then the folded list (a FoldedNode per node whose colour changed: at most a point
// each; for a scan of `count` points it starts at colorFoldedAt(capacity, chunk, count)).
inline std::uint32_t colorTableLog2(std::size_t count, std::size_t chunk) {
  return nextPow2Log2(std::max<std::size_t>(2 * std::min(count, chunk), 64));
}
inline std::size_t colorFoldedAt(std::size_t capacity, std::size_t chunk, std::size_t count) {
  return 2 * (std::size_t{1} << colorTableLog2(capacity, chunk)) + 2 * count;
}
inline std::size_t colorFoldBytes(std::size_t count, std::size_t chunk) {
  return (colorFoldedAt(count, chunk, count) +
          count * sizeof(gpu::FoldedNode) / sizeof(std::uint32_t)) *
         sizeof(std::uint32_t);
}
// The change set of 2^log2 slots (change detection on); log2 0: the one-slot set a map holds
// while change detection was never on.
inline std::size_t changesBytes(std::uint32_t log2) {
  return sizeof(gpu::ChangeHeader) + (std::size_t{1} << log2) * sizeof(gpu::ChangeSlot);
}
// Params, counters, pool, a readback region per frame, and the idle change set.
constexpr std::size_t kFixedBytes = sizeof(gpu::ScanParams) + sizeof(gpu::ScanCounters) +
                                    sizeof(gpu::PoolState) + kFramesInFlight * kReadbackBytes +
                                    sizeof(gpu::ChangeHeader) + sizeof(gpu::ChangeSlot);
// Points on the device and their staging in each frame.
inline std::size_t pointBytes(std::size_t count) {
  return count * 3 * sizeof(float) * (1 + kFramesInFlight);
}
// Entries of each list of walks saved between rounds (on a device that ends loops early) before
// a scan left more unfinished: most scans leave none, so the lists are not sized to the points
// (two lists of a 76,800-point view would take 7.4 MB); a scan that leaves more is refused
// (kStatusWalksShort) and the lists grow.
constexpr std::size_t kInitialWalkEntries = 256;
inline std::size_t walkBytes(std::size_t entries) { return 2 * entries * sizeof(gpu::WalkState); }

}  // namespace octovk::sizes
