// Map surgery: edits of the tree that are not scans (octomap_server's clear_bbx, keeping a box).
// The caller takes the results of the scans in flight first (OccupancyMap::Impl does).
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
  /// Keeps only the leaves OctoMap's leaf_bbx_iterator(min, max) visits and the inner nodes
  /// above them (each the maximum of its children, as updateInnerOccupancy); every other node is
  /// deleted and its block returns to the free stack. A corner outside the map keeps nothing.
  /// Change detection does not see it (OctoMap's deleteNode leaves the changed keys alone).
  /// kInvalidArgument (map unchanged) for a NaN corner or min > max.
  void keepBox(const Eigen::Vector3f& min, const Eigen::Vector3f& max);
  /// StampedMap::degradeOutdated: OcTreeStamped::degradeOutdatedNodes at `now`, then
  /// updateInnerOccupancy (inner stamps `now`).
  void degrade(std::uint32_t now, std::uint32_t threshold);

 private:
  /// One edit: the box checked and turned into keys (none when a corner is outside the map),
  /// `record(box or nullptr)` recorded into one submission, waited for, the tree marked changed.
  template <typename Record>
  void edit(const char* call, const Eigen::Vector3f& min, const Eigen::Vector3f& max,
            Record record);
  /// The leaf boxes go stale and castRay's scene is rebuilt on its next use.
  void treeChanged();

  MapCore& core_;
};

}  // namespace octovk
