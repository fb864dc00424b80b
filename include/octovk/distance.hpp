// octovk: The distance to the nearest obstacle: an exact Euclidean distance field over a box of a
// map, on the device, with DynamicEDTOctomap's meaning (dynamicEDT3D), and batched queries.
#pragma once

#include <Eigen/Core>
#include <array>
#include <cstddef>
#include <cstdint>
#include <limits>
#include <memory>
#include <span>
#include <vector>

#include "octovk/map.hpp"

namespace octovk {

/// How a DistanceField reads the map.
struct DistanceFieldOptions {
  /// Distances are capped here (metres, > 0): farther cells report this distance and no
  /// gradient. The squared distances in cells are exact and not capped.
  float max_distance_m = 2.0f;
  /// The unknown-space rule (DynamicEDTOctomap's treatUnknownAsOccupied, which it has every
  /// caller choose). true (the default): cells the map does not know count as obstacles, so a
  /// distance never promises clearance through space no sensor saw; a field over unseen space
  /// reads 0 (the cell is its own obstacle). false: only occupied cells (isNodeOccupied) are
  /// obstacles and unknown space reads as free, as far as the nearest occupied cell (capped).
  bool treat_unknown_as_occupied = true;
};

/// One answer of DistanceField::distances / clearances.
struct DistanceSample {
  /// Metres from the centre of the query's cell to the centre of the nearest occupied cell of
  /// the box, capped at max_distance_m, minus the sphere's radius (clearances). Outside the box
  /// (or a NaN coordinate): kOutside, DynamicEDTOctomap's distanceValue_Error.
  float distance_m = kOutside;
  /// Centre of the nearest occupied cell; NaN where the box has none or the query is outside.
  Eigen::Vector3f obstacle = Eigen::Vector3f::Constant(std::numeric_limits<float>::quiet_NaN());
  /// The gradient of the distance at the query's cell: the unit vector from the nearest
  /// obstacle's centre to the cell's centre (the derivative of the Euclidean distance to that
  /// obstacle). Zero on an obstacle, where the distance is capped, and outside.
  Eigen::Vector3f gradient = Eigen::Vector3f::Zero();
  /// Exact squared distance in cells (not capped), or kOutsideCells / kNoObstacleCells.
  std::uint32_t squared_cells = kOutsideCells;

  static constexpr float kOutside = -1.0f;
  static constexpr std::uint32_t kOutsideCells = 0xFFFFFFFFu;     ///< gpu::kDistanceOutside
  static constexpr std::uint32_t kNoObstacleCells = 0xFFFFFFFEu;  ///< gpu::kDistanceNoObstacle
  bool inside() const { return squared_cells != kOutsideCells; }
};

/// An exact Euclidean distance field over an axis-aligned box of an OccupancyMap, at the map's
/// finest resolution, held on the device. The box is DynamicEDTOctomap's: the cells from the
/// one holding `box_min` to the one holding `box_max` (OctoMap's coordToKey), both included;
/// by default the map's bounds and one cell around them.
/// For every cell it holds the squared distance in cells to the nearest occupied cell of the box
/// (obstacles outside the box do not count, as in dynamicEDT3D) and that cell; pruned leaves
/// count as each of their finest cells. Exact: the integer minimum over all occupied cells.
///
/// The field reads the map when it is built and at update(); between them it answers for the
/// map as it was. The field follows its map through moves; once the map is destroyed, its calls
/// throw kInvalidArgument (destroying it stays safe). Both are used from one thread at a time.
/// Its device bytes count under the map's MapParams::max_device_bytes
/// (OccupancyMap::DeviceBytes::distance_fields). A call that throws leaves the field and the
/// map as they were.
class DistanceField {
 public:
  /// Builds the field from scratch on the device. Throws kInvalidArgument for an inverted box,
  /// a NaN corner, a corner outside the map's key range, max_distance_m <= 0 or NaN, or a box
  /// whose lines the device cannot transform in one dispatch (named with the limit);
  /// kOutOfDeviceMemory when the map's cap (MapParams::max_device_bytes) leaves no room or the
  /// device cannot allocate it (naming the box, the bytes it needs and what to change).
  DistanceField(OccupancyMap& map, const Eigen::Vector3f& box_min, const Eigen::Vector3f& box_max,
                const DistanceFieldOptions& options = {});
  /// The same over the map's bounds: every cell of every leaf the map knows (free or occupied),
  /// and one cell more on each side, so that with treat_unknown_as_occupied the unknown space
  /// around the map bounds the distances at its edge. kInvalidArgument for a map with no leaf.
  explicit DistanceField(OccupancyMap& map, const DistanceFieldOptions& options = {});
  ~DistanceField();
  DistanceField(DistanceField&&) noexcept;
  DistanceField& operator=(DistanceField&&) noexcept;

