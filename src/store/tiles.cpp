// Tiles of a host tree and the tree rebuilt from them (tiles.hpp).
#include "store/tiles.hpp"

#include <octomap/OcTree.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <cstring>
#include <limits>
#include <optional>
#include <variant>

#include "gpu/gpu_types.h"
#include "io/parse.hpp"
#include "map/host_tree.hpp"
#include "map/pool_capture.hpp"

namespace octovk::store {

namespace {

constexpr unsigned kTreeDepth = 16;
constexpr std::size_t kRecordBytes = sizeof(float) + 1;

HostTree::Node leafNode(float log_odds) {
  HostTree::Node n = emptyHostNode();
  n.log_odds = log_odds;
  return n;
}

void checkTileDepth(unsigned tile_depth) {
  if (tile_depth < 1 || tile_depth > kTreeDepth)
    throw Error(ErrorCode::kInvalidArgument,
                "tile depth " + std::to_string(tile_depth) + " is not in 1..16");
}

std::string tileName(std::uint64_t key) {
  const Key corner = tileKeyCorner(key);
  return "tile " + std::to_string(key) + " (depth " + std::to_string(tileKeyDepth(key)) +
         ", corner key " + std::to_string(corner[0]) + " " + std::to_string(corner[1]) + " " +
         std::to_string(corner[2]) + ")";
}

// A tree's nodes as the cut reads them: log-odds, child bits and children's block. Over a host
// tree, or over a device pool as captured (child bits from the children's kFlagLive).
struct NodeView {
  float log_odds;
  std::uint32_t mask;
  std::size_t children;  // block
};

Error linkError(std::size_t index, std::size_t size) {
  return Error(ErrorCode::kFormat, "host tree: a link leads to node " + std::to_string(index) +
                                       " of " + std::to_string(size));
}

struct HostTreeNodes {
  const HostTree& tree;
  NodeView operator()(std::size_t index) const {
    if (index >= tree.nodes.size()) throw linkError(index, tree.nodes.size());
    const HostTree::Node& n = tree.nodes[index];
    return {n.log_odds, n.mask & 0xFFu, n.children};
  }
};

struct PoolNodes {
  const PoolCapture& pool;
  NodeView operator()(std::size_t index) const {
    const std::size_t size = pool.nodes.size();
    if (index >= size) throw linkError(index, size);
    const gpu::Node& n = pool.nodes[index];
    const std::size_t block = n.link & gpu::kBlockMask;
    std::uint32_t mask = 0;
    if (block != gpu::kNoChildren) {
      if (block * 8 + 8 > size) throw linkError(block * 8, size);
      for (unsigned s = 0; s < 8; ++s)
        if (pool.nodes[block * 8 + s].link & gpu::kFlagLive) mask |= 1u << s;
    }
    return {n.log_odds, mask, block};
  }
};

// Writes node `index` at `depth` and its subtree as .ot records (depth <= 16).
template <class Nodes>
void appendRecords(const Nodes& nodes, std::size_t index, unsigned depth, std::string& out) {
  const NodeView n = nodes(index);
  const std::uint32_t mask = depth < kTreeDepth ? n.mask : 0u;
  char record[kRecordBytes];
  std::memcpy(record, &n.log_odds, sizeof(float));
  record[sizeof(float)] = static_cast<char>(mask);
  out.append(record, kRecordBytes);
  for (unsigned i = 0; i < 8; ++i)
    if (mask & (1u << i)) appendRecords(nodes, n.children * 8 + i, depth + 1, out);
}

// Visits the tiles under node `index` (at `depth`, reached by `path`) in key order:
// visit(key, index, depth) for each node at the tile depth and each leaf above it.
template <class Nodes, class Visit>
void cut(const Nodes& nodes, std::size_t index, unsigned depth, std::uint64_t path,
         unsigned tile_depth, Visit&& visit) {
  const NodeView n = nodes(index);
  if (depth == tile_depth || n.mask == 0) {
    visit(tileKey(depth, path), index, depth);
    return;
  }
  for (unsigned i = 0; i < 8; ++i)
    if (n.mask & (1u << i))
      cut(nodes, n.children * 8 + i, depth + 1, (path << 3) | i, tile_depth, visit);
}

// The node above the tile depth, while the tree is rebuilt: a child is another such node
// (index >= 0), a tile (-2 - its index) or none (-1).
struct Upper {
  std::array<std::int64_t, 8> child;
  bool leaf = false;  // pruned, or a tile's leaf
  float log_odds = 0.0f;
};

class Rebuild {
 public:
  Rebuild(std::span<const Tile> tiles, unsigned tile_depth)
      : tiles_(tiles), tile_depth_(tile_depth) {}

