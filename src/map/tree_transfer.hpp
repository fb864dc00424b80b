// The tree transfer: the whole tree between the device pool and a HostTree (download, upload),
// and the leaf boxes to the host. The caller takes the results of the scans in flight first
// (OccupancyMap::Impl does).
#pragma once

#include <cstdint>
#include <span>
#include <vector>

#include "map/host_tree.hpp"
#include "map/map_core.hpp"
#include "map/pool_capture.hpp"
#include "map/ray_scene_cache.hpp"
#include "octovk/octovk.hpp"

namespace octovk {

class TreeTransfer {
 public:
  TreeTransfer(MapCore& core, RaySceneCache& scenes) : core_(core), scenes_(scenes) {}

  HostTree download();
  /// The pool's tree as the device holds it: hostTreeFromPool's, node i the pool's node i, inner
  /// colours as updates left them (download() averages them).
  /// `state`: where to put the pool's state it read.
  HostTree downloadRaw(gpu::PoolState* state = nullptr);
  /// The pool and what changed at depths 0..`depth` (at most 15) since the tree's version
  /// `since`, in one submission.
  PoolCapture capture(std::uint64_t since, unsigned depth);
  /// Replaces the tree; throws with the map unchanged where it cannot (pool limit, memory).
  /// `shrink`: also into a smaller pool than the current one, sized for the tree (compact()).
  /// `evicted`: nodes of `tree` (at the tile depth, without children in it) whose subtrees are
  /// off the device (kFlagEvicted, TileWorkingSet); `room`: blocks the pool keeps free for them
  /// beyond the tree.
  void upload(const HostTree& tree, bool shrink = false,
              std::span<const std::uint32_t> evicted = {}, std::uint64_t room = 0);
  /// The tree moved into a pool sized for it, when that gives back at least a fifth of the
  /// pool's blocks (OccupancyMap::compact).
  void compact();
  /// The leaf boxes, rebuilt first if stale.
  std::vector<OccupancyMap::LeafBoxHost> downloadLeafBoxes();

 private:
  std::uint32_t capacityFor(std::uint64_t blocks) const;

  MapCore& core_;
  RaySceneCache& scenes_;
  /// capture()'s host-visible staging, kept for the next capture once nobody holds the last
  /// one (a store captures after every scan: a fresh buffer each time cost its page faults).
  std::shared_ptr<vk::Buffer> capture_staging_;
};

}  // namespace octovk
