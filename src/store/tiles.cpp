// Tiles of a host tree and the tree rebuilt from them (tiles.hpp).
#include "store/tiles.hpp"

#include <octomap/OcTree.h>

#include <algorithm>
#include <array>
#include <bit>
#include <cmath>
#include <cstring>
#include <functional>
#include <limits>
#include <optional>
#include <unordered_map>
#include <variant>

#include "gpu/gpu_types.h"
#include "io/parse.hpp"
#include "map/host_tree.hpp"
#include "map/pool_capture.hpp"

namespace octovk::store {

namespace {

constexpr unsigned kTreeDepth = 16;
constexpr std::size_t kPlainRecordBytes = sizeof(float) + 1;

// A record's payload bytes (after the log-odds): r, g, b; or the stamp, little-endian.
void putPayload(char* at, Payload kind, std::uint32_t v) {
  const unsigned bytes = kind == Payload::kColor ? 3 : kind == Payload::kStamp ? 4 : 0;
  for (unsigned i = 0; i < bytes; ++i) at[i] = static_cast<char>((v >> (8 * i)) & 0xFFu);
}
std::uint32_t getPayload(const char* at, Payload kind) {
  const unsigned bytes = kind == Payload::kColor ? 3 : kind == Payload::kStamp ? 4 : 0;
  std::uint32_t v = 0;
  for (unsigned i = 0; i < bytes; ++i)
    v |= std::uint32_t{static_cast<unsigned char>(at[i])} << (8 * i);
  return v;
}
std::uint64_t getLittle64(const char* at) {
  std::uint64_t v = 0;
  for (unsigned i = 0; i < 8; ++i) v |= std::uint64_t{static_cast<unsigned char>(at[i])} << (8 * i);
  return v;
}
constexpr std::size_t kUpperEntryBytes = 12;  // a key, a stamp

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
  std::uint32_t payload;
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
    return {n.log_odds, n.mask & 0xFFu, n.children, n.payload};
  }
};

struct PoolNodes {
  explicit PoolNodes(const PoolCapture& pool) : nodes(pool.nodes), payload(pool.payload) {}
  std::span<const gpu::Node> nodes;
  std::span<const std::uint32_t> payload;
  NodeView operator()(std::size_t index) const {
    const std::size_t size = nodes.size();
    if (index >= size) throw linkError(index, size);
    const gpu::Node& n = nodes[index];
    const std::size_t block = n.link & gpu::kBlockMask;
    std::uint32_t mask = 0;
    if (block != gpu::kNoChildren) {
      if (block * 8 + 8 > size) throw linkError(block * 8, size);
      static_assert(gpu::kFlagLive == 1u << 31);
      for (unsigned s = 0; s < 8; ++s) {
        const std::uint32_t link = nodes[block * 8 + s].link;
        mask |= (link >> 31) << s;
        // The grandchildren's blocks lie scattered through the pool (a store's commit
        // serialises about 17,000 nodes a scan of FR-079, most of its time cache misses on
        // them, one after another): their reads start now, side by side.
        const std::size_t grandchildren = link & gpu::kBlockMask;
        if (grandchildren != gpu::kNoChildren && grandchildren * 8 + 8 <= size)
          __builtin_prefetch(nodes.data() + grandchildren * 8);
      }
    }
    return {n.log_odds, mask, block, index < payload.size() ? payload[index] : 0u};
  }
};

// Writes node `index` at `depth` and its subtree as records of `kind` (depth <= 16) at the end of
// `out`; returns the payload written: a colour map's inner nodes take their children's mean
// colour (ColorOcTree::updateInnerOccupancy), whatever the device left there. The records go
// into the string in place, which grows in steps of its own size.
template <class Nodes>
class RecordWriter {
 public:
  RecordWriter(const Nodes& nodes, Payload kind, std::string& out)
      : nodes_(nodes), kind_(kind), record_(recordBytes(kind)), out_(out), used_(out.size()) {}
  ~RecordWriter() { out_.resize(used_); }  // the room beyond cut off
  RecordWriter(const RecordWriter&) = delete;
  RecordWriter& operator=(const RecordWriter&) = delete;

