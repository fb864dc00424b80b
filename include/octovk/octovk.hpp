// octovk: an OctoMap-compatible occupancy octree that lives and is updated on a Vulkan device.
#pragma once

#include <Eigen/Core>
#include <Eigen/Geometry>
#include <cstddef>
#include <cstdint>
#include <functional>
#include <memory>
#include <optional>
#include <span>
#include <stdexcept>
#include <string>
#include <vector>

namespace octovk {

/// What went wrong, coarsely, so callers can react without parsing messages.
enum class ErrorCode {
  kNoDevice,           ///< no Vulkan device (install mesa-vulkan-drivers for the CPU device)
  kMissingFeature,     ///< the device lacks a feature octovk needs; the message names it
  kInvalidArgument,    ///< a parameter or input is out of its domain
  kOutOfDeviceMemory,  ///< the device could not hold the map; the map is as before the call
  kVulkan,             ///< an unexpected Vulkan failure; the message names the call and VkResult
  kIo,                 ///< a file could not be read or written
  kFormat,             ///< a file is not in the expected format
  /// The host could not allocate memory (std::bad_alloc inside octovk); the map is as before
  /// the call and keeps working.
  kOutOfHostMemory,
  /// octovk broke one of its own invariants: a bug, to be reported with the input.
  kInternal,
};

/// The one exception type of octovk. The library never exits the process.
class Error : public std::runtime_error {
 public:
  Error(ErrorCode code, const std::string& message, std::uint64_t scan = 0)
      : std::runtime_error(message), code_(code), scan_(scan) {}
  ErrorCode code() const noexcept { return code_; }
  /// For an error a synchronisation found in a scan submitted earlier (OccupancyMap::submit*,
  /// see there): that scan's ticket, so that a caller can say which of its inputs failed; 0 when
  /// the error is about the call that threw it.
  std::uint64_t scan() const noexcept { return scan_; }

 private:
  ErrorCode code_;
  std::uint64_t scan_;
};

/// A value or the reason there is none, for setup steps that fail for ordinary reasons.
template <class T>
class [[nodiscard]] Result {
 public:
  Result(T value) : value_(std::move(value)) {}      // NOLINT(google-explicit-constructor)
  Result(Error error) : error_(std::move(error)) {}  // NOLINT(google-explicit-constructor)
  explicit operator bool() const noexcept { return value_.has_value(); }
  T& value() {
    if (!value_) throw *error_;
    return *value_;
  }
  /// The reason there is no value; when there is one, an Error saying so (kInternal).
  const Error& error() const {
    static const Error kNoError(ErrorCode::kInternal, "Result::error() called on a value");
    return error_ ? *error_ : kNoError;
  }

 private:
  std::optional<T> value_;
  std::optional<Error> error_;
};

/// The sensor model and grid, with OctoMap's defaults.
/// How castRay is answered on the device (MapParams::cast_ray_backend). Both give OctoMap's
/// answers bit for bit.
enum class CastRayBackend : std::uint32_t {
  /// The ray-tracing backend where the device has ray queries, loops without a driver limit and
  /// no device-memory cap is set; else the walk (docs/benchmarks.md: which is faster where).
  kAuto = 0,
  /// A compute shader steps through every cell along the ray, as OctoMap does.
  kWalk = 1,
  /// Ray queries against an acceleration structure over the map's occupied and unknown boxes
  /// find where the walk can end; the walk jumps there exactly and decides with OctoMap's steps.
  /// Needs VK_KHR_acceleration_structure and VK_KHR_ray_query (DeviceInfo::ray_query_enabled).
  kRayTracing = 2,
};

/// How a scan's rays find their cells (MapParams::scan_rays). Both give OctoMap's map bit for bit.
enum class ScanRays : std::uint32_t {
  /// A compute shader steps OctoMap's DDA (computeRayKeys) through every cell of every ray.
  kWalk = 0,
  /// The paper's way: ray queries against an acceleration structure over the boxes a free
  /// update can change (occupied leaves, free leaves not yet clamped, unknown space), built on
  /// the device in each scan's own submission; OctoMap's DDA steps only through the boxes a ray
  /// crosses and jumps exactly over leaves already clamped free, whose free updates OctoMap
  /// aborts (ScanStats::free_cells then leaves those cells out). Needs VK_KHR_acceleration_
  /// structure and VK_KHR_ray_query (DeviceInfo::ray_query_enabled) and loops without a driver
  /// limit.
  kRayTracing = 1,
};

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
  /// castRay's backend. kRayTracing on a device without ray queries (or with a loop limit)
  /// makes the map's constructor throw kMissingFeature. The acceleration structure counts under
  /// max_device_bytes (with the query buffers): where it would not fit, a castRays call with
  /// kAuto answers with the walk (the same answers; CastRayInfo::cap_fallbacks), with
  /// kRayTracing it throws kOutOfDeviceMemory and the map stays as it was.
  CastRayBackend cast_ray_backend = CastRayBackend::kAuto;
  /// How scans find their cells. kRayTracing on a device without ray queries (or with a loop
  /// limit, or with max_device_bytes set: the acceleration structure is not under the cap)
  /// makes the map's constructor throw kMissingFeature / kInvalidArgument.
  ScanRays scan_rays = ScanRays::kWalk;

