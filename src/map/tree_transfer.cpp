#include "map/tree_transfer.hpp"

#include <algorithm>
#include <cstring>
#include <memory>
#include <string>

#include "gpu/gpu_types.h"

namespace octovk {

HostTree TreeTransfer::download() {
  HostTree tree = downloadRaw();
  averageInnerColors(tree);  // ColorOcTree::updateInnerOccupancy's colours
  return tree;
}

HostTree TreeTransfer::downloadRaw(gpu::PoolState* state) {
  const gpu::PoolState pool = core_.readPool();
  if (state) *state = pool;
  const std::size_t count = std::size_t{pool.bump} * 8;
  const Payload kind = core_.params.payload;
  const std::size_t node_bytes = count * sizeof(gpu::Node);
  const std::size_t payload_bytes = kind != Payload::kNone ? count * sizeof(std::uint32_t) : 0;
  vk::Buffer staging(core_.device, node_bytes + payload_bytes, true);
  core_.stream.begin(core_.buffers.bindings);
  core_.stream.copy(core_.buffers.nodes, staging, node_bytes);
  if (payload_bytes)
    core_.stream.copy(core_.buffers.payload, staging, payload_bytes, 0, node_bytes);
  core_.stream.submitAndWait();
  const auto* bytes = static_cast<const unsigned char*>(staging.mapped());
  HostTree tree = hostTreeFromPool(
      {reinterpret_cast<const gpu::Node*>(bytes), count},
      {reinterpret_cast<const std::uint32_t*>(bytes + node_bytes), payload_bytes / 4}, kind, pool);
  return tree;
}

PoolCapture TreeTransfer::capture(std::uint64_t since, unsigned depth) {
  PoolCapture out;
  out.version = core_.tree_version;
  const MapCore::TouchedLists& lists = core_.touched;
  const bool unchanged = out.version == since;
  const bool one_scan = out.version == since + 1 && lists.version == out.version &&
                        lists.generation == core_.buffers.listsGeneration();
  // After one scan its own readback has the pool's state: no round trip for it.
  const gpu::PoolState pool = one_scan ? lists.pool : core_.readPool();
  out.root_exists = pool.root_exists != 0;
  // A colour scan's folded list is read from the fold buffer it ran with; once that buffer was
  // replaced (scratch released after an outsized scan), which tiles the fold changed is unknown.
  const bool folds_known =
      lists.folded == 0 || lists.fold_generation == core_.buffers.foldGeneration();
  out.incremental = depth < gpu::kTreeDepth && (unchanged || (one_scan && folds_known));
  std::size_t listed = 0, folded = 0;
  if (out.incremental && !unchanged) {
    for (unsigned level = 0; level <= depth; ++level) listed += lists.counts[level];
    folded = lists.folded;  // the colour fold's list, after the touched entries
  }
  const std::size_t count = std::size_t{pool.bump} * 8;
  const std::size_t node_bytes = count * sizeof(gpu::Node);
  const std::size_t payload_bytes =
      core_.params.payload != Payload::kNone ? count * sizeof(std::uint32_t) : 0;
  const std::size_t staging_bytes = std::max<std::size_t>(
      node_bytes + payload_bytes + listed * 4 + folded * sizeof(gpu::FoldedNode), 4);
  // The last capture's staging again when it is large enough and no PoolCapture holds it;
  // else a new one with a quarter more room for the map's growth.
  if (!capture_staging_ || capture_staging_.use_count() > 1 ||
      capture_staging_->size() < staging_bytes) {
    capture_staging_.reset();
    capture_staging_ =
        std::make_shared<vk::Buffer>(core_.device, staging_bytes + staging_bytes / 4, true);
  }
  std::shared_ptr<vk::Buffer> owner = capture_staging_;
  vk::Buffer& staging = *owner;
  core_.stream.begin(core_.buffers.bindings);
  if (node_bytes) core_.stream.copy(core_.buffers.nodes, staging, node_bytes);
  if (payload_bytes)
    core_.stream.copy(core_.buffers.payload, staging, payload_bytes, 0, node_bytes);
  std::size_t at = node_bytes + payload_bytes;
  if (listed)
    for (unsigned level = 0; level <= depth; ++level) {
      const std::size_t bytes = std::size_t{lists.counts[level]} * 4;
      if (bytes == 0) continue;
      // The levels lie one after another from the deepest (tree.glsl's touchedBase).
      std::size_t base = 0;
      for (unsigned deeper = level + 1; deeper < gpu::kTreeDepth; ++deeper)
        base += lists.counts[deeper];
      core_.stream.copy(core_.buffers.touched, staging, bytes, base * 4, at);
      at += bytes;
    }
  if (folded)
    core_.stream.copy(core_.buffers.color_fold, staging, folded * sizeof(gpu::FoldedNode),
                      std::size_t{lists.folded_at} * 4, at);
  core_.stream.submitAndWait();
  const auto* bytes = static_cast<const unsigned char*>(staging.mapped());
  out.nodes = {reinterpret_cast<const gpu::Node*>(bytes), count};
  out.kind = core_.params.payload;
  if (payload_bytes)
    out.payload = {reinterpret_cast<const std::uint32_t*>(bytes + node_bytes), count};
  out.memory = std::move(owner);
  out.changed.resize(listed);
  if (listed) std::memcpy(out.changed.data(), bytes + node_bytes + payload_bytes, listed * 4);
  std::sort(out.changed.begin(), out.changed.end());
  const auto* f = reinterpret_cast<const gpu::FoldedNode*>(bytes + at);
  for (std::size_t i = 0; i < folded; ++i)
    out.folded.push_back(PoolCapture::Folded::of(f[i].key_xy, f[i].key_z_depth));
  return out;
}

// The pool a tree of `blocks` blocks is uploaded into: a quarter more for the next scans, at least
// an empty map's, at most the limit.
std::uint32_t TreeTransfer::capacityFor(std::uint64_t blocks) const {
  return static_cast<std::uint32_t>(std::min<std::uint64_t>(
      core_.buffers.blockLimit(), std::max<std::uint64_t>(blocks + blocks / 4, kInitialBlocks)));
}

void TreeTransfer::compact() {
  const gpu::PoolState pool = core_.readPool();
  const std::uint64_t held = std::uint64_t{pool.bump} - pool.free_count;
  const std::uint32_t capacity = capacityFor(held);
  // Worth a round trip only when it gives back a fifth of the pool or more.
  if (std::uint64_t{capacity} * 5 > std::uint64_t{core_.buffers.poolBlocks()} * 4) return;
  upload(compactHostTree(download()), /*shrink=*/true);
}

void TreeTransfer::upload(const HostTree& tree, bool shrink, std::span<const std::uint32_t> evicted,
                          std::uint64_t room) {
  if (tree.payload != core_.params.payload)
    throw Error(ErrorCode::kInvalidArgument,
                std::string("upload: the tree is a ") + treeTypeName(tree.payload) +
                    " and the map a " + treeTypeName(core_.params.payload) +
                    "; upload a tree of the map's type (HostTree::payload), or make the map "
                    "with the tree's payload");
  const std::size_t blocks = std::max<std::size_t>((tree.nodes.size() + 7) / 8, 1);
  if (blocks > core_.buffers.blockLimit())
    throw Error(ErrorCode::kOutOfDeviceMemory,
                "upload: the tree needs " + std::to_string(blocks * 8) +
                    " pool nodes, over the limit of " +
                    std::to_string(core_.buffers.blockLimit() * 8ull) +
                    " (MapParams::max_nodes or 2^32); the map is unchanged");
  PoolImage image = poolImageFromTree(tree);
  for (const std::uint32_t n : evicted) {
    if (n >= image.nodes.size() || (image.nodes[n].link & gpu::kBlockMask) != gpu::kNoChildren)
      throw Error(ErrorCode::kInternal, "internal error: an evicted tile's node has children");
    image.nodes[n].link |= gpu::kFlagEvicted;
  }
  // The staging first: once the pool is replaced (its old nodes not copied) nothing else may
  // fail, or the map would be neither the old tree nor the new one.
  const std::size_t node_bytes = image.nodes.size() * sizeof(gpu::Node);
  const std::size_t meta_bytes = image.parents.size() * sizeof(std::uint32_t);
  const std::size_t free_bytes = image.free_blocks.size() * sizeof(std::uint32_t);
  const std::size_t payload_bytes = image.payload.size() * sizeof(std::uint32_t);
  vk::Buffer staging(core_.device, node_bytes + meta_bytes + free_bytes + payload_bytes, true);
  auto* bytes = static_cast<unsigned char*>(staging.mapped());
  std::memcpy(bytes, image.nodes.data(), node_bytes);
  std::memcpy(bytes + node_bytes, image.parents.data(), meta_bytes);
  if (free_bytes)
    std::memcpy(bytes + node_bytes + meta_bytes, image.free_blocks.data(), free_bytes);
  if (payload_bytes)
    std::memcpy(bytes + node_bytes + meta_bytes + free_bytes, image.payload.data(), payload_bytes);
  scenes_.releaseUnderCap();
  const std::uint64_t needed = std::uint64_t{image.blocks} + room;
  const std::uint32_t capacity = capacityFor(needed);
  if (capacity > core_.buffers.poolBlocks() || (shrink && capacity < core_.buffers.poolBlocks()))
    core_.buffers.allocatePoolAtLeast(
        capacity,
        static_cast<std::uint32_t>(std::max<std::uint64_t>(
            std::min<std::uint64_t>(needed, core_.buffers.blockLimit()), 2)),
        /*copy_old=*/false);
  gpu::PoolState pool{};
  pool.bump = image.blocks;
  pool.capacity = core_.buffers.poolBlocks();
  pool.free_count = static_cast<std::uint32_t>(image.free_blocks.size());
  pool.root_exists = image.root_exists ? 1u : 0u;
  pool.live_nodes = image.live_nodes;

  const gpu::ScanParams sp = core_.queryParams();
  core_.stream.begin(core_.buffers.bindings);
  core_.rec.setParams(sp);
  core_.stream.update(core_.buffers.pool, &pool, sizeof(pool));
  core_.stream.copy(staging, core_.buffers.nodes, node_bytes);
  core_.stream.copy(staging, core_.buffers.block_parents, meta_bytes, node_bytes);
  core_.stream.copy(staging, core_.buffers.free_stack, free_bytes, node_bytes + meta_bytes);
  if (payload_bytes)
    core_.stream.copy(staging, core_.buffers.payload, payload_bytes,
                      node_bytes + meta_bytes + free_bytes);
  core_.stream.submitAndWait();
  // The leaf boxes are rebuilt when next asked for (refreshLeafBoxes), as after an edit: a
  // store's writer uploads a whole map whenever another writer committed, and reads none.
  core_.leaf_boxes = LeafBoxes::kStale;
  core_.treeChanged();  // a new tree
}

std::vector<OccupancyMap::LeafBoxHost> TreeTransfer::downloadLeafBoxes() {
  core_.refreshLeafBoxes();
  const gpu::PoolState pool = core_.readPool();
  std::vector<OccupancyMap::LeafBoxHost> out(pool.leaf_count);
  if (out.empty()) return out;
  const std::size_t bytes = out.size() * sizeof(gpu::LeafBox);
  vk::Buffer staging(core_.device, bytes, true);
  core_.stream.begin(core_.buffers.bindings);
  core_.stream.copy(core_.buffers.leaf_boxes, staging, bytes);
  core_.stream.submitAndWait();
  static_assert(sizeof(OccupancyMap::LeafBoxHost) == sizeof(gpu::LeafBox));
  std::memcpy(out.data(), staging.mapped(), bytes);
  return out;
}

}  // namespace octovk