  std::uint32_t write(std::size_t index, unsigned depth) {
    const NodeView n = nodes_(index);
    const std::uint32_t mask = depth < kTreeDepth ? n.mask : 0u;
    if (used_ + record_ > out_.size()) out_.resize(std::max(2 * out_.size(), used_ + 2048));
    const std::size_t at = used_;
    used_ += record_;
    std::memcpy(out_.data() + at, &n.log_odds, sizeof(float));
    out_[at + record_ - 1] = static_cast<char>(mask);
    std::uint32_t payload = n.payload;
    ChildColorMean mean;
    for (std::uint32_t m = mask; m != 0; m &= m - 1)
      mean.add(write(n.children * 8 + static_cast<unsigned>(std::countr_zero(m)), depth + 1));
    if (kind_ == Payload::kColor && mask != 0) payload = mean.value();
    if (kind_ != Payload::kNone) putPayload(out_.data() + at + sizeof(float), kind_, payload);
    return payload;
  }

 private:
  const Nodes nodes_;  // small: a reference, or two spans
  Payload kind_;
  std::size_t record_;
  std::string& out_;
  std::size_t used_;
};

template <class Nodes>
void appendRecords(const Nodes& nodes, std::size_t index, unsigned depth, Payload kind,
                   std::string& out) {
  RecordWriter<Nodes>(nodes, kind, out).write(index, depth);
}

// Visits the tiles under node `index` (at `depth`, reached by `path`) in key order:
// visit(key, index, depth) for each node at the tile depth and each leaf above it, and
// upper(key, view) for each node above the tile depth that has children, before its tiles.
template <class Nodes, class Visit, class Upper>
void cut(const Nodes& nodes, std::size_t index, unsigned depth, std::uint64_t path,
         unsigned tile_depth, Visit&& visit, Upper&& upper) {
  const NodeView n = nodes(index);
  if (depth == tile_depth || n.mask == 0) {
    visit(tileKey(depth, path), index, depth);
    return;
  }
  upper(tileKey(depth, path), n);
  for (unsigned i = 0; i < 8; ++i)
    if (n.mask & (1u << i))
      cut(nodes, n.children * 8 + i, depth + 1, (path << 3) | i, tile_depth, visit, upper);
}

constexpr auto kNoUpper = [](std::uint64_t, const NodeView&) {};

// The upper stamps record's body: the stamps of the nodes above the tile depth with children.
template <class Nodes>
std::string upperStamps(const Nodes& nodes, unsigned tile_depth) {
  std::string body;
  cut(
      nodes, 0, 0, 0, tile_depth, [](std::uint64_t, std::size_t, unsigned) {},
      [&](std::uint64_t key, const NodeView& n) {
        char entry[kUpperEntryBytes];
        for (unsigned i = 0; i < 8; ++i) entry[i] = static_cast<char>((key >> (8 * i)) & 0xFFu);
        putPayload(entry + 8, Payload::kStamp, n.payload);
        body.append(entry, kUpperEntryBytes);
      });
  return body;  // keys ascending: a node's key is below its subtree's
}

// The node above the tile depth, while the tree is rebuilt: a child is another such node
// (index >= 0), a tile (-2 - its index) or none (-1).
struct Upper {
  std::array<std::int64_t, 8> child;
  bool leaf = false;  // pruned, or a tile's leaf
  float log_odds = 0.0f;
  std::uint32_t payload = 0;
};

class Rebuild {
 public:
  Rebuild(std::span<const Tile> tiles, unsigned tile_depth, Payload kind)
      : tiles_(tiles), tile_depth_(tile_depth), kind_(kind), record_(recordBytes(kind)) {}