  /// Device bytes an empty map with these parameters holds: the smallest max_device_bytes.
  std::size_t minDeviceBytes() const;

  /// Empty when valid, else a sentence naming the bad value.
  std::string validate() const;
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

/// Which device to use: empty picks a real GPU when present, else lavapipe. The OCTOVK_DEVICE
/// environment variable (index or name substring) overrides when `selector` is empty.
struct ContextOptions {
  std::string selector;
  /// Runs every Vulkan call through the Khronos validation layer (core and synchronization
  /// validation; package vulkan-validationlayers). The OCTOVK_VALIDATION environment variable
  /// (set and not "0") turns it on too. For debugging and tests: it is slow.
  bool enable_validation = false;
  /// Receives each validation warning or error (one line each), in the thread of the Vulkan call
  /// that caused it. Without it, messages go to stderr. Either way they are counted
  /// (validationMessageCount()).
  std::function<void(const std::string&)> on_validation_message;
  /// For tests: treat the device's maxStorageBufferRange as at most this many bytes (0: the
  /// device's own), to check that no binding depends on a large range.
  std::uint64_t max_binding_bytes = 0;
  /// Enable ray queries (VK_KHR_acceleration_structure + VK_KHR_ray_query) where the device has
  /// them, for castRay's ray-tracing backend. false: never (the compute walk only).
  bool enable_ray_query = true;
};

/// Validation messages received by every Context of this process so far.
std::size_t validationMessageCount() noexcept;

/// The device a Context runs on.
struct DeviceInfo {
  std::string name;
  std::string type;    ///< "discrete GPU", "integrated GPU", "CPU", ...
  std::string driver;  ///< driver name and version, e.g. "llvmpipe: Mesa 25.0.7 (LLVM 15.0.6)"
  std::uint32_t index = 0;
  std::uint64_t memory_bytes = 0;
  /// The device offers ray queries against acceleration structures (VK_KHR_acceleration_structure
  /// and VK_KHR_ray_query with their features): castRay can use its ray-tracing backend.
  bool ray_query = false;
  /// It also offers ray-tracing pipelines (VK_KHR_ray_tracing_pipeline); octovk does not need them.
  bool ray_tracing_pipeline = false;
  /// Ray queries are enabled on this Context's device (Context::device() only; false in
  /// listDevices()).
  bool ray_query_enabled = false;
};

namespace vk {
class Device;
}
class InteropAccess;

/// The Vulkan device every map of a process shares.
///
/// Threads: a Context may be shared by maps used from different threads at once (their
/// submissions to the device's one queue and the pipelines built at first use are serialised
/// inside). One OccupancyMap is used from one thread at a time: calls on the same map from two
/// threads, const queries included, must be ordered by the caller (a map records into its own
/// command buffers). Different maps need no ordering.
///
/// Lifetime: each map keeps the device alive, so a Context may be destroyed before its maps;
/// the device goes with the last of them.
class Context {
 public:
  static Result<std::unique_ptr<Context>> create(const ContextOptions& options = {});
  ~Context();
  Context(const Context&) = delete;
  Context& operator=(const Context&) = delete;

