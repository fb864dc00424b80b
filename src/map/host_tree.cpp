#include "map/host_tree.hpp"

#include <algorithm>
#include <cmath>
#include <string>

namespace octovk {

HostTree::Node emptyHostNode() { return {0.0f, gpu::kNoBlock, 0, 0}; }

gpu::Node emptyPoolNode() { return {0.0f, gpu::kNoChildren}; }

void copyNodeData(const gpu::Node& from, HostTree::Node& to) { to.log_odds = from.log_odds; }

void copyNodeData(const HostTree::Node& from, gpu::Node& to) { to.log_odds = from.log_odds; }

void copyNodeData(const HostTree::Node& from, HostTree::Node& to) {
  to.log_odds = from.log_odds;
  to.payload = from.payload;
}

void checkNodeData(const HostTree::Node& node, std::size_t index, const char* call) {
  // As the .ot reader: a value that no update can give would make a file no reader takes.
  if (!std::isfinite(node.log_odds))
    throw Error(ErrorCode::kFormat, std::string(call) + ": node " + std::to_string(index) +
                                        " has a log-odds of " + std::to_string(node.log_odds) +
                                        "; every node's log-odds must be a finite number");
}

HostTree hostTreeFromPool(std::span<const gpu::Node> nodes, std::span<const std::uint32_t> payload,
                          Payload kind, const gpu::PoolState& pool) {
  HostTree tree;
  tree.payload = kind;
  tree.root_exists = pool.root_exists != 0;
  const std::size_t count = std::min<std::size_t>(std::size_t{pool.bump} * 8, nodes.size());
  // Device nodes keep a node's existence in the node itself (kFlagLive); the host tree keeps a
  // parent's child bits.
  tree.nodes.resize(count);
  for (std::size_t i = 0; i < count; ++i) {
    const std::uint32_t block = nodes[i].link & gpu::kBlockMask;
    HostTree::Node& n = tree.nodes[i];
    n = emptyHostNode();
    copyNodeData(nodes[i], n);
    if (i < payload.size()) n.payload = payload[i];
    if (block == gpu::kNoChildren || block >= pool.bump || std::size_t{block} * 8 + 8 > count)
      continue;
    n.children = block;
    for (std::uint32_t s = 0; s < 8; ++s)
      if (nodes[std::size_t{block} * 8 + s].link & gpu::kFlagLive) n.mask |= 1u << s;
  }
  // Free blocks keep stale contents; only what hangs from the root is the tree.
  return tree;
}

HostTree compactHostTree(const HostTree& tree) {
  HostTree out;
  out.root_exists = tree.root_exists;
  out.payload = tree.payload;
  // Block 0 holds the root (its other slots are unused), as in every pool.
  out.nodes.assign(8, emptyHostNode());
  if (!tree.root_exists || tree.nodes.size() < 8) return out;
  struct Move {
    std::size_t from, to;
  };
  std::vector<Move> queue{{gpu::kRootNode, gpu::kRootNode}};
  for (std::size_t next = 0; next < queue.size(); ++next) {
    const Move m = queue[next];
    const HostTree::Node& n = tree.nodes[m.from];
    copyNodeData(n, out.nodes[m.to]);
    if ((n.mask & gpu::kChildMask) == 0) continue;
    if (n.children == 0 || std::size_t{n.children} * 8 + 8 > tree.nodes.size() ||
        out.nodes.size() + 8 > tree.nodes.size() + 8)
      throw Error(ErrorCode::kInternal, "compact: the downloaded tree links outside its nodes");
    const std::size_t block = out.nodes.size() / 8;
    out.nodes[m.to].children = static_cast<std::uint32_t>(block);
    out.nodes[m.to].mask = n.mask & gpu::kChildMask;
    out.nodes.resize(out.nodes.size() + 8, emptyHostNode());
    for (std::uint32_t s = 0; s < 8; ++s)
      if (n.mask & (1u << s)) queue.push_back({std::size_t{n.children} * 8 + s, block * 8 + s});
  }
  return out;
}

PoolImage poolImageFromTree(const HostTree& tree) {
  PoolImage image;
  const std::size_t blocks = std::max<std::size_t>((tree.nodes.size() + 7) / 8, 1);
  if (blocks > 0x1FFFFFFFu)
    throw Error(ErrorCode::kOutOfDeviceMemory,
                "upload: the tree has more than 2^32 nodes, more than a map can hold");
  image.blocks = static_cast<std::uint32_t>(blocks);
  image.parents.assign(blocks, gpu::kNoBlock);
  image.nodes.assign(blocks * 8, emptyPoolNode());
  if (tree.payload != Payload::kNone)
    image.payload.assign(blocks * 8, newNodePayload(tree.payload));
  image.root_exists = tree.root_exists;
  if (tree.root_exists) {
    if (tree.nodes.empty()) throw Error(ErrorCode::kFormat, "upload: the tree has no root node");
    // Walk from the root: each node that hangs in the tree exists (kFlagLive) and each child
    // block records its parent.
    struct Item {
      std::uint32_t node, depth;
    };
    std::vector<Item> stack{{gpu::kRootNode, 0}};
    while (!stack.empty()) {
      const Item it = stack.back();
      stack.pop_back();
      ++image.live_nodes;
      const HostTree::Node& n = tree.nodes[it.node];
      checkNodeData(n, it.node, "upload");
      gpu::Node& g = image.nodes[it.node];
      copyNodeData(n, g);
      if (!image.payload.empty()) image.payload[it.node] = n.payload;
      g.link = gpu::kNoChildren | gpu::kFlagLive;
      if ((n.mask & gpu::kChildMask) == 0) continue;
      if (it.depth >= gpu::kTreeDepth)
        throw Error(ErrorCode::kFormat, "upload: the tree has nodes below depth 16");
      if (n.children >= blocks || n.children == 0 ||
          std::size_t{n.children} * 8 + 8 > tree.nodes.size())
        throw Error(ErrorCode::kFormat, "upload: the tree has a child block outside its nodes");
      if (image.parents[n.children] != gpu::kNoBlock)
        throw Error(ErrorCode::kFormat,
                    "upload: the tree has a child block shared by two nodes (a cycle or a copy)");
      g.link = n.children | gpu::kFlagLive;
      image.parents[n.children] = it.node;
      for (std::uint32_t s = 0; s < 8; ++s)
        if (n.mask & (1u << s)) stack.push_back({n.children * 8 + s, it.depth + 1});
    }
  }
  // Blocks that nothing points at go onto the free stack.
  for (std::uint32_t b = 1; b < blocks; ++b)
    if (image.parents[b] == gpu::kNoBlock) image.free_blocks.push_back(b);
  return image;
}

SubtreeSize subtreeSize(const HostTree& tree, std::uint32_t node) {
  SubtreeSize size;
  std::vector<std::uint32_t> stack{node};
  while (!stack.empty()) {
    const HostTree::Node& n = tree.nodes[stack.back()];
    stack.pop_back();
    ++size.nodes;
    if ((n.mask & gpu::kChildMask) == 0) continue;
    ++size.blocks;
    for (std::uint32_t s = 0; s < 8; ++s)
      if (n.mask & (1u << s)) stack.push_back(n.children * 8 + s);
  }
  return size;
}

void averageInnerColors(HostTree& tree) {
  if (tree.payload != Payload::kColor || !tree.root_exists || tree.nodes.empty()) return;
  // Children before parents: a depth-first order reversed.
  std::vector<std::uint32_t> order{gpu::kRootNode};
  for (std::size_t i = 0; i < order.size(); ++i) {
    const HostTree::Node& n = tree.nodes[order[i]];
    if ((n.mask & gpu::kChildMask) == 0) continue;
    for (std::uint32_t s = 0; s < 8; ++s)
      if (n.mask & (1u << s)) order.push_back(n.children * 8 + s);
  }
  for (auto it = order.rbegin(); it != order.rend(); ++it) {
    HostTree::Node& n = tree.nodes[*it];
    if ((n.mask & gpu::kChildMask) == 0) continue;
    ChildColorMean mean;
    for (std::uint32_t s = 0; s < 8; ++s)
      if (n.mask & (1u << s)) mean.add(tree.nodes[n.children * 8 + s].payload);
    n.payload = mean.value();
  }
}

}  // namespace octovk