  /// Brings the field up to the map as it is now (every scan submitted before it included),
  /// equal cell for cell to a field built from scratch. Incremental: the obstacles of the box
  /// are read again, and only the lines of the transform whose input changed are redone. The
  /// obstacles come from the map's change set (only its cells are searched again) where it
  /// holds every cell changed since the last update and is small against the box; else from
  /// the whole tree (after an upload, clearBox, scans with change detection off, a reset of the
  /// set by someone else, or many changes). The first update() turns the map's change detection
  /// on (DynamicEDTOctomap's constructor does; a field only built and queried leaves the map
  /// as it was; the last field to go turns it off again and gives its memory back), and each
  /// update empties the set. A map whose user turned change detection on or off
  /// (OccupancyMap::enableChangeDetection) keeps its set as the user leaves it: the field never
  /// empties it, and reads the whole tree after each user reset.
  void update();

  /// The distance at each point (its cell's centre), with the nearest obstacle and gradient.
  /// Batches whose query buffers the map's cap has no room for run in smaller batches.
  std::vector<DistanceSample> distances(std::span<const Eigen::Vector3f> points) const;
  /// Spheres (centre x, y, z, radius): the clearance distance - radius at each centre's cell,
  /// with the nearest obstacle and gradient. Negative where the sphere reaches an obstacle.
  std::vector<DistanceSample> clearances(std::span<const Eigen::Vector4f> spheres) const;

  /// The whole field, downloaded: per cell (index x + size[0] * (y + size[1] * z)) the exact
  /// squared distance in cells (kNoObstacleCells where the box has no obstacle) and the index of
  /// the nearest occupied cell (same numbering; kNoObstacleCells where none).
  struct Grid {
    std::array<std::uint32_t, 3> size{};
    std::array<std::uint32_t, 3> min_key{};  ///< OctoMap key of cell (0, 0, 0)
    std::vector<std::uint32_t> squared_cells;
    std::vector<std::uint32_t> nearest;
  };
  Grid download() const;

  /// Cells along x, y, z, and the key of cell (0, 0, 0).
  std::array<std::uint32_t, 3> size() const;
  std::array<std::uint32_t, 3> minKey() const;
  const DistanceFieldOptions& options() const;
  /// Device bytes the field holds (its part of the map's cap).
  std::size_t deviceBytes() const;
  /// Device time of the last build or update(), in milliseconds (0 without timestamps).
  double lastUpdateMs() const;
  /// How the last build or update() went: kBuild (every cell and line), kFromTree (the whole
  /// tree read again, only the lines whose input changed redone), kFromChanges (only the cells
  /// in the map's change set read again, only the lines whose input changed redone).
  enum class UpdateKind { kBuild, kFromTree, kFromChanges };
  UpdateKind lastUpdateKind() const;

  class Impl;

 private:
  friend class FieldInteropAccess;  // vulkan_interop.hpp
  Impl& self() const;
  std::unique_ptr<Impl> impl_;
};

}  // namespace octovk
