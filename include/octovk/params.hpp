// octovk: A map's parameters (OctoMap's sensor model and grid) and OctoMap's pose arithmetic.
#pragma once

#include <Eigen/Core>
#include <Eigen/Geometry>
#include <cstddef>
#include <cstdint>
#include <span>
#include <string>

namespace octovk {

/// How castRay is answered on the device (MapParams::cast_ray_backend). All give OctoMap's
/// answers bit for bit.
enum class CastRayBackend : std::uint32_t {
  /// Ray tracing (kRayTracing) where the device can trace rays and loops have no driver limit,
  /// else the walk (docs/benchmarks.md: which is faster where). Under max_device_bytes, a
  /// castRays call whose acceleration structure would not fit answers with the walk.
  kAuto = 0,
  /// A compute shader steps through every cell along the ray, as OctoMap does.
  kWalk = 1,
  /// Rays traced against an acceleration structure over the map's occupied leaves find where
  /// the walk can end; the walk jumps there exactly and decides with OctoMap's steps. Traced
  /// with ray queries (kRayQuery) where the device has them, else through a ray-tracing pipeline
  /// (kRayTracingPipeline): on Mesa 25's lavapipe, which has both, ray queries were faster.
  kRayTracing = 2,
  /// kRayTracing with ray queries in compute shaders. Needs VK_KHR_acceleration_structure and
  /// VK_KHR_ray_query (DeviceInfo::ray_query_enabled).
  kRayQuery = 3,
  /// kRayTracing through a ray-tracing pipeline (a ray generation shader per ray, the boxes'
  /// intersection and any-hit shaders). Needs VK_KHR_acceleration_structure and
  /// VK_KHR_ray_tracing_pipeline (DeviceInfo::ray_tracing_pipeline), as NVIDIA's drivers offer
  /// them without ray queries.
  kRayTracingPipeline = 4,
};

/// How a scan's rays find their cells (MapParams::scan_rays). All give OctoMap's map bit for bit.
/// Numbered as CastRayBackend (0 is no value here: a scan has no automatic choice).
enum class ScanRays : std::uint32_t {
  /// A compute shader steps OctoMap's DDA (computeRayKeys) through every cell of every ray.
  kWalk = 1,
  /// The paper's way: rays traced against an acceleration structure over the boxes a free
  /// update can change (occupied leaves, free leaves not yet clamped, unknown space), built on
  /// the device in each scan's own submission; OctoMap's DDA steps only through the boxes a ray
  /// crosses and jumps exactly over leaves already clamped free, whose free updates OctoMap
  /// aborts (ScanStats::free_cells then leaves those cells out). Traced as CastRayBackend::
  /// kRayTracing is (ray queries where the device has them, else a ray-tracing pipeline); needs
  /// one of them and loops without a driver limit.
  kRayTracing = 2,
  /// kRayTracing with ray queries (VK_KHR_ray_query).
  kRayQuery = 3,
  /// kRayTracing through a ray-tracing pipeline (VK_KHR_ray_tracing_pipeline).
  kRayTracingPipeline = 4,
};
static_assert(static_cast<std::uint32_t>(ScanRays::kRayQuery) ==
                  static_cast<std::uint32_t>(CastRayBackend::kRayQuery) &&
              static_cast<std::uint32_t>(ScanRays::kRayTracingPipeline) ==
                  static_cast<std::uint32_t>(CastRayBackend::kRayTracingPipeline));

/// What every node holds besides its log-odds (MapParams::payload): OctoMap's tree type.
enum class Payload : std::uint32_t {
  kNone = 0,   ///< OcTree: the log-odds alone
  kColor = 1,  ///< ColorOcTree: a colour per node (Rgb; white is "no colour yet")
  kStamp = 2,  ///< OcTreeStamped: a time stamp per node, whole seconds
};
/// OctoMap's tree-type name of a payload ("OcTree", "ColorOcTree", "OcTreeStamped").
const char* treeTypeName(Payload payload);

/// A colour, as OctoMap's ColorOcTreeNode::Color. White (255, 255, 255) is OctoMap's "no colour
/// yet" (isColorSet() false).
struct Rgb {
  std::uint8_t r = 255;
  std::uint8_t g = 255;
  std::uint8_t b = 255;
  friend bool operator==(const Rgb&, const Rgb&) = default;
};
/// A colour packed as HostTree::Node::payload and the device hold it: r | g << 8 | b << 16.
constexpr std::uint32_t packRgb(Rgb c) {
  return std::uint32_t{c.r} | (std::uint32_t{c.g} << 8) | (std::uint32_t{c.b} << 16);
}
constexpr Rgb unpackRgb(std::uint32_t v) {
  return Rgb{static_cast<std::uint8_t>(v & 0xFFu), static_cast<std::uint8_t>((v >> 8) & 0xFFu),
             static_cast<std::uint8_t>((v >> 16) & 0xFFu)};
}
/// The payload of a new node: white for colour, stamp 0, 0 for none (OctoMap's constructors).
constexpr std::uint32_t newNodePayload(Payload payload) {
  return payload == Payload::kColor ? 0x00FFFFFFu : 0u;
}

/// How a point's colour is folded into its node (ScanOptions::color_fold).
enum class ColorFold : std::uint32_t {
  /// ColorOcTree::averageNodeColor: an uncoloured node takes the colour, a coloured one the
  /// integer mean of its colour and the new one, per channel.
  kAverage = 0,
  /// ColorOcTree::integrateNodeColor: an uncoloured node takes the colour, a coloured one
  /// old * p + new * (0.99 - p) per channel in double, p the node's occupancy
  /// (octomap::probability: exp correctly rounded on the device, shaders/probability.glsl), the
  /// result truncated to 8 bits as x86-64 GCC converts a double to uint8_t (a negative channel,
  /// possible only with clamping_max above 0.99, wraps: -1 gives 255). glibc's exp, which OctoMap
  /// calls, is not always correctly rounded: p differs by an ULP at 2 in 100,000 log-odds, and
  /// a colour at 21 of the 2.15 billion of the default clamping range, for old = new = 100 or
  /// 200 only, one apart from OctoMap's (docs/benchmarks.md).
  kIntegrate = 1,
};

/// The sensor model and grid, with OctoMap's defaults.
struct MapParams {
  double resolution = 0.1;
  double prob_hit = 0.7;
  double prob_miss = 0.4;
  double clamping_min = 0.1192;
  double clamping_max = 0.971;
  double occupancy_threshold = 0.5;
  /// Most nodes the device pool may hold; 0 = as many as the device's memory allows. A scan that
  /// would need more throws kOutOfDeviceMemory and leaves the map as it was.
  std::size_t max_nodes = 0;
  /// Most bytes the map may hold on the device, all its buffers together: the node pool, the
  /// leaf boxes, the per-scan scratch (cell sets, lists, points, ray walks, depth image, upload
  /// staging) and the query buffers; 0 = no cap. It bounds what the map holds between calls
  /// (OccupancyMap::deviceBytes() never exceeds it); while a buffer is replaced by a larger one
  /// both exist for a moment, so the peak during a growth can be higher. A scan or query batch
  /// that would need more throws kOutOfDeviceMemory and leaves the map as it was; the map keeps
  /// working. At least minDeviceBytes().
  std::size_t max_device_bytes = 0;
  /// castRay's backend. A ray-tracing backend the device cannot run (no ray queries for
  /// kRayQuery, no pipelines for kRayTracingPipeline, neither for kRayTracing, or a loop limit)
  /// makes the map's constructor throw kMissingFeature. OccupancyMap::castRayInfo().backend
  /// says what runs: kWalk, kRayQuery or kRayTracingPipeline. The acceleration structure counts
  /// under max_device_bytes (with the query buffers): where it would not fit, a castRays call with
  /// kAuto answers with the walk (the same answers; CastRayInfo::cap_fallbacks), with a
  /// ray-tracing backend it throws kOutOfDeviceMemory and the map stays as it was.
  CastRayBackend cast_ray_backend = CastRayBackend::kAuto;
  /// How scans find their cells. A ray-tracing value the device cannot run (as for
  /// cast_ray_backend), or one with max_device_bytes set (the acceleration structure is not
  /// under the cap), makes the map's constructor throw kMissingFeature / kInvalidArgument.
  ScanRays scan_rays = ScanRays::kWalk;
  /// What each node holds besides its log-odds. ColorMap and StampedMap set it; an
  /// OccupancyMap made with kColor or kStamp is the same map without their extra calls.
  Payload payload = Payload::kNone;

