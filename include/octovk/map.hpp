// octovk: The occupancy octree on the device: OccupancyMap.
#pragma once

#include <Eigen/Core>
#include <cstddef>
#include <cstdint>
#include <memory>
#include <span>
#include <string>
#include <vector>

#include "octovk/context.hpp"
#include "octovk/errors.hpp"
#include "octovk/params.hpp"
#include "octovk/queries.hpp"
#include "octovk/scan.hpp"

namespace octovk {

/// Where a map keeps the tiles its device working set does not hold (OccupancyMap::spillTilesTo):
/// the subtrees at depth 12 (16^3 finest cells) that a map outgrowing MapParams::max_device_bytes
/// moves off the device. A key is a tile's path from the root (3 bits a level); a body is bytes
/// only the map reads. The map calls it from the thread that uses the map. Errors: octovk::Error
/// (kIo where the spill cannot read or write).
class TileSpill {
 public:
  virtual ~TileSpill() = default;
  /// Keeps `body` under `key`, replacing what was kept there.
  virtual void put(std::uint64_t key, const std::string& body) = 0;
  /// What put() kept under `key`; kInternal where nothing is.
  virtual std::string get(std::uint64_t key) = 0;
  /// Forgets `key` (nothing where nothing is kept).
  virtual void erase(std::uint64_t key) = 0;
};
/// A TileSpill in host memory. (octovk::store::sqliteTileSpill keeps them in a temporary SQLite
/// file instead, for maps larger than the host's memory too.)
std::shared_ptr<TileSpill> makeHostTileSpill();

/// The occupancy octree, held in device buffers. Not copyable; movable. A moved-from map throws
/// kInvalidArgument from every call until a map is assigned to it. A call that throws leaves the
/// map as it was before the call (a std::bad_alloc inside becomes kOutOfHostMemory), and the map
/// keeps working.
///
/// const members read host state only: they never wait for the device nor throw a scan's error,
/// and they may run beside each other (as the standard library's const members). Every call that
/// reads the tree (search, castRays, nodeCount, download, ...) is non-const: it first takes the
/// submitted scans (flush()), so it may throw an earlier scan's error, and it records into the
/// map's command buffers, so no other call on this map may run beside it (see Context).
class OccupancyMap {
 public:
  OccupancyMap(Context& context, const MapParams& params);
  ~OccupancyMap();
  OccupancyMap(OccupancyMap&&) noexcept;
  OccupancyMap& operator=(OccupancyMap&&) noexcept;

  /// The map's parameters; kInvalidArgument for a moved-from map.
  const MapParams& params() const;

  /// OctoMap's insertPointCloud(points, origin, max_range, lazy_eval=false, discretize) with
  /// points and origin in the world frame; the options in one struct, e.g.
  /// `map.insertPointCloud(points, origin, {.max_range_m = 5.0, .discretize = true})`
  /// (ScanOptions: max_range_m < 0 means unlimited).
  ScanStats insertPointCloud(std::span<const Eigen::Vector3f> points_world,
                             const Eigen::Vector3f& origin_world, const ScanOptions& options = {});

  /// OctoMap's insertPointCloud(points, sensor_origin, frame_origin, ...): points and sensor origin
  /// in the sensor frame; both are moved to the world by T_world_sensor, the points on the device.
  ScanStats insertPointCloud(std::span<const Eigen::Vector3f> points_sensor,
                             const Eigen::Vector3f& origin_sensor, const Pose& T_world_sensor,
                             const ScanOptions& options = {});

  /// A depth image, unprojected on the device (DepthImage), then inserted like
  /// insertPointCloud(points_camera, origin_camera, T_world_camera, options): the result equals
  /// inserting unprojectDepthImage(image) with that overload.
  ScanStats insertDepthImage(const DepthImage& image, const Pose& T_world_camera,
                             const ScanOptions& options = {},
                             const Eigen::Vector3f& origin_camera = Eigen::Vector3f::Zero());

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

