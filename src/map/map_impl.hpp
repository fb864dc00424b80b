// OccupancyMap::Impl: the map's state (params, buffers, what the last scan left in the sets) and
// the host-side decisions of each operation. The passes it records are in map/passes/.
#pragma once

#include <chrono>
#include <cstdint>
#include <deque>
#include <memory>
#include <optional>
#include <span>
#include <vector>

#include "map/map_buffers.hpp"
#include "map/passes/passes.hpp"
#include "map/ray_scene.hpp"
#include "map/reference.hpp"
#include "octovk/octovk.hpp"
#include "vk/device.hpp"

namespace octovk {

class OccupancyMap::Impl {
  // First, so destroyed last: every buffer, scene and stream below is released before the last
  // reference to the device can go (a Context may be destroyed before its maps).
  std::shared_ptr<vk::Device> device_owner_;

 public:
  using DeviceBytes = OccupancyMap::DeviceBytes;
  Impl(Context& context, const MapParams& params);
  ~Impl();  // waits for the scans in flight (their results are dropped)

  /// What a scan inserts: points, or a depth image (unprojected on the device), from the host
  /// or from a caller's device buffer (`device`, read once `wait` is signalled).
  struct ScanSource {
    std::span<const Eigen::Vector3f> points;
    const DepthImage* depth = nullptr;  ///< its pixels are ignored when `device` is given
    std::size_t device_points = 0;      ///< points in `device` (when no depth image)
    VkBuffer device = VK_NULL_HANDLE;
    VkDeviceSize device_offset = 0;
    VkSemaphore wait = VK_NULL_HANDLE;
    std::uint64_t wait_value = 0;
    std::size_t count() const {
      if (depth) return std::size_t{depth->width} * depth->height;
      return device != VK_NULL_HANDLE ? device_points : points.size();
    }
  };
  /// One scan, then the queries if any, waited for: submit() and flush(), the scan's errors
  /// thrown with the map as before it.
  ScanStats insert(const ScanSource& source, const Eigen::Vector3f& origin, const Pose* pose,
                   double max_range, bool discretize, const QueryRequest* queries = nullptr,
                   QueryResults* results = nullptr);
  /// Records and submits a scan without waiting for it (the host's points or pixels are copied
  /// into the frame's staging first); returns its ticket. Waits only where a frame is still
  /// busy or buffers must grow.
  std::uint64_t submit(const ScanSource& source, const Eigen::Vector3f& origin, const Pose* pose,
                       double max_range, bool discretize);
  /// Waits for every submitted scan; a scan the device refused (and the ones behind it) run
  /// again after the host grew what was short. Throws where a scan cannot be inserted: the
  /// map then holds every scan before it, and it and the later ones are dropped.
  void flush();
  /// Statistics of the scans known to be in the map, in order, not taken before.
  std::vector<ScanStats> takeStats();
  /// Whether scan `ticket` is in the map (polls, does not wait).
  bool finished(std::uint64_t ticket);
  std::size_t scansInFlight() const { return pending_.size(); }
  OccupancyMap::SyncCounts syncCounts() const {
    return {stream_.submissions(), stream_.blockingWaits()};
  }
  QueryResults runQueries(const QueryRequest& queries);
  /// A castRay (rays) or lookup batch between ranges of the caller's buffers (interop).
  void queryOnDevice(bool rays, VkBuffer in, VkDeviceSize in_offset, VkDeviceSize in_size,
                     VkBuffer out, VkDeviceSize out_offset, VkDeviceSize out_size,
                     std::uint32_t count);
  std::vector<LeafBoxHost> leavesInBox(const Eigen::Vector3f& min, const Eigen::Vector3f& max,
                                       bool occupied_only);
  HostTree download();
  void upload(const HostTree& tree);
  std::vector<LeafBoxHost> downloadLeafBoxes();
  gpu::PoolState readPool();
  /// Every buffer and both scenes (MapBuffers counts the scenes, see noteSceneBytes).
  std::size_t deviceBytes() const { return buffers_.deviceBytes(); }
  std::size_t poolBytes() const { return buffers_.poolBytes(); }
  DeviceBytes deviceBytesByUse() const;
  /// Releases the per-scan scratch and the query buffers (OccupancyMap::trim).
  void trim();