  HostTree run() {
    HostTree tree;
    tree.payload = kind_;
    std::vector<std::size_t> order;
    order.reserve(tiles_.size());
    for (std::size_t i = 0; i < tiles_.size(); ++i) {
      if (tiles_[i].key != kUpperStampsKey) {
        order.push_back(i);
        continue;
      }
      readUpperStamps(i);
    }
    if (order.empty()) return tree;
    // A tile at depth 0 is the whole tree: a root leaf.
    std::sort(order.begin(), order.end(),
              [&](std::size_t a, std::size_t b) { return tiles_[a].key < tiles_[b].key; });
    tile_count_ = order.size();
    upper_.push_back(emptyUpper());
    for (std::size_t t : order) place(t);
    tree.root_exists = true;
    // A block of 8 per node with children: the upper nodes, and the records whose child byte
    // is set (a damaged body only makes the guess wrong; readRecords checks it).
    std::size_t blocks = 1 + upper_.size();
    for (const std::size_t t : order) {
      const std::string& body = tiles_[t].body;
      for (std::size_t at = record_ - 1; at < body.size(); at += record_) blocks += body[at] != 0;
    }
    tree.nodes.reserve(blocks * 8);
    tree.nodes.assign(8, leafNode(0.0f));
    if (root_tile_) {
      std::size_t at = 0;
      readRecords(*root_tile_, at, 0, 0, tree);
      finishBody(*root_tile_, at);
      return tree;
    }
    resolve(0, 0, 0);
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
      if (tiles_[t].body.size() != record_ || tiles_[t].body[record_ - 1] != 0)
        throw bad(t, "it lies above the tile depth but is not one leaf record");
    }
    if (depth == 0) {
      if (tile_count_ != 1) throw bad(t, "it is the root leaf, yet other tiles exist");
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

  // The upper node's log-odds and payload, and whether OctoMap's pruning makes it a leaf,
  // bottom up; `depth` and `path` make its key.
  void resolve(std::size_t node, unsigned depth, std::uint64_t path) {
    bool all_leaves = true;
    float first = 0.0f;
    std::uint32_t first_payload = 0;
    float max = -std::numeric_limits<float>::max();  // OcTreeNode::getMaxChildLogOdds
    std::uint32_t newest = 0;
    ChildColorMean mean;
    for (unsigned i = 0; i < 8; ++i) {
      const std::int64_t c = upper_[node].child[i];
      if (c == -1) {
        all_leaves = false;
        continue;
      }
      bool leaf;
      float v;
      std::uint32_t payload;
      if (c >= 0) {
        resolve(static_cast<std::size_t>(c), depth + 1, (path << 3) | i);
        const Upper& u = upper_[static_cast<std::size_t>(c)];
        leaf = u.leaf;
        v = u.log_odds;
        payload = u.payload;
      } else {
        const std::string& body = tiles_[static_cast<std::size_t>(-2 - c)].body;
        if (body.size() < record_) throw bad(static_cast<std::size_t>(-2 - c), "it is empty");
        std::memcpy(&v, body.data(), sizeof(float));
        payload = getPayload(body.data() + sizeof(float), kind_);
        leaf = body[record_ - 1] == 0;
      }
      if (i == 0) {
        first = v;
        first_payload = payload;
      }
      // OcTree compares log-odds only, ColorOcTree too; OcTreeStamped's operator== the stamps.
      if (!leaf || v != first || (kind_ == Payload::kStamp && payload != first_payload))
        all_leaves = false;
      if (v > max) max = v;
      newest = std::max(newest, payload);
      mean.add(payload);
    }
    Upper& u = upper_[node];
    u.leaf = all_leaves;  // isNodeCollapsible: 8 equal leaves
    u.log_odds = all_leaves ? first : max;
    switch (kind_) {
      case Payload::kNone:
        break;
      case Payload::kColor:
        // pruneNode: the first child's data, then, when that colour is set, the children's mean;
        // updateInnerOccupancy: the children's mean.
        u.payload =
            all_leaves && (first_payload & 0xFFFFFFu) == 0xFFFFFFu ? first_payload : mean.value();
        break;
      case Payload::kStamp:
        if (all_leaves) {
          u.payload = first_payload;  // pruneNode's copyData
        } else {
          const auto found = upper_stamps_.find(tileKey(depth, path));
          u.payload = found != upper_stamps_.end() ? found->second : newest;
        }
        break;
    }
  }

  // The upper stamps record (kUpperStampsKey) of tile `t`.
  void readUpperStamps(std::size_t t) {
    if (kind_ != Payload::kStamp) throw bad(t, "it holds stamps, but the map holds none");
    const std::string& body = tiles_[t].body;
    if (body.size() % kUpperEntryBytes != 0)
      throw bad(t, "its " + std::to_string(body.size()) + " bytes are no whole number of " +
                       std::to_string(kUpperEntryBytes) + "-byte entries");
    for (std::size_t at = 0; at < body.size(); at += kUpperEntryBytes)
      upper_stamps_[getLittle64(body.data() + at)] =
          getPayload(body.data() + at + 8, Payload::kStamp);
  }

  // Writes upper node `node` into host node `index`.
  void emit(std::size_t node, std::size_t index, HostTree& tree) {
    const Upper& u = upper_[node];
    tree.nodes[index] = leafNode(u.log_odds);
    tree.nodes[index].payload = u.payload;
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
    if (at + record_ > body.size())
      throw bad(t, "the record at byte " + std::to_string(at) + " runs past its end");
    float v;
    std::memcpy(&v, body.data() + at, sizeof(float));
    if (!std::isfinite(v))
      throw bad(t, "the record at byte " + std::to_string(at) +
                       " has a log-odds that is not a "
                       "finite number");
    const auto mask = static_cast<unsigned char>(body[at + record_ - 1]);
    if (mask != 0 && depth >= kTreeDepth)
      throw bad(t, "the record at byte " + std::to_string(at) +
                       " has children below the tree's 16 levels");
    const std::uint32_t payload = getPayload(body.data() + at + sizeof(float), kind_);
    at += record_;
    tree.nodes[index] = leafNode(v);
    tree.nodes[index].payload = payload;
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
  Payload kind_;
  std::size_t record_;
  std::size_t tile_count_ = 0;  // without the upper stamps record
  std::unordered_map<std::uint64_t, std::uint32_t> upper_stamps_;
  std::vector<Upper> upper_;
  std::vector<unsigned> depth_;
  std::optional<std::size_t> root_tile_;
};

}  // namespace

unsigned tileFormatOf(Payload payload) {
  switch (payload) {
    case Payload::kColor:
      return 2;
    case Payload::kStamp:
      return 3;
    case Payload::kNone:
      break;
  }
  return 1;
}

std::optional<Payload> payloadOfTileFormat(std::int64_t format) {
  for (const Payload p : {Payload::kNone, Payload::kColor, Payload::kStamp})
    if (format == tileFormatOf(p)) return p;
  return std::nullopt;
}

std::size_t recordBytes(Payload payload) {
  switch (payload) {
    case Payload::kColor:
      return kPlainRecordBytes + 3;
    case Payload::kStamp:
      return kPlainRecordBytes + 4;
    case Payload::kNone:
      break;
  }
  return kPlainRecordBytes;
}

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

std::uint64_t cellPath(const Key& key) {
  std::uint64_t path = 0;
  for (unsigned level = 0; level < kTreeDepth; ++level) {
    const unsigned bit = kTreeDepth - 1 - level;  // OctoMap's child index: x bit 0, y 1, z 2
    path = (path << 3) | ((key[0] >> bit) & 1u) | (((key[1] >> bit) & 1u) << 1) |
           (((key[2] >> bit) & 1u) << 2);
  }
  return path;
}

std::vector<Tile> tilesOf(const HostTree& tree, unsigned tile_depth) {
  checkTileDepth(tile_depth);
  std::vector<Tile> tiles;
  if (!tree.root_exists) return tiles;
  const HostTreeNodes nodes{tree};
  if (tree.payload == Payload::kStamp)
    if (std::string upper = upperStamps(nodes, tile_depth); !upper.empty())
      tiles.push_back({kUpperStampsKey, std::move(upper)});
  std::vector<Tile> cut_tiles;
  cut(
      nodes, 0, 0, 0, tile_depth,
      [&](std::uint64_t key, std::size_t index, unsigned depth) {
        Tile& tile = cut_tiles.emplace_back();
        tile.key = key;
        appendRecords(nodes, index, depth, tree.payload, tile.body);
      },
      kNoUpper);
  // Depth first: in key order. The record's key (31) sorts among them.
  tiles.insert(tiles.end(), std::make_move_iterator(cut_tiles.begin()),
               std::make_move_iterator(cut_tiles.end()));
  std::sort(tiles.begin(), tiles.end(), [](const Tile& a, const Tile& b) { return a.key < b.key; });
  return tiles;
}

std::vector<PoolTile> poolTiles(const PoolCapture& pool, unsigned tile_depth) {
  checkTileDepth(tile_depth);
  std::vector<PoolTile> tiles;
  if (pool.root_exists)
    cut(
        PoolNodes(pool), 0, 0, 0, tile_depth,
        [&](std::uint64_t key, std::size_t index, unsigned depth) {
          tiles.push_back({key, static_cast<std::uint32_t>(index), depth});
        },
        kNoUpper);
  return tiles;
}

std::pair<std::uint64_t, std::uint64_t> tileKeyRange(unsigned depth, std::uint64_t path) {
  const unsigned shift = 5 + 3 * (kTreeDepth - depth);
  return {path << shift, (path + 1) << shift};
}

namespace {

class ChangedTileWalk {
 public:
  ChangedTileWalk(const PoolCapture& pool, unsigned tile_depth,
                  const std::function<bool(std::uint64_t)>& committed, PoolTileChanges& out)
      : pool_(pool), nodes_{pool}, tile_depth_(tile_depth), committed_(committed), out_(out) {
    // The paths of the cells whose nodes the colour fold changed.
    for (const PoolCapture::Folded& f : pool.folded) folded_.push_back(cellPath(f.key));
    std::sort(folded_.begin(), folded_.end());
  }