  HostTree run() {
    HostTree tree;
    if (tiles_.empty()) return tree;
    // A tile at depth 0 is the whole tree: a root leaf.
    std::vector<std::size_t> order(tiles_.size());
    for (std::size_t i = 0; i < order.size(); ++i) order[i] = i;
    std::sort(order.begin(), order.end(),
              [&](std::size_t a, std::size_t b) { return tiles_[a].key < tiles_[b].key; });
    upper_.push_back(emptyUpper());
    for (std::size_t t : order) place(t);
    tree.root_exists = true;
    // A block of 8 per node with children: the upper nodes, and the records whose child byte
    // is set (a damaged body only makes the guess wrong; readRecords checks it).
    std::size_t blocks = 1 + upper_.size();
    for (const Tile& tile : tiles_)
      for (std::size_t at = sizeof(float); at < tile.body.size(); at += kRecordBytes)
        blocks += tile.body[at] != 0;
    tree.nodes.reserve(blocks * 8);
    tree.nodes.assign(8, leafNode(0.0f));
    if (root_tile_) {
      std::size_t at = 0;
      readRecords(*root_tile_, at, 0, 0, tree);
      finishBody(*root_tile_, at);
      return tree;
    }
    resolve(0);
    emit(0, 0, tree);
    return tree;
  }

 private:
  static Upper emptyUpper() {
    Upper u;
    u.child.fill(-1);
    return u;
  }

  // Hangs tile `t` under the upper nodes on its path, creating them.
  void place(std::size_t t) {
    const std::uint64_t key = tiles_[t].key;
    const unsigned depth = tileKeyDepth(key);
    if (depth > tile_depth_ || tileKey(depth, pathOf(key)) != key)
      throw bad(t, "its key is no tile key of depth at most " + std::to_string(tile_depth_));
    if (depth < tile_depth_) {
      // A leaf above the tile depth: one record without children.
      if (tiles_[t].body.size() != kRecordBytes || tiles_[t].body[sizeof(float)] != 0)
        throw bad(t, "it lies above the tile depth but is not one leaf record");
    }
    if (depth == 0) {
      if (tiles_.size() != 1) throw bad(t, "it is the root leaf, yet other tiles exist");
      root_tile_ = t;
      return;
    }
    const std::uint64_t path = pathOf(key);
    std::size_t node = 0;
    for (unsigned d = 1; d <= depth; ++d) {
      const unsigned slot = static_cast<unsigned>(path >> (3 * (depth - d))) & 7u;
      std::int64_t& child = upper_[node].child[slot];
      if (d == depth) {
        if (child != -1) throw bad(t, "another tile already covers its place");
        child = -2 - static_cast<std::int64_t>(t);
        return;
      }
      if (child < -1) throw bad(t, "it lies inside another tile");
      if (child == -1) {
        child = static_cast<std::int64_t>(upper_.size());
        node = upper_.size();
        upper_.push_back(emptyUpper());  // `child` dangles from here on
      } else {
        node = static_cast<std::size_t>(child);
      }
    }
  }