  const DeviceInfo& device() const noexcept;
  /// Every usable Vulkan device, for --help and error messages.
  static std::vector<DeviceInfo> listDevices();

  vk::Device& vulkan() noexcept { return *device_; }
  /// The device, shared with the maps that use it (they keep it alive).
  std::shared_ptr<vk::Device> sharedDevice() const noexcept { return device_; }

 private:
  explicit Context(std::unique_ptr<vk::Device> device);
  std::shared_ptr<vk::Device> device_;
};

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
  double total() const {
    return upload_ms + ray_keys_ms + classify_ms + tree_update_ms + prune_ms + leaf_boxes_ms;
  }
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
/// sensor produces and devices may flush differently).
struct DepthImage {
  enum class Encoding : std::uint32_t { kUint16 = 0, kFloat32 = 1 };
  std::uint32_t width = 0;
  std::uint32_t height = 0;
  Encoding encoding = Encoding::kUint16;
  /// width * height depths (std::uint16_t or float as `encoding` says), row by row, no padding.
  const void* pixels = nullptr;
  float fx = 525.0f, fy = 525.0f, cx = 319.5f, cy = 239.5f;  ///< TUM RGB-D's defaults
  float depth_scale = 5000.0f;  ///< depth units per metre (TUM: 5000; metres in float: 1)

  /// Empty when valid, else a sentence naming the bad value.
  std::string validate() const;
};

/// The points of a depth image in the camera frame, computed on the host with the same float
/// operations the device uses, row by row (v), then column (u). `skipped` (if given) receives
/// the number of pixels with no usable depth.
std::vector<Eigen::Vector3f> unprojectDepthImage(const DepthImage& image,
                                                 std::size_t* skipped = nullptr);

/// The tree as the host sees it after an explicit download. Node index = block * 8 + slot;
/// the root is node 0. Children of node n are at children * 8 + i where bit i of mask is set.
struct HostTree {
  struct Node {
    float log_odds;
    std::uint32_t children;
    std::uint32_t mask;
  };
  bool root_exists = false;
  std::vector<Node> nodes;
};

/// State of a cell as OctoMap's search() and isNodeOccupied() see it.
enum class CellState : std::uint32_t { kUnknown = 0, kFree = 1, kOccupied = 2 };

/// Result of a point lookup: the deepest existing node on the point's path (OctoMap's search,
/// pruned nodes included). Unknown for points outside the map, NaN points and unmapped space.
struct Lookup {
  CellState state = CellState::kUnknown;
  float log_odds = 0.0f;    ///< of the node found (0 when unknown)
  std::uint32_t depth = 0;  ///< depth of the node found, 16 = finest (0 when unknown)
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

/// The occupancy octree, held in device buffers. Not copyable; movable. A moved-from map throws
/// kInvalidArgument from every call until a map is assigned to it. One thread at a time (see
/// Context). A call that throws leaves the map as it was before the call (a std::bad_alloc
/// inside becomes kOutOfHostMemory), and the map keeps working.
class OccupancyMap {
 public:
  OccupancyMap(Context& context, const MapParams& params);
  ~OccupancyMap();
  OccupancyMap(OccupancyMap&&) noexcept;
  OccupancyMap& operator=(OccupancyMap&&) noexcept;

  const MapParams& params() const noexcept;

  /// OctoMap's insertPointCloud(points, origin, max_range, lazy_eval=false, discretize) with
  /// points and origin in the world frame. max_range_m < 0 means unlimited.
  ScanStats insertPointCloud(std::span<const Eigen::Vector3f> points_world,
                             const Eigen::Vector3f& origin_world, double max_range_m = -1.0,
                             bool discretize = false);

  /// OctoMap's insertPointCloud(points, sensor_origin, frame_origin, ...): points and sensor origin
  /// in the sensor frame; both are moved to the world by T_world_sensor, the points on the device.
  ScanStats insertPointCloud(std::span<const Eigen::Vector3f> points_sensor,
                             const Eigen::Vector3f& origin_sensor, const Pose& T_world_sensor,
                             double max_range_m = -1.0, bool discretize = false);