  // Node `index` at `depth`, reached by `path`: nothing when it did not change (its tiles are
  // as committed), else a tile to compare, or its children walked. `fresh`: the node is new
  // (the scan expanded a leaf above it), and so is everything under it.
  void walk(std::size_t index, unsigned depth, std::uint64_t path, bool fresh) {
    if (!fresh && !std::binary_search(pool_.changed.begin(), pool_.changed.end(), index) &&
        !holdsFolded(depth, path))
      return;
    const NodeView n = nodes_(index);
    const std::uint64_t own = tileKey(depth, path);
    if (depth == tile_depth_ || n.mask == 0) {
      out_.tiles.push_back({own, static_cast<std::uint32_t>(index), depth});
      out_.cleared.push_back(tileKeyRange(depth, path));
      return;
    }
    out_.cleared.emplace_back(own, own + 1);
    // A committed leaf that now has children was expanded by the scan: its children are all
    // new, the ones beside the scan's paths too, which the changed list does not name.
    fresh = fresh || committed_(own);
    for (unsigned i = 0; i < 8; ++i) {
      const std::uint64_t child = (path << 3) | i;
      if (n.mask & (1u << i))
        walk(n.children * 8 + i, depth + 1, child, fresh);
      else
        out_.cleared.push_back(tileKeyRange(depth + 1, child));
    }
  }