  // The upper node's log-odds and whether OctoMap's pruning makes it a leaf, bottom up.
  void resolve(std::size_t node) {
    bool all_leaves = true;
    float first = 0.0f;
    float max = -std::numeric_limits<float>::max();  // OcTreeNode::getMaxChildLogOdds
    for (unsigned i = 0; i < 8; ++i) {
      const std::int64_t c = upper_[node].child[i];
      if (c == -1) {
        all_leaves = false;
        continue;
      }
      bool leaf;
      float v;
      if (c >= 0) {
        resolve(static_cast<std::size_t>(c));
        leaf = upper_[static_cast<std::size_t>(c)].leaf;
        v = upper_[static_cast<std::size_t>(c)].log_odds;
      } else {
        const std::string& body = tiles_[static_cast<std::size_t>(-2 - c)].body;
        if (body.size() < kRecordBytes) throw bad(static_cast<std::size_t>(-2 - c), "it is empty");
        std::memcpy(&v, body.data(), sizeof(float));
        leaf = body[sizeof(float)] == 0;
      }
      if (i == 0) first = v;
      if (!leaf || v != first) all_leaves = false;
      if (v > max) max = v;
    }
    upper_[node].leaf = all_leaves;  // OcTree::isNodeCollapsible: 8 equal leaves
    upper_[node].log_odds = all_leaves ? first : max;
  }

  // Writes upper node `node` into host node `index`.
  void emit(std::size_t node, std::size_t index, HostTree& tree) {
    const Upper& u = upper_[node];
    tree.nodes[index] = leafNode(u.log_odds);
    if (u.leaf) return;
    const auto block = static_cast<std::uint32_t>(tree.nodes.size() / 8);
    tree.nodes.resize(tree.nodes.size() + 8, leafNode(0.0f));
    std::uint32_t mask = 0;
    for (unsigned i = 0; i < 8; ++i)
      if (u.child[i] != -1) mask |= 1u << i;
    tree.nodes[index].children = block;
    tree.nodes[index].mask = mask;
    const unsigned depth = depthOf(node);
    for (unsigned i = 0; i < 8; ++i) {
      const std::int64_t c = u.child[i];
      if (c >= 0) {
        depth_[static_cast<std::size_t>(c)] = depth + 1;
        emit(static_cast<std::size_t>(c), std::size_t{block} * 8 + i, tree);
      } else if (c < -1) {
        const auto t = static_cast<std::size_t>(-2 - c);
        std::size_t at = 0;
        readRecords(t, at, depth + 1, std::size_t{block} * 8 + i, tree);
        finishBody(t, at);
      }
    }
  }

  unsigned depthOf(std::size_t node) {
    if (depth_.size() < upper_.size()) depth_.resize(upper_.size(), 0);
    return depth_[node];
  }

  // Reads the record at `at` of tile `t` and its subtree into host node `index`, at `depth`.
  void readRecords(std::size_t t, std::size_t& at, unsigned depth, std::size_t index,
                   HostTree& tree) {
    const std::string& body = tiles_[t].body;
    if (at + kRecordBytes > body.size())
      throw bad(t, "the record at byte " + std::to_string(at) + " runs past its end");
    float v;
    std::memcpy(&v, body.data() + at, sizeof(float));
    if (!std::isfinite(v))
      throw bad(t, "the record at byte " + std::to_string(at) +
                       " has a log-odds that is not a "
                       "finite number");
    const auto mask = static_cast<unsigned char>(body[at + sizeof(float)]);
    if (mask != 0 && depth >= kTreeDepth)
      throw bad(t, "the record at byte " + std::to_string(at) +
                       " has children below the tree's 16 levels");
    at += kRecordBytes;
    tree.nodes[index] = leafNode(v);
    if (mask == 0) return;
    const auto block = static_cast<std::uint32_t>(tree.nodes.size() / 8);
    tree.nodes.resize(tree.nodes.size() + 8, leafNode(0.0f));
    tree.nodes[index].children = block;
    tree.nodes[index].mask = mask;
    for (unsigned i = 0; i < 8; ++i)
      if (mask & (1u << i)) readRecords(t, at, depth + 1, std::size_t{block} * 8 + i, tree);
  }

  void finishBody(std::size_t t, std::size_t at) const {
    if (at != tiles_[t].body.size())
      throw bad(t,
                std::to_string(tiles_[t].body.size() - at) + " bytes follow its last node record");
  }

