#include "map/tile_working_set.hpp"

#include <algorithm>
#include <cmath>
#include <cstring>
#include <utility>

#include "map/host_tree.hpp"

namespace octovk {

namespace {

// ---- a tile's body in the spill: its subtree's nodes in pre-order, each its log-odds, its
// payload word and its child mask (9 bytes) ----

constexpr std::size_t kRecordBytes = 9;

void appendSubtree(const HostTree& tree, std::uint32_t node, std::string& out) {
  const HostTree::Node& n = tree.nodes[node];
  const std::uint8_t mask = static_cast<std::uint8_t>(n.mask & gpu::kChildMask);
  char record[kRecordBytes];
  std::memcpy(record, &n.log_odds, 4);
  std::memcpy(record + 4, &n.payload, 4);
  std::memcpy(record + 8, &mask, 1);
  out.append(record, kRecordBytes);
  if (mask == 0) return;
  for (std::uint32_t s = 0; s < 8; ++s)
    if (mask & (1u << s)) appendSubtree(tree, n.children * 8 + s, out);
}

// Reads the record at `at` into `node` and its subtree into new blocks at the end of the tree.
void placeSubtree(HostTree& tree, std::uint32_t node, unsigned depth, const std::string& body,
                  std::size_t& at) {
  if (at + kRecordBytes > body.size() || depth > gpu::kTreeDepth)
    throw Error(ErrorCode::kInternal,
                "internal error: a spilled tile's body is damaged (it ends early or goes below "
                "depth 16); please report this");
  HostTree::Node& n = tree.nodes[node];
  std::uint8_t mask = 0;
  std::memcpy(&n.log_odds, body.data() + at, 4);
  std::memcpy(&n.payload, body.data() + at + 4, 4);
  std::memcpy(&mask, body.data() + at + 8, 1);
  at += kRecordBytes;
  n.mask = mask;
  n.children = gpu::kNoBlock;
  if (mask == 0) return;
  const auto block = static_cast<std::uint32_t>(tree.nodes.size() / 8);
  tree.nodes[node].children = block;
  tree.nodes.resize(tree.nodes.size() + 8, emptyHostNode());
  for (std::uint32_t s = 0; s < 8; ++s)
    if (mask & (1u << s)) placeSubtree(tree, block * 8 + s, depth + 1, body, at);
}

void graft(HostTree& tree, std::uint32_t node, const std::string& body) {
  std::size_t at = 0;
  placeSubtree(tree, node, gpu::kTileDepth, body, at);
  if (at != body.size())
    throw Error(ErrorCode::kInternal,
                "internal error: a spilled tile's body has bytes after its last node; please "
                "report this");
}

// The nodes at the tile depth, with their paths (a child index, 3 bits, per level from the
// root); and the blocks the tree above them takes (block 0, the root's, included).
struct TileNode {
  std::uint32_t node;
  std::uint64_t path;
};
struct Cut {
  std::vector<TileNode> tiles;
  std::uint64_t upper_blocks = 1;
};
Cut cutAtTileDepth(const HostTree& tree) {
  Cut cut;
  if (!tree.root_exists || tree.nodes.empty()) return cut;
  struct Item {
    std::uint32_t node;
    unsigned depth;
    std::uint64_t path;
  };
  std::vector<Item> stack{{gpu::kRootNode, 0, 0}};
  while (!stack.empty()) {
    const Item it = stack.back();
    stack.pop_back();
    if (it.depth == gpu::kTileDepth) {
      cut.tiles.push_back({it.node, it.path});
      continue;
    }
    const HostTree::Node& n = tree.nodes[it.node];
    if ((n.mask & gpu::kChildMask) == 0) continue;
    ++cut.upper_blocks;  // its children's block
    for (std::uint32_t s = 0; s < 8; ++s)
      if (n.mask & (1u << s))
        stack.push_back({n.children * 8 + s, it.depth + 1, (it.path << 3) | s});
  }
  return cut;
}

// The centre of the tile at `path`, in metres (OctoMap's keys: cell k's centre is
// (k - 32768 + 0.5) * resolution; a tile is 16 cells wide).
Eigen::Vector3f tileCentre(std::uint64_t path, double resolution) {
  std::uint32_t key[3] = {0, 0, 0};
  for (unsigned d = 0; d < gpu::kTileDepth; ++d) {
    const auto s = static_cast<std::uint32_t>((path >> (3 * (gpu::kTileDepth - 1 - d))) & 7u);
    const unsigned bit = gpu::kTreeDepth - 1 - d;
    for (unsigned axis = 0; axis < 3; ++axis) key[axis] |= ((s >> axis) & 1u) << bit;
  }
  const double half = 0.5 * double(1u << (gpu::kTreeDepth - gpu::kTileDepth));
  Eigen::Vector3f c;
  for (int axis = 0; axis < 3; ++axis)
    c[axis] =
        static_cast<float>((double(key[axis]) - double(gpu::kTreeMaxVal) + half) * resolution);
  return c;
}

class HostTileSpill final : public TileSpill {
 public:
  void put(std::uint64_t key, const std::string& body) override { bodies_[key] = body; }
  std::string get(std::uint64_t key) override {
    const auto it = bodies_.find(key);
    if (it == bodies_.end())
      throw Error(ErrorCode::kInternal,
                  "internal error: the host spill holds no tile " + std::to_string(key));
    return it->second;
  }
  void erase(std::uint64_t key) override { bodies_.erase(key); }

