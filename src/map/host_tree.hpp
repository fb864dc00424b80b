// The tree between its device form (node pool: nodes with a live flag and a child-block link,
// block parents, free-block stack) and the host form of HostTree, converted on the host with no
// device, so it is testable on its own.
#pragma once

#include <cstddef>
#include <cstdint>
#include <span>
#include <vector>

#include "gpu/gpu_types.h"
#include "octovk/octovk.hpp"

namespace octovk {

// ---- a node's data: its log-odds ----
// Every copy, creation and check of a node's data on the host goes through these (with their
// OctoMap twins in src/io/octomap_io.cpp and the .ot record in src/io/tree_file.cpp), so that a
// payload (colour, time stamp) is added here, not in each conversion. The link words and child
// masks, the tree's shape, are the conversions' own.

/// A host node without children that holds a new node's data (log-odds 0).
HostTree::Node emptyHostNode();
/// A pool node without children, not live, that holds a new node's data.
gpu::Node emptyPoolNode();
/// `from`'s data given to `to` (download, upload and compact); `to`'s links are kept.
void copyNodeData(const gpu::Node& from, HostTree::Node& to);
void copyNodeData(const HostTree::Node& from, gpu::Node& to);
void copyNodeData(const HostTree::Node& from, HostTree::Node& to);
/// Throws kFormat, naming node `index` and `call`, when its data is nothing an update can give
/// (a log-odds that is not a finite number).
void checkNodeData(const HostTree::Node& node, std::size_t index, const char* call);

/// The tree that hangs from the root of a downloaded pool (`nodes`: the first pool.bump blocks;
/// `payload`: their payload words, empty for Payload::kNone).
HostTree hostTreeFromPool(std::span<const gpu::Node> nodes, std::span<const std::uint32_t> payload,
                          Payload kind, const gpu::PoolState& pool);

/// Nodes and blocks (nodes with children, each one block of 8 slots in a pool) of the subtree
/// under `node`, `node` included; its leaves are nodes - blocks.
struct SubtreeSize {
  std::uint64_t nodes = 0, blocks = 0;
};
SubtreeSize subtreeSize(const HostTree& tree, std::uint32_t node);

/// ColorOcTree::updateInnerOccupancy's colours: every inner node that hangs from the root takes
/// the integer mean of its children's set colours (white where none is set), bottom up. The
/// device leaves inner colours as OctoMap's updates leave them; a download gives these. Does
/// nothing unless tree.payload is kColor.
void averageInnerColors(HostTree& tree);

/// ColorOcTreeNode::getAverageChildColor over the children's packed colours given to add():
/// the integer mean per channel of those whose colour is set (not white), white when none is.
class ChildColorMean {
 public:
  void add(std::uint32_t color) {
    if ((color & 0xFFFFFFu) == 0xFFFFFFu) return;
    r_ += static_cast<int>(color & 0xFFu);
    g_ += static_cast<int>((color >> 8) & 0xFFu);
    b_ += static_cast<int>((color >> 16) & 0xFFu);
    ++count_;
  }
  std::uint32_t value() const {
    if (count_ == 0) return 0x00FFFFFFu;
    return static_cast<std::uint32_t>(r_ / count_) |
           (static_cast<std::uint32_t>(g_ / count_) << 8) |
           (static_cast<std::uint32_t>(b_ / count_) << 16);
  }

 private:
  int r_ = 0, g_ = 0, b_ = 0, count_ = 0;
};

/// The same tree with its blocks renumbered in breadth-first order from the root, with no block
/// that nothing points at: what compact() uploads. Throws kInternal on a tree whose links leave
/// its nodes or come back to a block (the device's tree never does).
HostTree compactHostTree(const HostTree& tree);

/// A HostTree as the device pool holds it, ready to upload.
struct PoolImage {
  std::vector<gpu::Node> nodes;            ///< blocks * 8
  std::vector<std::uint32_t> payload;      ///< blocks * 8 payload words (empty for kNone)
  std::vector<std::uint32_t> parents;      ///< per block, the node it hangs under, or kNoBlock
  std::vector<std::uint32_t> free_blocks;  ///< blocks nothing points at (block 0 excepted)
  std::uint32_t blocks = 0;
  std::uint32_t live_nodes = 0;
  bool root_exists = false;
};
/// Checks `tree` (depth at most 16, child blocks inside it, none shared) and lays it out for the
/// pool; throws kFormat naming what is wrong.
PoolImage poolImageFromTree(const HostTree& tree);

}  // namespace octovk