  static std::uint64_t pathOf(std::uint64_t key) {
    const unsigned depth = tileKeyDepth(key);
    return depth > kTreeDepth ? 0 : (key >> 5) >> (3 * (kTreeDepth - depth));
  }

  Error bad(std::size_t t, const std::string& why) const {
    return Error(ErrorCode::kFormat, tileName(tiles_[t].key) + " is damaged: " + why);
  }

  std::span<const Tile> tiles_;
  unsigned tile_depth_;
  std::vector<Upper> upper_;
  std::vector<unsigned> depth_;
  std::optional<std::size_t> root_tile_;
};

}  // namespace

std::uint64_t tileKey(unsigned depth, std::uint64_t path) {
  return ((path << (3 * (kTreeDepth - depth))) << 5) | depth;
}

unsigned tileKeyDepth(std::uint64_t key) { return static_cast<unsigned>(key & 31u); }

Key tileKeyCorner(std::uint64_t key) {
  const std::uint64_t morton = key >> 5;  // 16 levels of 3 bits, level 1 highest
  Key k{0, 0, 0};
  for (unsigned level = 0; level < kTreeDepth; ++level) {
    const unsigned slot = static_cast<unsigned>(morton >> (3 * (kTreeDepth - 1 - level))) & 7u;
    for (unsigned a = 0; a < 3; ++a)  // OctoMap's child index: x bit 0, y bit 1, z bit 2
      if (slot & (1u << a))
        k[a] = static_cast<std::uint16_t>(k[a] | (1u << (kTreeDepth - 1 - level)));
  }
  return k;
}

std::vector<Tile> tilesOf(const HostTree& tree, unsigned tile_depth) {
  checkTileDepth(tile_depth);
  if (tree.payload != Payload::kNone)
    throw Error(ErrorCode::kInvalidArgument,
                std::string("a store holds plain occupancy maps (OcTree), not ") +
                    treeTypeName(tree.payload) + " maps");
  std::vector<Tile> tiles;
  const HostTreeNodes nodes{tree};
  if (tree.root_exists)
    cut(nodes, 0, 0, 0, tile_depth, [&](std::uint64_t key, std::size_t index, unsigned depth) {
      Tile& tile = tiles.emplace_back();
      tile.key = key;
      appendRecords(nodes, index, depth, tile.body);
    });
  return tiles;  // depth first: in key order
}

std::vector<PoolTile> poolTiles(const PoolCapture& pool, unsigned tile_depth) {
  checkTileDepth(tile_depth);
  std::vector<PoolTile> tiles;
  if (pool.root_exists)
    cut(PoolNodes{pool}, 0, 0, 0, tile_depth,
        [&](std::uint64_t key, std::size_t index, unsigned depth) {
          tiles.push_back({key, static_cast<std::uint32_t>(index), depth});
        });
  return tiles;
}

std::string poolTileBody(const PoolCapture& pool, const PoolTile& tile) {
  std::string body;
  appendRecords(PoolNodes{pool}, tile.node, tile.depth, body);
  return body;
}

HostTree treeFromTiles(std::span<const Tile> tiles, unsigned tile_depth) {
  checkTileDepth(tile_depth);
  return Rebuild(tiles, tile_depth).run();
}

std::string nodeStream(const HostTree& tree) {
  std::string out;
  if (tree.root_exists) appendRecords(HostTreeNodes{tree}, 0, 0, out);
  return out;
}

std::unique_ptr<octomap::OcTree> ocTreeOf(const HostTree& tree, const MapParams& params) {
  std::unique_ptr<octomap::OcTree> out = std::get<std::unique_ptr<octomap::OcTree>>(
      io::parseTreeBody(nodeStream(tree), /*binary=*/false, "OcTree", params.resolution, "store"));
  out->setProbHit(params.prob_hit);
  out->setProbMiss(params.prob_miss);
  out->setClampingThresMin(params.clamping_min);
  out->setClampingThresMax(params.clamping_max);
  out->setOccupancyThres(params.occupancy_threshold);
  return out;
}

}  // namespace octovk::store
