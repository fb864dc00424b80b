// Map surgery: edits of the tree that are not scans (octomap_server's clear_bbx). The caller
// takes the results of the scans in flight first (OccupancyMap::Impl does).
#pragma once

#include <Eigen/Core>

#include "map/map_core.hpp"

namespace octovk {

class TreeEdits {
 public:
  explicit TreeEdits(MapCore& core) : core_(core) {}

  /// octomap_server's clear_bbx: every leaf OctoMap's leaf_bbx_iterator(min, max) visits gets
  /// the lower clamping bound's log-odds, then updateInnerOccupancy (no pruning; later scans
  /// prune as OctoMap's would). kInvalidArgument (map unchanged) for a NaN corner or min > max.
  void clearBox(const Eigen::Vector3f& min, const Eigen::Vector3f& max);

 private:
  MapCore& core_;
};

}  // namespace octovk
