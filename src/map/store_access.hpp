// The map store's way into a map (src/store/), which the public header does not hand out: the
// node pool captured with the nodes near the root that changed since an earlier capture, so that
// a commit serialises only the tiles a scan changed, and the tree's version to capture from.
#pragma once

#include <cstdint>
#include <optional>
#include <utility>
#include <vector>

#include "map/pool_capture.hpp"
#include "octovk/map.hpp"

namespace octovk {

class StoreAccess {
 public:
  /// TreeTransfer::capture after the scans in flight: the pool, and which nodes at depths
  /// 0..`depth` changed since the tree's version `since` (PoolCapture::incremental says whether
  /// that is known).
  static PoolCapture capture(OccupancyMap& map, std::uint64_t since, unsigned depth);
  /// From the next scan on, each scan's submission ends with a capture of the map, cut at
  /// `depth` (not while tiles may leave the device: spillTilesTo).
  static void captureScans(OccupancyMap& map, unsigned depth);
  /// The last scan submitted, when it brings such a capture; else 0 (capture() it is).
  static std::uint64_t capturingTicket(OccupancyMap& map);
  /// Waits for scan `ticket` only (not the scans after it) and returns the map as it left it,
  /// as capture() would have right after it; nullopt when it brought no capture.
  static std::optional<PoolCapture> takeCapture(OccupancyMap& map, std::uint64_t ticket,
                                                std::uint64_t since);
  /// The tree's version after the scans in flight: changes with every scan that changed the
  /// tree, edit and upload.
  static std::uint64_t version(OccupancyMap& map);
  /// The map is committed to a store after every scan from now on: its working set of tiles
  /// (spillTilesTo) then moves no tile while a scan is partly applied (TileWorkingSet).
  static void attach(OccupancyMap& map);
  /// The tiles evicted while a scan was partly applied, still off the device, which no commit
  /// has seen: each its path below the root (3 bits a level) and its subtree (root at node 0).
  static std::vector<std::pair<std::uint64_t, HostTree>> takeDirtyTiles(OccupancyMap& map);
};

}  // namespace octovk
