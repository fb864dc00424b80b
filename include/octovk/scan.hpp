// octovk: What a scan is given (point clouds, depth images) and what it reports (ScanStats).
#pragma once

#include <Eigen/Core>
#include <cstddef>
#include <cstdint>
#include <span>
#include <string>
#include <variant>
#include <vector>

namespace octovk {

/// Device time of each stage of one scan, from Vulkan timestamp queries (all zero when the
/// device has no timestamps on its compute queue).
struct StageTimes {
  double upload_ms = 0;       ///< points, parameters, clearing the cell sets
  double ray_keys_ms = 0;     ///< transform, discretize, ray walk into the hash set
  double classify_ms = 0;     ///< early abort against the tree, new-block count
  double tree_update_ms = 0;  ///< create, expand, log-odds update
  double prune_ms = 0;        ///< prune and inner-node values
  double leaf_boxes_ms = 0;   ///< leaf-box rebuild
  /// With ScanRays::kRayTracing, the parts of ray_keys_ms (not added again by total()): the
  /// boxes of the scan's acceleration structure, its build, and the rays traced through it.
  double scan_boxes_ms = 0;
  double scan_build_ms = 0;
  double scan_trace_ms = 0;
  /// The stages' sum (the scan_* parts are inside ray_keys_ms).
  double total_ms() const {
    return upload_ms + ray_keys_ms + classify_ms + tree_update_ms + prune_ms + leaf_boxes_ms;
  }
  /// The old name of total_ms(), kept for one release (the unit is in every other field's name).
  [[deprecated("StageTimes::total() is total_ms()")]] double total() const { return total_ms(); }
};

/// A scan submitted with OccupancyMap::submitPointCloud / submitDepthImage: 1, 2, 3, ... in
/// submission order (the blocking calls take one too).
using ScanTicket = std::uint64_t;

/// What one insertPointCloud (or one submitted scan) did.
struct ScanStats {
  ScanTicket ticket = 0;              ///< the scan's place in the map's order
  std::size_t points = 0;             ///< points given (for a depth image: its pixels)
  std::size_t skipped_nonfinite = 0;  ///< NaN or infinite coordinates: nothing inserted
  std::size_t skipped_outside = 0;    ///< ray or end cell outside the map: nothing inserted
  std::size_t skipped_no_depth = 0;   ///< depth-image pixels with no depth (d = 0, non-finite)
  /// Distinct cells updated as free (before early abort). With ScanRays::kRayTracing the cells
  /// whose leaf is already clamped free are mostly not counted (the rays jump over them: their
  /// updates are no-ops), so this is lower than OctoMap's computeUpdate count; the map is the
  /// same.
  std::size_t free_cells = 0;
  std::size_t occupied_cells = 0;  ///< distinct cells updated as occupied (before early abort)
  std::size_t aborted_cells = 0;   ///< cells already at the clamping bound: left unchanged
  std::size_t nodes = 0;           ///< nodes in the tree after the scan
  /// Times the scan was run: more than 1 when the device refused it (a set, the pool or the
  /// lists too small, or an earlier scan in flight refused) and it ran again after growth.
  std::size_t cell_set_attempts = 0;
  /// Parts the scan was applied in, each the cells of a group of tiles: more than 1 where its
  /// cells did not fit the scan scratch at once (under MapParams::max_device_bytes, or what the
  /// device gives). The map is the same either way; each part walks every ray again.
  std::size_t tile_groups = 1;
  /// Host wall time of the call: the whole blocking call; for a submitted scan, the time
  /// submit*() took (staging its input and recording; waits for a busy frame or growth
  /// included).
  double wall_ms = 0.0;
  StageTimes device;  ///< device time per stage (of the final attempt)
};

/// A depth image and the pinhole camera that took it (camera frame: x right, y down, z forward).
/// Pixel (u, v) with depth d becomes the point z = d / depth_scale, x = (u - cx) * z / fx,
/// y = (v - cy) * z / fy, in float, in that order. Pixels with no usable depth are skipped:
/// d = 0 or non-finite (also a subnormal d, or a z that is 0, subnormal or not finite, which no
/// sensor produces and devices may flush differently). E.g.
/// `DepthImage{.width = 640, .height = 480, .depths = std::span<const std::uint16_t>(raw)}`, or
/// for metres in float `.encoding = DepthImage::Encoding::kFloat32, .depths =
/// std::span<const float>(metres), .depth_scale = 1`.
struct DepthImage {
  enum class Encoding : std::uint32_t { kUint16 = 0, kFloat32 = 1 };
  /// The host's depths: none, or a typed view of them.
  using Depths =
      std::variant<std::monostate, std::span<const std::uint16_t>, std::span<const float>>;
  std::uint32_t width = 0;
  std::uint32_t height = 0;
  /// The depths' type: std::uint16_t (kUint16) or float (kFloat32). `depths` must hold that type
  /// (validate() refuses a mismatch); for insertDepthImageOnDevice it describes the device buffer.
  Encoding encoding = Encoding::kUint16;
  /// width * height depths, row by row, no padding; the span is only read during the call (the
  /// submit calls copy it). Empty (std::monostate) only for insertDepthImageOnDevice, which
  /// ignores it.
  Depths depths;
  float fx = 525.0f, fy = 525.0f, cx = 319.5f, cy = 239.5f;  ///< TUM RGB-D's defaults
  float depth_scale = 5000.0f;  ///< depth units per metre (TUM: 5000; metres in float: 1)

  /// Empty when valid, else a sentence naming the bad value and its fix: among others no
  /// depths, depths of the other type than `encoding`, or fewer or more than width * height.
  std::string validate() const;
};

/// The points of a depth image in the camera frame, computed on the host with the same float
/// operations the device uses, row by row (v), then column (u). `skipped` (if given) receives
/// the number of pixels with no usable depth.
std::vector<Eigen::Vector3f> unprojectDepthImage(const DepthImage& image,
                                                 std::size_t* skipped = nullptr);

}  // namespace octovk
