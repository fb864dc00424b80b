// The tree transfer: the whole tree between the device pool and a HostTree (download, upload),
// and the leaf boxes to the host. The caller takes the results of the scans in flight first
// (OccupancyMap::Impl does).
#pragma once

#include <vector>

#include "map/host_tree.hpp"
#include "map/map_core.hpp"
#include "map/ray_scene_cache.hpp"
#include "octovk/octovk.hpp"

namespace octovk {

class TreeTransfer {
 public:
  TreeTransfer(MapCore& core, RaySceneCache& scenes) : core_(core), scenes_(scenes) {}

  HostTree download();
  /// Replaces the tree; throws with the map unchanged where it cannot (pool limit, memory).
  void upload(const HostTree& tree);
  /// The leaf boxes, rebuilt first if stale.
  std::vector<OccupancyMap::LeafBoxHost> downloadLeafBoxes();

 private:
  MapCore& core_;
  RaySceneCache& scenes_;
};

}  // namespace octovk