  /// A depth image, unprojected on the device (DepthImage), then inserted like
  /// insertPointCloud(points_camera, origin_camera, T_world_camera, max_range_m, discretize):
  /// the result equals inserting unprojectDepthImage(image) with that overload.
  ScanStats insertDepthImage(const DepthImage& image, const Pose& T_world_camera,
                             double max_range_m = -1.0,
                             const Eigen::Vector3f& origin_camera = Eigen::Vector3f::Zero(),
                             bool discretize = false);

  // ---- streaming: scans submitted back to back, no host wait per scan ----
  //
  // submit*() stages the input (points or pixels copied into one of 3 staging buffers), records
  // the scan and submits it, and returns without waiting; the device decides on its own whether
  // the scan fits. The host waits only when all 3 frames are in flight (the oldest one then), or
  // when buffers must grow. A scan that did not fit leaves the map as it was, and so do the
  // scans behind it; at the next synchronisation (flush(), or any call that reads or changes
  // the map: queries, download, nodeCount, insertPointCloud, ...) the library grows what was
  // short and runs them again in order. The map after any sequence of submits equals the map of
  // the same scans inserted one by one with the blocking calls, and OctoMap's.
  // Errors a scan's input shows are thrown by submit*() (nothing submitted); an error found on
  // the device (a pool over MapParams::max_nodes, the memory cap, ...) is thrown by the
  // synchronisation that finds it: the map then holds every scan before the failing one, and
  // it and the scans submitted after it are not inserted (the message names its ticket, and
  // Error::scan() gives it).

  /// insertPointCloud(points_world, origin_world, ...), submitted without waiting. The points
  /// are copied before it returns: the span may be reused at once.
  ScanTicket submitPointCloud(std::span<const Eigen::Vector3f> points_world,
                              const Eigen::Vector3f& origin_world, double max_range_m = -1.0,
                              bool discretize = false);
  /// insertPointCloud(points_sensor, origin_sensor, T_world_sensor, ...), without waiting.
  ScanTicket submitPointCloud(std::span<const Eigen::Vector3f> points_sensor,
                              const Eigen::Vector3f& origin_sensor, const Pose& T_world_sensor,
                              double max_range_m = -1.0, bool discretize = false);
  /// insertDepthImage(...), without waiting. The pixels are copied before it returns.
  ScanTicket submitDepthImage(const DepthImage& image, const Pose& T_world_camera,
                              double max_range_m = -1.0,
                              const Eigen::Vector3f& origin_camera = Eigen::Vector3f::Zero(),
                              bool discretize = false);
  /// Waits until every submitted scan is in the map (running refused ones again); throws as
  /// described above.
  void flush();
  /// Whether scan `ticket` is in the map; does not wait (takes the results already there).
  bool finished(ScanTicket ticket);
  /// Statistics of the submitted scans known to be in the map since the last call, in ticket
  /// order (the newest 4096 are kept); does not wait. Blocking calls return their own instead.
  std::vector<ScanStats> takeScanStats();
  /// Submitted scans not yet known to be in the map.
  std::size_t scansInFlight() const noexcept;
  /// Device submissions this map made, and the times the host waited for one still running
  /// (for a free frame, for results, before growing), since the map was made: for measuring
  /// how much of a stream the host spends waiting.
  struct SyncCounts {
    std::uint64_t submissions = 0;
    std::uint64_t host_waits = 0;
  };
  SyncCounts syncCounts() const noexcept;

  /// One leaf: centre, edge length, log-odds.
  struct LeafBoxHost {
    float center[3];
    float size;
    float log_odds;
  };
  /// The same scan, then `queries` on the updated map, recorded in the same command stream (no
  /// host round trip between the update and the queries).
  ScanStats insertPointCloud(std::span<const Eigen::Vector3f> points_world,
                             const Eigen::Vector3f& origin_world, double max_range_m,
                             bool discretize, const QueryRequest& queries, QueryResults& results);

