// The Vulkan-free part of MapBuffers: the pool's block limit and an empty map's bytes.
#include "map/buffer_sizes.hpp"

#include <algorithm>

namespace octovk {

using namespace sizes;

std::uint32_t poolBlockLimit(std::size_t max_nodes) {
  constexpr std::uint64_t kMax = 0x1FFFFFFFu;  // 2^32 nodes
  if (max_nodes == 0) return kMax;
  return static_cast<std::uint32_t>(std::clamp<std::uint64_t>(max_nodes / 8, 2, kMax));
}

std::size_t MapBuffers::initialBytes(std::uint32_t block_limit, Payload payload) {
  const bool with = payload != Payload::kNone;
  // Small buffers: points, walks, depth, colour fold, leaf boxes, the frames' staging, and the
  // payload of a map without one.
  return kFixedBytes + 4 * kSmallQuery + (5 + kFramesInFlight + (with ? 0 : 1)) * kSmallBuffer +
         hashBytes(kInitialHashLog2) + endpointBytes(kInitialHashLog2) +
         slotBytes(kInitialHashLog2, kInitialHashLog2) + listBytes(kInitialListEntries) +
         std::size_t{std::min<std::uint32_t>(kInitialBlocks, block_limit)} *
             blockBytes(with, /*leaf_boxes=*/false);
}

}  // namespace octovk