 private:
  // Whether a cell whose node the fold changed lies under the node at `depth` reached by
  // `path`: its colour changed, though the node need not be on the scan's updated paths.
  bool holdsFolded(unsigned depth, std::uint64_t path) const {
    const unsigned shift = 3 * (kTreeDepth - depth);
    const auto first = std::lower_bound(folded_.begin(), folded_.end(), path << shift);
    return first != folded_.end() && (*first >> shift) == path;
  }

  const PoolCapture& pool_;
  PoolNodes nodes_;
  unsigned tile_depth_;
  const std::function<bool(std::uint64_t)>& committed_;
  PoolTileChanges& out_;
  std::vector<std::uint64_t> folded_;  // sorted
};

}  // namespace

PoolTileChanges changedPoolTiles(const PoolCapture& pool, unsigned tile_depth,
                                 const std::function<bool(std::uint64_t)>& committed) {
  checkTileDepth(tile_depth);
  PoolTileChanges out;
  if (!pool.root_exists)
    out.cleared.push_back(tileKeyRange(0, 0));
  else
    ChangedTileWalk(pool, tile_depth, committed, out).walk(0, 0, 0, false);
  return out;
}

std::string poolTileBody(const PoolCapture& pool, const PoolTile& tile) {
  std::string body;
  appendRecords(PoolNodes(pool), tile.node, tile.depth, pool.kind, body);
  return body;
}

std::string poolUpperStamps(const PoolCapture& pool, unsigned tile_depth) {
  checkTileDepth(tile_depth);
  if (!pool.root_exists || pool.kind != Payload::kStamp) return {};
  return upperStamps(PoolNodes(pool), tile_depth);
}

HostTree treeFromTiles(std::span<const Tile> tiles, unsigned tile_depth, Payload payload) {
  checkTileDepth(tile_depth);
  return Rebuild(tiles, tile_depth, payload).run();
}

std::string nodeStream(const HostTree& tree) {
  std::string out;
  if (tree.root_exists) appendRecords(HostTreeNodes{tree}, 0, 0, tree.payload, out);
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