  /// OctoMap's search() for each point, on the device.
  std::vector<Lookup> search(std::span<const Eigen::Vector3f> points) const;
  /// OctoMap's castRay for each ray, on the device.
  std::vector<RayHit> castRays(std::span<const Ray> rays) const;
  /// The leaves OctoMap's leaf_bbx_iterator(min, max) visits (all, or only the occupied ones),
  /// compacted on the device and downloaded. Empty if a corner lies outside the map.
  std::vector<LeafBoxHost> leavesInBox(const Eigen::Vector3f& min, const Eigen::Vector3f& max,
                                       bool occupied_only = false) const;

  /// Nodes in the tree (read from the device's counters, no map data moves).
  std::size_t nodeCount() const;
  /// Device bytes held by this map's buffers (staging included): what
  /// MapParams::max_device_bytes caps.
  std::size_t deviceBytes() const;
  /// Of those, the node pool (nodes, block records, free-block stack, at their capacity); the
  /// rest is per-scan scratch, query buffers and the leaf boxes (deviceBytesByUse()).
  std::size_t poolBytes() const;
  /// deviceBytes() by use.
  struct DeviceBytes {
    std::size_t pool = 0;        ///< nodes, block records, free-block stack (poolBytes())
    std::size_t leaf_boxes = 0;  ///< a leaf box per pool slot
    /// Per-scan scratch: cell sets, touched lists, points and their upload staging, ray walks,
    /// depth image, counters. Sized by the largest scan since it was last released (trim(), or
    /// automatically after an outsized scan).
    std::size_t scratch = 0;
    std::size_t queries = 0;  ///< query input and output, with their staging
    std::size_t total() const { return pool + leaf_boxes + scratch + queries; }
  };
  DeviceBytes deviceBytesByUse() const;

  /// castRay's backend on this map and what its acceleration structure cost (ray tracing only).
  struct CastRayInfo {
    CastRayBackend backend = CastRayBackend::kWalk;  ///< kWalk or kRayTracing, as castRays runs
    std::size_t builds = 0;  ///< acceleration-structure builds (lazily, by castRays) since trim()
    double last_build_ms = 0.0;      ///< device time of the last: the boxes, then the structures
    double last_boxes_ms = 0.0;      ///< of which the boxes (leaf boxes if stale, accel_boxes)
    std::size_t occupied_boxes = 0;  ///< boxes of the last build: occupied leaves
    std::size_t unknown_boxes = 0;   ///< and unknown regions
    std::size_t device_bytes = 0;    ///< boxes, structures, scratch (in deviceBytesByUse().queries)
    /// castRays calls answered by the walk because, under MapParams::max_device_bytes, the
    /// structure would not have fitted (kAuto only; kRayTracing throws kOutOfDeviceMemory).
    std::size_t cap_fallbacks = 0;
  };
  CastRayInfo castRayInfo() const;
  /// deviceBytesByUse().scratch.
  std::size_t scratchBytes() const;
  /// Releases the per-scan scratch and the query buffers back to an empty map's sizes (the
  /// node pool and the leaf boxes stay). The next scan or query grows them again; results do
  /// not change. A scan also releases the scratch by itself when an outsized scan grew it: when
  /// the largest scan since the last release had more than 4 times the points of the median of
  /// the last 8 scans, and the scratch holds more than 4 MiB.
  void trim();
  /// Leaves of the map (rebuilding the leaf boxes first if they are out of date).
  std::size_t leafCount() const;

  /// Whether each scan ends by rebuilding the leaf boxes. Off (the default), they are rebuilt
  /// on the next leafCount() / downloadLeafBoxes() that follows a scan: the rebuild visits every
  /// block of the map, so doing it after every scan makes a scan's cost grow with the map.
  void setLeafBoxesEveryScan(bool every_scan);

  /// Explicit transfer of the whole tree to the host.
  HostTree download() const;
  /// Replaces the map with `tree` (explicit transfer to the device).
  void upload(const HostTree& tree);

  /// The leaf boxes (centre, size, log-odds) of the map, downloaded.
  std::vector<LeafBoxHost> downloadLeafBoxes() const;

  class Impl;

 private:
  friend class InteropAccess;  // vulkan_interop.hpp
  /// impl_, or kInvalidArgument for a moved-from map.
  Impl& self() const;
  std::unique_ptr<Impl> impl_;
};

}  // namespace octovk