  /// insertPointCloud(points_world, origin_world, options), submitted without waiting. The
  /// points are copied before it returns: the span may be reused at once.
  ScanTicket submitPointCloud(std::span<const Eigen::Vector3f> points_world,
                              const Eigen::Vector3f& origin_world, const ScanOptions& options = {});
  /// insertPointCloud(points_sensor, origin_sensor, T_world_sensor, options), without waiting.
  ScanTicket submitPointCloud(std::span<const Eigen::Vector3f> points_sensor,
                              const Eigen::Vector3f& origin_sensor, const Pose& T_world_sensor,
                              const ScanOptions& options = {});
  /// insertDepthImage(...), without waiting. The pixels are copied before it returns.
  ScanTicket submitDepthImage(const DepthImage& image, const Pose& T_world_camera,
                              const ScanOptions& options = {},
                              const Eigen::Vector3f& origin_camera = Eigen::Vector3f::Zero());
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
  /// host round trip between the update and the queries). On a map with a payload the rays'
  /// RayHit::payload takes a second lookup batch after the scan.
  ScanStats insertPointCloud(std::span<const Eigen::Vector3f> points_world,
                             const Eigen::Vector3f& origin_world, const ScanOptions& options,
                             const QueryRequest& queries, QueryResults& results);

  // ---- queries: each waits for the submitted scans first (flush()) and may throw their error ----
  /// OctoMap's search() for each point, on the device.
  std::vector<Lookup> search(std::span<const Eigen::Vector3f> points);
  /// OctoMap's castRay for each ray, on the device. On a map with a payload each hit also
  /// carries the hit cell's payload (RayHit::payload: a second lookup batch at the ends).
  std::vector<RayHit> castRays(std::span<const Ray> rays);
  /// The leaves OctoMap's leaf_bbx_iterator(min, max) visits (all, or only the occupied ones),
  /// compacted on the device and downloaded. Empty if a corner lies outside the map.
  std::vector<LeafBoxHost> leavesInBox(const Eigen::Vector3f& min, const Eigen::Vector3f& max,
                                       bool occupied_only = false);

  // ---- change detection: OctoMap's enableChangeDetection / changedKeys, on the device ----
  /// Turns change detection on or off for the scans inserted or submitted after this call
  /// (OcTree::enableChangeDetection). With it on, every leaf a scan updates is noted as OctoMap
  /// notes it: created (`true`), or its occupancy flipped (`false`; flipped back: removed). The
  /// set lives on the device (its bytes in deviceBytesByUse().changes, under
  /// MapParams::max_device_bytes); turning detection off keeps the keys noted so far.
  void enableChangeDetection(bool enable);
  bool isChangeDetectionEnabled() const;
  /// Empties the change set (OcTree::resetChangeDetection).
  void resetChangeDetection();
  /// Keys in the change set (OcTree::numChangesDetected).
  std::size_t numChangesDetected();
  /// The change set (OcTree::changedKeysBegin/End), in no particular order.
  std::vector<ChangedKey> changedKeys();

  // ---- map surgery ----
  /// octomap_server's clear_bbx on the device: every leaf OctoMap's leaf_bbx_iterator(min, max)
  /// visits (a pruned leaf reaching into the box whole) gets the lower clamping bound's log-odds
  /// (getClampingThresMinLog()), then the inner nodes are updated as updateInnerOccupancy does
  /// (no pruning: later scans prune as OctoMap's would). A corner outside the map clears
  /// nothing, as OctoMap's iterator; a NaN corner or min > max is kInvalidArgument, the map
  /// unchanged. Not noted by change detection (clear_bbx sets values directly).
  void clearBox(const Eigen::Vector3f& min, const Eigen::Vector3f& max);
  /// Keeps only a box (a rolling window around a robot), on the device: afterwards the map holds
  /// exactly the leaves OctoMap's leaf_bbx_iterator(min, max) visits (same keys, depths and
  /// log-odds; a pruned leaf reaching into the box stays whole), the inner nodes on their paths,
  /// each the maximum of its children as updateInnerOccupancy makes it, and no other node. The
  /// deleted nodes' blocks go back to the pool's free list: nodeCount() falls and later scans
  /// reuse them, so a window kept around a moving sensor stays within MapParams::max_device_bytes.
  /// A corner outside the map keeps nothing (OctoMap's iterator visits nothing); a NaN corner or
  /// min > max is kInvalidArgument, the map unchanged. Not noted by change detection (OctoMap's
  /// deleteNode leaves the changed keys alone: a deleted leaf's key stays in the set).
  void keepBox(const Eigen::Vector3f& min, const Eigen::Vector3f& max);
  /// Gives the pool's free blocks back to the device: the tree is moved into a pool sized for
  /// the blocks it holds and a quarter more (at least an empty map's), so deviceBytesByUse().pool
  /// falls after keepBox, or after scans whose pruning freed many blocks. The tree, its queries
  /// and the change set stay as they are. It reads the tree to the host and writes it back (as
  /// download() then upload()), so it is for an occasional call, not one per scan; a pool with
  /// little free room is left as it is. Throws with the map unchanged where it cannot.
  void compact();

