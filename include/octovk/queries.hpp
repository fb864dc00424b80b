// octovk: Queries on a map with OctoMap's meaning (search, castRay) and the tree on the host.
#pragma once

#include <Eigen/Core>
#include <array>
#include <cstdint>
#include <optional>
#include <span>
#include <vector>

#include "octovk/params.hpp"

namespace octovk {

/// The tree as the host sees it after an explicit download. Node index = block * 8 + slot;
/// the root is node 0. Children of node n are at children * 8 + i where bit i of mask is set.
struct HostTree {
  struct Node {
    float log_odds;
    std::uint32_t children;
    std::uint32_t mask;
    /// The payload (HostTree::payload): packRgb(colour) or the time stamp; 0 for kNone.
    std::uint32_t payload = 0;
  };
  bool root_exists = false;
  /// What the nodes' payload holds (the tree type).
  Payload payload = Payload::kNone;
  std::vector<Node> nodes;
};

/// A cell's key at the finest depth: OctoMap's OcTreeKey (k[0], k[1], k[2]).
using Key = std::array<std::uint16_t, 3>;
/// OctoMap's coordToKeyChecked at the finest depth: per axis floor(coordinate / resolution) +
/// 32768 (the coordinate widened to double, times 1.0 / resolution); nullopt where a coordinate
/// is NaN or the key would fall outside [0, 65536).
std::optional<Key> coordToKey(double resolution, const Eigen::Vector3f& point);
/// OctoMap's keyToCoord at the finest depth: the centre of the key's cell, per axis
/// (key - 32768 + 0.5) * resolution in double, then float (OctoMap's point3d).
Eigen::Vector3f keyToCoord(double resolution, const Key& key);

/// One entry of the change set (OctoMap's KeyBoolMap, change detection on): a finest-level key
/// (OcTreeKey k[0], k[1], k[2]) and its flag: `created` (OctoMap's `true`: the leaf was created)
/// or not (`false`: an existing leaf's occupancy flipped).
struct ChangedKey {
  Key key{};
  bool created = false;
  friend bool operator==(const ChangedKey&, const ChangedKey&) = default;
};

/// State of a cell as OctoMap's search() and isNodeOccupied() see it.
enum class CellState : std::uint32_t { kUnknown = 0, kFree = 1, kOccupied = 2 };

/// Result of a point lookup: the deepest existing node on the point's path (OctoMap's search,
/// pruned nodes included). Unknown for points outside the map, NaN points and unmapped space.
struct Lookup {
  CellState state = CellState::kUnknown;
  float log_odds = 0.0f;    ///< of the node found (0 when unknown)
  std::uint32_t depth = 0;  ///< depth of the node found, 16 = finest (0 when unknown)
  /// The node's payload (packRgb(colour) or time stamp; MapParams::payload), 0 when unknown or
  /// the map has none.
  std::uint32_t payload = 0;
};

/// A castRay query, as OctoMap's castRay(origin, direction, end, ignore_unknown, max_range).
struct Ray {
  Eigen::Vector3f origin = Eigen::Vector3f::Zero();
  Eigen::Vector3f direction = Eigen::Vector3f::UnitX();  ///< need not be normalised
  double max_range_m = -1.0;                             ///< <= 0: up to the map's border
  bool ignore_unknown = false;                           ///< true: unknown cells count as free
};

/// Result of a castRay: OctoMap's return value and its `end` (the centre of the last cell
/// visited). Where OctoMap leaves `end` untouched (origin outside the map, zero direction) it is
/// the ray's origin.
struct RayHit {
  bool hit = false;
  Eigen::Vector3f end = Eigen::Vector3f::Zero();
  /// On a map with a payload (MapParams::payload), the hit cell's payload word (packRgb colour
  /// or stamp); 0 for a miss or a map without one.
  std::uint32_t payload = 0;
};

/// Queries to run right after a scan, in the same command stream.
struct QueryRequest {
  std::span<const Eigen::Vector3f> lookups;
  std::span<const Ray> rays;
};

struct QueryResults {
  std::vector<Lookup> lookups;
  std::vector<RayHit> rays;
};

}  // namespace octovk