  /// Device bytes an empty map with these parameters holds: the smallest max_device_bytes.
  std::size_t minDeviceBytes() const;

  /// Empty when valid, else a sentence naming the bad value.
  std::string validate() const;
};

/// How one scan is inserted: OctoMap's insertPointCloud arguments after the points and origin
/// (lazy_eval is always false: the inner nodes are updated with every scan).
struct ScanOptions {
  double max_range_m = -1.0;  ///< rays longer than this are cut there (no occupied end); < 0: none
  bool discretize = false;    ///< OctoMap's discretize: one ray per distinct end cell
  /// Colour maps (Payload::kColor): one colour per point (per pixel for a depth image, row by
  /// row), folded after the scan into the node search() finds for each point, in the cloud's
  /// order, as ColorOcTree::averageNodeColor (or integrateNodeColor) called for every point.
  /// Empty: no colour. kInvalidArgument where the count differs from the points' or the map
  /// holds no colour. The colours are copied before the call returns.
  std::span<const Rgb> colors{};
  ColorFold color_fold = ColorFold::kAverage;
  /// Stamped maps (Payload::kStamp): the scan's time in whole seconds, which every node the scan
  /// updates takes (OcTreeStamped's time(NULL)). 0 for other maps: a stamp given to a map that
  /// holds none is kInvalidArgument (it would be lost).
  std::uint32_t stamp = 0;
};

/// A rigid transform with OctoMap's float arithmetic (octomath::Pose6D): rotation applied as
/// q * v * q^-1 in single precision, then the translation added.
struct Pose {
  Eigen::Vector3f translation = Eigen::Vector3f::Zero();
  Eigen::Quaternionf rotation = Eigen::Quaternionf::Identity();

  /// `this` applied to v, bit-exact with octomath::Pose6D::transform.
  Eigen::Vector3f transform(const Eigen::Vector3f& v) const;
  /// The inverse, bit-exact with octomath::Pose6D::inv.
  Pose inverse() const;
};

}  // namespace octovk