  const MapParams& params() const { return params_; }
  void setLeafBoxesEveryScan(bool every_scan) { leaf_boxes_every_scan_ = every_scan; }
  /// Rebuilds the leaf boxes if scans were inserted without rebuilding them.
  void refreshLeafBoxes();

  vk::Device& device() { return device_; }
  /// The map's buffers for a distance field (src/field/): after flush(), the field reads the node
  /// pool (`pool`, `nodes`) and counts its bytes under the cap (checkBudget, noteFieldBytes). It
  /// records on its own command stream; nothing else is shared.
  MapBuffers& fieldBuffers() { return buffers_; }
  /// The map's log-odds parameters (the occupancy threshold isNodeOccupied compares with).
  const ref::LogOddsParams& logOdds() const { return logs_; }

  /// castRay's backend on this map (kWalk or kRayTracing) and its build statistics.
  OccupancyMap::CastRayInfo castRayInfo() const;

 private:
  // ---- castRay's ray-tracing backend (map/ray_scene.cpp) ----
  /// Resolves MapParams::cast_ray_backend on this device; throws when kRayTracing cannot run.
  static CastRayBackend chooseCastRayBackend(const vk::Device& device, const MapParams& params);
  /// Brings the acceleration structure up to the tree (lazily: when the tree changed since it
  /// was built) and returns the address of its boxes buffer for cast_ray_rt; 0 with the walk.
  /// Under MapParams::max_device_bytes a structure that would not fit is not built: with
  /// kAuto the scene is dropped and 0 returned (the walk answers, CastRayInfo::cap_fallbacks
  /// counts it); with kRayTracing BudgetError, the map unchanged.
  VkDeviceAddress rayScene();
  /// Whether castRay's scene may hold `bytes` in place of what it holds now under the cap; if
  /// not, drops the scene, then with kRayTracing throws BudgetError naming `what`, with kAuto
  /// counts a fallback and returns false.
  bool rayScenefits(std::size_t bytes, const std::string& what);
  /// Tells the buffers' cap accounting what the two scenes hold (after either changes).
  void noteSceneBytes();
  /// Under a cap, drops castRay's scene (no castRay uses it after its call returns), so that a
  /// scan's or an upload's growth never loses room to a structure the change makes stale anyway.
  void releaseRaySceneUnderCap();
  CastRayBackend cast_ray_backend_ = CastRayBackend::kWalk;
  std::unique_ptr<RayScene> ray_scene_;
  /// castRays calls the walk answered because the structure did not fit under the cap (kAuto).
  std::size_t cap_fallbacks_ = 0;
  /// Counts the changes of the tree (scans that updated cells, uploads), for the ray scene.
  std::uint64_t tree_version_ = 0;

  // ---- scans through ray tracing (map/ray_scene.cpp, passes/scan_rays_rt.cpp) ----
  /// Resolves MapParams::scan_rays on this device; throws when kRayTracing cannot run.
  static ScanRays chooseScanRays(const vk::Device& device, const MapParams& params);
  /// The scans' scene with its boxes buffer sized for the pool as it is now; when that changes
  /// (the pool grew), waits for the scans in flight first, which use the scene.
  RayScene& scanScene();
  ScanRays scan_rays_ = ScanRays::kWalk;
  std::unique_ptr<RayScene> scan_scene_;  ///< its own, not castRay's: other boxes
  gpu::AccelHeader scan_header_{};        ///< the capacities scan_scene_ is built for

