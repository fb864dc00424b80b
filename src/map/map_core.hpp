// What every part of a map shares: its device, parameters, command stream, buffers and recorder,
// and the two facts about the tree that more than one part reads or changes (its version, for
// castRay's scene and the change set; whether the leaf boxes are current). The parts (scan
// pipeline, growth policy, ray-scene cache, query runner, tree transfer) each hold a reference to
// it; OccupancyMap::Impl owns it.
#pragma once

#include <array>
#include <cstdint>

#include "map/map_buffers.hpp"
#include "map/passes/passes.hpp"
#include "map/reference.hpp"
#include "octovk/octovk.hpp"
#include "vk/device.hpp"

namespace octovk {

/// Whether the leaf-box buffer describes the tree as it is.
enum class LeafBoxes : std::uint8_t {
  kCurrent,  ///< rebuilt since the tree last changed (or the map is new)
  kStale     ///< scans changed the tree without rebuilding them (setLeafBoxesEveryScan(false))
};

struct MapCore {
  MapCore(vk::Device& device, const MapParams& params);

  /// The parameters of a scan of `count` points from `origin` (moved by `pose`, if any), with
  /// the sets' and lists' sizes as they are now.
  gpu::ScanParams scanParams(const Eigen::Vector3f& origin, const Pose* pose, double max_range,
                             std::size_t count) const;
  /// The parameters of a pass that is not a scan (queries, uploads): the map's, no scan.
  gpu::ScanParams queryParams() const {
    return scanParams(Eigen::Vector3f::Zero(), nullptr, -1.0, 0);
  }
  /// The pool's state, read back in a submission of its own (waited for). Sees what the device
  /// has done; the caller takes the results of the scans in flight first.
  gpu::PoolState readPool();
  /// Rebuilds the leaf boxes (waited for) if they are stale; the caller flushes first.
  void refreshLeafBoxes();
  /// The leaf-box buffer made if the map had none (then stale); nothing may be in flight.
  void ensureLeafBoxes();
  /// The tree changed (a scan updated cells, an upload, an edit): what was derived from the
  /// version before (castRay's scene, a distance field not following the change set) is stale.
  void treeChanged() noexcept { ++tree_version; }

  vk::Device& device;
  const MapParams params;
  const ref::LogOddsParams logs;
  vk::CommandStream stream;
  MapBuffers buffers;
  passes::Recorder rec;
  /// Counts the changes of the tree (treeChanged): castRay's scene is rebuilt when it was built
  /// from another version.
  std::uint64_t tree_version = 0;
  /// What the touched lists (the prune pass's nodes per depth) hold: the nodes on the paths the
  /// last recorded scan updated, when that scan changed the tree to `version` and nothing was
  /// recorded after it (version 0: they describe no one change). A capture reads them to find
  /// what changed (TreeTransfer::capture).
  struct TouchedLists {
    std::uint64_t version = 0;
    std::array<std::uint32_t, gpu::kLevelCount> counts{};
    std::uint64_t generation = 0;  ///< MapBuffers::listsGeneration() when the scan ran
    gpu::PoolState pool{};         ///< the pool after it (the scan's own readback)
    /// Entries of its colour fold's folded list (ScanCounters::folded_count; 0 without a fold).
    std::uint32_t folded = 0;
    std::uint32_t folded_at = 0;        ///< where that list starts (passes::foldedListAt)
    std::uint64_t fold_generation = 0;  ///< MapBuffers::foldGeneration() when the scan ran
  };
  TouchedLists touched;
  /// Scans recorded (each recording, a scan run again included, overwrites the touched lists).
  std::uint64_t scans_recorded = 0;
  LeafBoxes leaf_boxes = LeafBoxes::kCurrent;
};

}  // namespace octovk