  /// Nodes in the tree (read from the device's counters, no map data moves; with tiles spilled,
  /// the spilled ones' nodes added).
  std::size_t nodeCount();

  /// Lets the map outgrow MapParams::max_device_bytes: where a scan needs more pool than the cap
  /// allows, the tiles (depth-12 subtrees) farthest from the scan's sensor move to `spill`, and a
  /// scan that reaches a spilled tile loads it back first (each a round trip of the node pool
  /// through the host). The map stays OctoMap's, node for node; download() (and every file
  /// written from it) includes the spilled tiles. While tiles are spilled, what reads the whole
  /// tree on the device (queries, leaf boxes, castRays, edits, degradeOutdated, compact,
  /// distance fields) is refused with kInvalidArgument; scans, a store's commits, download(),
  /// nodeCount() and leafCount() work. Not with MapParams::scan_rays = kRayTracing. A spill
  /// cannot be changed while it holds tiles (kInvalidArgument).
  void spillTilesTo(std::shared_ptr<TileSpill> spill);
  /// Tiles off the device now (0: the whole map is in the pool).
  std::size_t spilledTiles();
  /// What the working set of tiles did since the map was made (spillTilesTo).
  struct SpillCounts {
    std::size_t round_trips =
        0;                    ///< pool round trips through the host (each loads, evicts or both)
    std::size_t loaded = 0;   ///< tiles loaded back for scans that reached them
    std::size_t evicted = 0;  ///< tiles moved to the spill
  };
  SpillCounts spillCounts();
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
    std::size_t queries = 0;          ///< query input and output, with their staging
    std::size_t changes = 0;          ///< the change set (change detection), 16 B per slot
    std::size_t distance_fields = 0;  ///< the DistanceFields built on this map (distance.hpp)
    std::size_t total() const {
      return pool + leaf_boxes + scratch + queries + changes + distance_fields;
    }
  };
  DeviceBytes deviceBytesByUse() const;

  /// castRay's backend on this map and what its acceleration structure cost (ray tracing only).
  struct CastRayInfo {
    CastRayBackend backend = CastRayBackend::kWalk;  ///< kWalk or kRayTracing, as castRays runs
    std::size_t builds = 0;  ///< acceleration-structure builds (lazily, by castRays) since trim()
    double last_build_ms = 0.0;  ///< device time of the last: the boxes, then the structures
    double last_boxes_ms = 0.0;  ///< of which the boxes (leaf boxes if stale, accel_boxes)
    /// Boxes of the last build: its occupied leaves (castRay traces only the rays that ignore
    /// unknown space, so the structure holds no unknown regions).
    std::size_t occupied_boxes = 0;
    std::size_t device_bytes = 0;  ///< boxes, structures, scratch (in deviceBytesByUse().queries)
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
  std::size_t leafCount();

  /// Whether each scan ends by rebuilding the leaf boxes. Off (the default), they are rebuilt
  /// on the next leafCount() / downloadLeafBoxes() that follows a scan: the rebuild visits every
  /// block of the map, so doing it after every scan makes a scan's cost grow with the map.
  void setLeafBoxesEveryScan(bool every_scan);

  /// Explicit transfer of the whole tree to the host.
  HostTree download();
  /// Replaces the map with `tree` (explicit transfer to the device).
  void upload(const HostTree& tree);