 private:
  /// A scan submitted and not yet known to be in the map: what it needs to run again.
  struct PendingScan {
    std::uint64_t ticket = 0;
    std::uint64_t serial = 0;         ///< its last submission
    std::uint32_t frame = 0;          ///< that submission's frame (readback region, timestamps)
    std::uint32_t staging_frame = 0;  ///< whose upload staging holds its input
    bool host_input = true;           ///< input in uploads[staging_frame], else a caller's buffer
    passes::RayKeysInput input;
    Eigen::Vector3f origin = Eigen::Vector3f::Zero();
    std::optional<Pose> pose;
    double max_range = -1.0;
    std::size_t count = 0;
    bool blocking = false;                  ///< the blocking call's scan (which waits for it)
    const QueryRequest* queries = nullptr;  // the blocking call's
    QueryResults* results = nullptr;
    ScanStats stats;
  };
  /// Where the ray pass reads the scan's input: frame `frame`'s upload staging, after writing
  /// the host's points or pixels into it, or the caller's buffer.
  passes::RayKeysInput stage(const ScanSource& source, std::uint32_t frame);
  /// Grows what the next scan of `count` points (`depth_bytes` of depth image) needs, and what
  /// recent scans asked for ahead, waiting for the scans in flight first if anything grows.
  void prepareBuffers(std::size_t count, std::size_t depth_bytes);
  /// submit(); `blocking`: the blocking call's scan, whose `queries` (staged here) run right
  /// after it in its submission.
  std::uint64_t enqueue(const ScanSource& source, const Eigen::Vector3f& origin, const Pose* pose,
                        double max_range, bool discretize, bool blocking,
                        const QueryRequest* queries, QueryResults* results);
  /// What the results of recent scans asked for ahead (pool and list room, releasing the
  /// scratch after an outsized scan); nothing may be in flight. `pool`: the pool's state if
  /// known (else it is read); `release`: also release the scratch if asked for (not while
  /// refused scans wait in their staging to run again).
  void growAhead(const gpu::PoolState* pool = nullptr, bool release = true);
  /// Records and submits scan `p` (its queries, if any, after it).
  void record(PendingScan& p);
  /// Waits for the oldest scan in flight and takes its result; a refused one is run again with
  /// everything behind it (recover).
  void confirmOldest();
  /// Takes the result of the oldest scan in flight, which has completed: false if the device
  /// refused it.
  bool takeResult(PendingScan& p, const gpu::ScanCounters& counters, const gpu::PoolState& pool);
  /// Queues a finished scan's statistics for takeStats() (the newest kKeptStats).
  void keepStats(const ScanStats& stats) noexcept;
  /// The oldest scan was refused: waits for all, grows, runs them again in order, each waited.
  void recover(gpu::ScanCounters counters, gpu::PoolState pool);
  /// Throws kInvalidArgument naming the first bad input of a scan of `count` points.
  void checkScan(std::size_t count, const Eigen::Vector3f& origin, const Pose* pose,
                 double max_range) const;
  gpu::ScanParams scanParams(const Eigen::Vector3f& origin, const Pose* pose, double max_range,
                             std::size_t count) const;
  /// The parameters of a pass that is not a scan (queries, uploads): the map's, no scan.
  gpu::ScanParams queryParams() const {
    return scanParams(Eigen::Vector3f::Zero(), nullptr, -1.0, 0);
  }
  /// Grows what a scan the device did not apply found short; throws (map unchanged) where it
  /// may not grow.
  void growForRetry(const gpu::ScanCounters& counters, const gpu::PoolState& pool);
  /// Room in the pool for `blocks` more blocks; `ahead`: for later scans, never an error.
  void reservePool(std::uint64_t blocks, const gpu::PoolState& pool, bool ahead);

  vk::Device& device_;
  MapParams params_;
  ref::LogOddsParams logs_;
  vk::CommandStream stream_;
  MapBuffers buffers_;
  passes::Recorder rec_;
  std::deque<PendingScan> pending_;       // submitted, in order
  std::deque<ScanStats> finished_stats_;  // in the map, not taken yet (the newest kKeptStats)
  ScanStats blocking_stats_;              // the last blocking call's scan (its result)
  static constexpr std::size_t kKeptStats = 4096;
  std::uint64_t next_ticket_ = 1;
  std::size_t last_nodes_ = 0;  // nodes after the last scan taken
  // A scan was refused since the last submission: the next one clears PoolState::halted.
  bool resume_ = false;
  // Growth asked for by the results of recent scans, done at the next submit (after waiting).
  std::uint64_t ahead_blocks_ = 0;
  std::size_t ahead_active_ = 0;
  bool release_scratch_ = false;
  std::uint32_t hash_guess_tried_ = 0;  // the largest first guess of the cell set tried
  bool leaf_boxes_every_scan_ = false;
  bool leaf_boxes_dirty_ = false;
};

}  // namespace octovk
