// A map's device working set of tiles (the subtrees at gpu::kTileDepth): when the node pool cannot
// grow under MapParams::max_device_bytes, the tiles farthest from the scan's sensor are written to
// a TileSpill (OccupancyMap::spillTilesTo) and their subtrees leave the pool; their nodes stay,
// with their own data (the max of the subtree, its payload) and kFlagEvicted. A scan that
// reaches such a tile is refused by the device (kStatusTilesNeeded, the tiles' nodes in its
// counters); the host loads them back and runs the scan again, so every cell update is applied
// to the same tree as in one pool. Pruning never merges an evicted node (it has children), and
// nothing else of a scan reads below the tile depth, so the map equals the one a large enough
// device would hold, node for node; download() grafts the spilled tiles back.
//
// Every load and eviction is one round trip of the pool (download, edit on the host, upload):
// the pool is at most the cap, and it happens only when the working set changes.
#pragma once

#include <cstddef>
#include <cstdint>
#include <memory>
#include <string>
#include <unordered_map>
#include <unordered_set>
#include <utility>
#include <vector>

#include "map/map_core.hpp"
#include "map/tree_transfer.hpp"
#include "octovk/octovk.hpp"

namespace octovk {

class TileWorkingSet {
 public:
  TileWorkingSet(MapCore& core, TreeTransfer& transfer) : core_(core), transfer_(transfer) {}

  /// Where evicted tiles go from now on; kInvalidArgument while tiles are spilled elsewhere.
  void setSpill(std::shared_ptr<TileSpill> spill);
  /// Whether the map may evict tiles (a spill was given).
  bool enabled() const noexcept { return spill_ != nullptr; }
  /// Tiles off the device now.
  std::size_t spilledTiles() const noexcept { return spilled_.size(); }
  /// Nodes of the spilled tiles below their roots (the roots stay in the pool).
  std::uint64_t spilledNodes() const noexcept { return spilled_nodes_; }
  /// Round trips, loads and evictions so far.
  OccupancyMap::SpillCounts counts() const noexcept { return counts_; }

  /// A scan (`scan`: the key its loads are pinned under, ScanPipeline::rebalanceTiles) was refused
  /// for the evicted tiles `counters` names: loads them, evicting unpinned tiles farthest from
  /// `sensor` if the pool needs room for them and `counters.new_blocks` more. False, with
  /// nothing changed, where they do not fit even so. Nothing may be in flight.
  /// `partly_applied`: parts of the scan are in the map already.
  bool load(const gpu::ScanCounters& counters, const Eigen::Vector3f& sensor,
            const std::string& scan, bool partly_applied);
  /// A scan was refused for want of `blocks` free pool blocks and the pool cannot grow under the
  /// cap: evicts unpinned tiles, farthest from `sensor` first, until they fit. False, with
  /// nothing changed, where evicting every unpinned tile would not make the room.
  bool makeRoom(std::uint64_t blocks, const Eigen::Vector3f& sensor, const std::string& scan,
                bool partly_applied);
  /// `resident` (the pool's tree, as hostTreeFromPool gives it) with every spilled tile grafted
  /// back: the whole map.
  HostTree wholeTree(HostTree resident) const;
  /// Throws kInvalidArgument naming `call` while tiles are spilled: the passes that read the
  /// whole tree (queries, leaf boxes, edits, fields) need it on the device.
  void requireResident(const char* call) const;
  /// The map was replaced (upload): nothing is spilled any more.
  void forget();
  /// A store captures the map after every scan (MapWriter): a tile evicted between scans is as
  /// the last commit holds it; one evicted while a scan is partly applied may hold changes of
  /// the parts applied, which the store has not seen: it is noted dirty (takeDirty).
  void noteCommittedPerScan() noexcept { committed_per_scan_ = true; }
  /// The dirty tiles still off the device, each its path and its subtree (the tile's root at
  /// node 0), forgotten as dirty: the capture that takes them commits them.
  std::vector<std::pair<std::uint64_t, HostTree>> takeDirty();

 private:
  /// A tile off the device: its body in the spill, and what it holds below its root.
  struct Spilled {
    std::uint64_t nodes = 0;   ///< nodes below the root
    std::uint64_t blocks = 0;  ///< pool blocks its subtree takes
  };
  /// The round trip: downloads the pool, loads `needed` (pool nodes of evicted tiles), evicts
  /// (unpinned, farthest from `sensor`) until the tree and `room` more blocks fit, uploads.
  bool rebalance(const std::vector<std::uint32_t>& needed, std::uint64_t room,
                 const Eigen::Vector3f& sensor, const std::string& scan, bool partly_applied);

  MapCore& core_;
  TreeTransfer& transfer_;
  std::shared_ptr<TileSpill> spill_;
  std::unordered_map<std::uint64_t, Spilled> spilled_;  // by tile path (3 bits a level)
  std::uint64_t spilled_nodes_ = 0;
  bool committed_per_scan_ = false;
  std::unordered_set<std::uint64_t> dirty_;  // evicted with changes no commit has seen
  OccupancyMap::SpillCounts counts_;
  // The tiles loaded for the scan (or part) being applied: never evicted while it runs again,
  // so that its loads only grow and the retries end.
  std::string pinned_scan_;
  std::unordered_set<std::uint64_t> pinned_;
  std::string idle_scan_;  // the scan whose round trip moved no tile (one such trip a scan)
};

}  // namespace octovk