  /// The leaf boxes (centre, size, log-odds) of the map, downloaded.
  std::vector<LeafBoxHost> downloadLeafBoxes();

  class Impl;

 protected:
  /// impl_, or kInvalidArgument for a moved-from map.
  Impl& self() const;
  /// On a map with a payload, each hit's payload (a lookup at the hit ends); else nothing.
  void addHitPayloads(std::vector<RayHit>& hits);

 private:
  friend class InteropAccess;  // vulkan_interop.hpp
  friend class FieldAccess;    // distance.hpp (src/field/)
  friend class StoreAccess;    // src/map/store_access.hpp (the map store, src/store/)
  std::unique_ptr<Impl> impl_;
};

/// OctoMap's ColorOcTree on the device: an OccupancyMap whose nodes hold a colour
/// (MapParams::payload = Payload::kColor). A scan is inserted as ColorOcTree::insertPointCloud
/// inserts it, then each point's colour is folded into the node search() finds for it, in the
/// cloud's order (ScanOptions::colors, ColorFold). Pruning is ColorOcTree's: children merge on
/// their log-odds alone, and the merged node takes child 0's colour, or, where that is set, the
/// integer mean of the children's set colours. download() gives inner nodes the colours
/// updateInnerOccupancy() gives them, so a written .ot equals OctoMap's after the same steps.
class ColorMap : public OccupancyMap {
 public:
  /// `params` with its payload set to kColor.
  ColorMap(Context& context, MapParams params);
  /// Takes over a map whose payload is kColor (readMapFile of a ColorOcTree file); any other
  /// is kInvalidArgument, `map` then unchanged.
  explicit ColorMap(OccupancyMap&& map);
  using OccupancyMap::insertPointCloud;
  /// insertPointCloud(points_world, origin_world, options) with options.colors = colors.
  ScanStats insertPointCloud(std::span<const Eigen::Vector3f> points_world,
                             const Eigen::Vector3f& origin_world, std::span<const Rgb> colors,
                             ScanOptions options = {});
  /// The colour of the node search() finds for each point; white where it finds none. The
  /// colours of leaves (leavesInBox, downloadLeafBoxes): colors() of their centres.
  std::vector<Rgb> colors(std::span<const Eigen::Vector3f> points);
};

/// OctoMap's OcTreeStamped on the device: an OccupancyMap whose nodes hold a time stamp in whole
/// seconds (MapParams::payload = Payload::kStamp). Every node a scan updates takes the scan's
/// stamp (ScanOptions::stamp, OcTreeStamped's time(NULL)); children merge only where their
/// log-odds and stamps are equal (OcTreeNodeStamped::operator==).
class StampedMap : public OccupancyMap {
 public:
  /// `params` with its payload set to kStamp.
  StampedMap(Context& context, MapParams params);
  /// Takes over a map whose payload is kStamp; any other is kInvalidArgument, `map` unchanged.
  explicit StampedMap(OccupancyMap&& map);
  using OccupancyMap::insertPointCloud;
  /// insertPointCloud(points_world, origin_world, options) with options.stamp = stamp.
  ScanStats insertPointCloud(std::span<const Eigen::Vector3f> points_world,
                             const Eigen::Vector3f& origin_world, std::uint32_t stamp,
                             ScanOptions options = {});
  /// OcTreeStamped::degradeOutdatedNodes with query time `now`: every occupied leaf (pruned
  /// leaves included) with now - stamp > threshold_s (unsigned, as OctoMap) takes one miss and
  /// keeps its stamp; then the inner nodes are updated as updateInnerOccupancy() does (their
  /// stamps become `now`). On the device.
  void degradeOutdated(std::uint32_t now, std::uint32_t threshold_s);
  /// The stamp of the node search() finds for each point; 0 where it finds none.
  std::vector<std::uint32_t> stamps(std::span<const Eigen::Vector3f> points);
  /// OcTreeStamped::getLastUpdateTime: the root's stamp (0 for an empty map).
  std::uint32_t lastUpdateTime();
};

}  // namespace octovk