 private:
  std::unordered_map<std::uint64_t, std::string> bodies_;
};

}  // namespace

void TileWorkingSet::setSpill(std::shared_ptr<TileSpill> spill) {
  if (!spilled_.empty() && spill != spill_)
    throw Error(ErrorCode::kInvalidArgument,
                "spillTilesTo: " + std::to_string(spilled_.size()) +
                    " tiles of this map are in its current spill; a spill cannot be changed "
                    "while it holds tiles");
  if (spill && core_.params.scan_rays != ScanRays::kWalk)
    throw Error(ErrorCode::kInvalidArgument,
                "spillTilesTo: a map whose scans are ray traced (MapParams::scan_rays) cannot "
                "spill tiles; use ScanRays::kWalk (--rays walk)");
  spill_ = std::move(spill);
}

void TileWorkingSet::requireResident(const char* call) const {
  if (spilled_.empty()) return;
  throw Error(ErrorCode::kInvalidArgument,
              std::string(call) + ": " + std::to_string(spilled_.size()) +
                  " tiles of this map are spilled off the device (the map outgrew "
                  "max_device_bytes), and this reads the whole tree on the device. Raise "
                  "max_device_bytes (--max-device-memory), or work on the downloaded tree "
                  "(download(), or a written .bt/.ot file)");
}

std::vector<std::pair<std::uint64_t, HostTree>> TileWorkingSet::takeDirty() {
  std::vector<std::pair<std::uint64_t, HostTree>> out;
  for (const std::uint64_t path : dirty_) {
    HostTree subtree;
    subtree.root_exists = true;
    subtree.payload = core_.params.payload;
    subtree.nodes.assign(8, emptyHostNode());
    graft(subtree, gpu::kRootNode, spill_->get(path));
    out.emplace_back(path, std::move(subtree));
  }
  dirty_.clear();
  return out;
}

void TileWorkingSet::forget() {
  if (spill_)
    for (const auto& [path, spilled] : spilled_) spill_->erase(path);
  spilled_.clear();
  dirty_.clear();
  spilled_nodes_ = 0;
  pinned_.clear();
  pinned_scan_.clear();
}

HostTree TileWorkingSet::wholeTree(HostTree resident) const {
  if (spilled_.empty()) return resident;
  for (const TileNode& t : cutAtTileDepth(resident).tiles)
    if (spilled_.count(t.path)) graft(resident, t.node, spill_->get(t.path));
  return resident;
}

bool TileWorkingSet::load(const gpu::ScanCounters& counters, const Eigen::Vector3f& sensor,
                          const std::string& scan, bool partly_applied) {
  std::vector<std::uint32_t> needed;
  for (const std::uint32_t slot : counters.needed_tiles)
    if (slot != 0) needed.push_back(slot - 1);
  if (needed.empty())
    throw Error(ErrorCode::kInternal,
                "internal error: a scan was refused for tiles off the device but named none; "
                "please report this with the input");
  return rebalance(needed, counters.new_blocks, sensor, scan, partly_applied);
}

bool TileWorkingSet::makeRoom(std::uint64_t blocks, const Eigen::Vector3f& sensor,
                              const std::string& scan, bool partly_applied) {
  return rebalance({}, blocks, sensor, scan, partly_applied);
}

bool TileWorkingSet::rebalance(const std::vector<std::uint32_t>& needed, std::uint64_t room,
                               const Eigen::Vector3f& sensor, const std::string& scan,
                               bool partly_applied) {
  if (scan != pinned_scan_) {
    pinned_.clear();
    pinned_scan_ = scan;
  }
  gpu::PoolState pool{};
  HostTree tree = transfer_.downloadRaw(&pool);
  const Cut cut = cutAtTileDepth(tree);

  // The tiles to load: the needed nodes that are spilled tiles.
  std::unordered_map<std::uint32_t, std::uint64_t> path_of;
  for (const TileNode& t : cut.tiles) path_of.emplace(t.node, t.path);
  std::vector<TileNode> loads;
  std::uint64_t held = cut.upper_blocks;  // blocks once loaded, before evicting
  for (const std::uint32_t n : needed) {
    const auto it = path_of.find(n);
    if (it == path_of.end() || !spilled_.count(it->second)) continue;
    if (std::any_of(loads.begin(), loads.end(), [&](const TileNode& l) { return l.node == n; }))
      continue;
    loads.push_back({n, it->second});
    held += spilled_.at(it->second).blocks;
  }
  if (!needed.empty() && loads.empty())
    throw Error(ErrorCode::kInternal,
                "internal error: a scan was refused for tiles that are not spilled; please "
                "report this with the input");

  // The blocks the pool holds (every block in use belongs to a node with children that hangs in
  // the tree), and the resident tiles that may go: not pinned, not loaded now, with children;
  // their sizes are walked only if tiles must go.
  held = held - cut.upper_blocks + (std::uint64_t{pool.bump} - pool.free_count);
  struct Candidate {
    TileNode tile;
    SubtreeSize size;
    float distance;
  };
  std::vector<Candidate> candidates;
  for (const TileNode& t : cut.tiles) {
    if ((tree.nodes[t.node].mask & gpu::kChildMask) == 0 || pinned_.count(t.path)) continue;
    candidates.push_back(
        {t, {}, (tileCentre(t.path, core_.params.resolution) - sensor).squaredNorm()});
  }

  // The pool may take what the cap leaves beside the other buffers (and the pool's limit).
  const std::uint64_t limit = std::min<std::uint64_t>(
      core_.buffers.blockLimit(),
      std::min<std::size_t>(core_.buffers.poolBlocksWithinCap(), std::size_t{1} << 40));
  // When tiles must go, they go until the tree and the room take half of what the pool may
  // have: the other half stays for the next scans, so that evicting is rare.
  std::vector<Candidate> evict;
  if (held + room + 1 > limit) {
    std::sort(candidates.begin(), candidates.end(),
              [](const Candidate& a, const Candidate& b) { return a.distance > b.distance; });
    for (Candidate& c : candidates) {
      if (held + room + 1 <= limit / 2) break;
      c.size = subtreeSize(tree, c.tile.node);
      evict.push_back(c);
      held -= c.size.blocks;
    }
    if (held + room + 1 > limit) return false;  // nothing changed
  }
  if (loads.empty() && evict.empty()) {
    // Nothing to move, and the tree and the room fit: one round trip sizes the pool for them,
    // once a scan (a second would change nothing, and the scan is split instead).
    if (held + room + 1 > limit || idle_scan_ == scan) return false;
    idle_scan_ = scan;
  }

  // The spill's side first (a failure leaves the device as it was): bodies in, loads read.
  for (const Candidate& c : evict) {
    std::string body;
    appendSubtree(tree, c.tile.node, body);
    spill_->put(c.tile.path, body);
  }
  for (const TileNode& l : loads) graft(tree, l.node, spill_->get(l.path));
  for (const Candidate& c : evict) {
    tree.nodes[c.tile.node].mask = 0;
    tree.nodes[c.tile.node].children = gpu::kNoBlock;
  }
  HostTree compact = compactHostTree(tree);

  // Which nodes of the new layout are evicted tiles.
  std::unordered_set<std::uint64_t> off;
  for (const auto& [path, spilled] : spilled_) off.insert(path);
  for (const TileNode& l : loads) off.erase(l.path);
  for (const Candidate& c : evict) off.insert(c.tile.path);
  std::vector<std::uint32_t> evicted_nodes;
  for (const TileNode& t : cutAtTileDepth(compact).tiles)
    if (off.count(t.path)) evicted_nodes.push_back(t.node);
  transfer_.upload(compact, /*shrink=*/false, evicted_nodes, room);

  // The device holds the new working set: the bookkeeping follows.
  for (const TileNode& l : loads) {
    spilled_nodes_ -= spilled_.at(l.path).nodes;
    spilled_.erase(l.path);
    spill_->erase(l.path);
    pinned_.insert(l.path);
    dirty_.erase(l.path);  // on the device again: the capture reads it there
  }
  for (const Candidate& c : evict) {
    spilled_[c.tile.path] = Spilled{c.size.nodes - 1, c.size.blocks};
    spilled_nodes_ += c.size.nodes - 1;
    if (committed_per_scan_ && partly_applied) dirty_.insert(c.tile.path);
  }
  ++counts_.round_trips;
  counts_.loaded += loads.size();
  counts_.evicted += evict.size();
  return true;
}

std::shared_ptr<TileSpill> makeHostTileSpill() { return std::make_shared<HostTileSpill>(); }

}  // namespace octovk
