// OccupancyMap: the public face (each call turns a host allocation failure into Error) and
// OccupancyMap::Impl, which owns the map's parts (map/map_impl.hpp) and delegates to them.
#include <string>

#include "gpu/gpu_types.h"
#include "map/context_access.hpp"
#include "map/host_memory.hpp"
#include "map/map_impl.hpp"
#include "map/store_access.hpp"

namespace octovk {

OccupancyMap::Impl::Impl(Context& context, const MapParams& params)
    : device_owner_(ContextAccess::shared(context)),
      core_(*device_owner_, params),
      changes_(core_),
      scenes_(core_),
      growth_(core_, changes_),
      queries_(core_, scenes_),
      transfer_(core_, scenes_),
      tiles_(core_, transfer_),
      edits_(core_),
      scans_(core_, changes_, growth_, scenes_, queries_, tiles_) {}

OccupancyMap::Impl::~Impl() {
  *link_ = nullptr;  // the fields on this map refuse from now on
  try {
    core_.stream.waitIdle();  // the buffers go before the stream: no scan may still use them
  } catch (...) {
    // a lost device: nothing left to wait for
  }
}

QueryResults OccupancyMap::Impl::runQueries(const QueryRequest& queries) {
  requireResident("queries (search, castRays, colors, stamps)");
  flush();  // sees every scan submitted before it
  return queries_.run(queries);
}

void OccupancyMap::Impl::queryOnDevice(bool rays, VkBuffer in, VkDeviceSize in_offset,
                                       VkDeviceSize in_size, VkBuffer out, VkDeviceSize out_offset,
                                       VkDeviceSize out_size, std::uint32_t count) {
  requireResident("queries on the device (interop)");
  queries_.onDevice(rays, in, in_offset, in_size, out, out_offset, out_size, count);
}

std::vector<OccupancyMap::LeafBoxHost> OccupancyMap::Impl::leavesInBox(const Eigen::Vector3f& min,
                                                                       const Eigen::Vector3f& max,
                                                                       bool occupied_only) {
  requireResident("leavesInBox");
  return queries_.leavesInBox(min, max, occupied_only);
}

HostTree OccupancyMap::Impl::download() {
  flush();
  if (tiles_.spilledTiles() == 0) return transfer_.download();
  HostTree tree = tiles_.wholeTree(transfer_.downloadRaw());
  averageInnerColors(tree);  // ColorOcTree::updateInnerOccupancy's colours
  return tree;
}

void OccupancyMap::Impl::upload(const HostTree& tree) {
  flush();
  transfer_.upload(tree);
  tiles_.forget();  // the map is `tree` now, all of it in the pool
}

std::size_t OccupancyMap::Impl::nodeCount() {
  const gpu::PoolState pool = readPool();
  return pool.root_exists ? pool.live_nodes + tiles_.spilledNodes() : 0;
}

std::size_t OccupancyMap::Impl::leafCount() {
  flush();
  if (tiles_.spilledTiles() == 0) {
    core_.refreshLeafBoxes();
    return core_.readPool().leaf_count;
  }
  // The leaf boxes would take a spilled tile for a leaf: the whole tree's leaves instead.
  const HostTree tree = download();
  if (!tree.root_exists || tree.nodes.empty()) return 0;
  const SubtreeSize size = subtreeSize(tree, gpu::kRootNode);
  return size.nodes - size.blocks;
}

std::vector<OccupancyMap::LeafBoxHost> OccupancyMap::Impl::downloadLeafBoxes() {
  requireResident("downloadLeafBoxes");
  return transfer_.downloadLeafBoxes();
}

gpu::PoolState OccupancyMap::Impl::readPool() {
  flush();
  return core_.readPool();
}

void OccupancyMap::Impl::refreshLeafBoxes() {
  requireResident("the leaf boxes");
  core_.refreshLeafBoxes();
}

OccupancyMap::DeviceBytes OccupancyMap::Impl::deviceBytesByUse() const {
  const BufferBytes b = core_.buffers.bytesByUse();  // the scenes are in b.queries
  return {.pool = b.pool,
          .leaf_boxes = b.leaf_boxes,
          .scratch = b.scratch,
          .queries = b.queries,
          .changes = b.changes,
          .distance_fields = b.fields};
}

void OccupancyMap::Impl::trim() {
  flush();
  growth_.trim();
  scenes_.release();
}

// ---- public face -----------------------------------------------------------------------------

OccupancyMap::OccupancyMap(Context& context, const MapParams& params)
    : impl_(hostMemoryGuard("OccupancyMap", [&] {
        ContextAccess::shared(context)->checkNotForked("OccupancyMap");
        return std::make_unique<Impl>(context, params);
      })) {}
// A map made before fork() is the parent's: a forked child leaves it alone rather than destroy
// it (that would wait on the driver's threads, which the child does not have). So does a map
// destroyed after exit() began (a static's): the driver may have torn itself down by then.
OccupancyMap::~OccupancyMap() {
  if (impl_ && impl_->device().abandoned()) vk::Device::keepUntilExit(impl_.release());
}
OccupancyMap::OccupancyMap(OccupancyMap&&) noexcept = default;
OccupancyMap& OccupancyMap::operator=(OccupancyMap&& other) noexcept {
  if (impl_ && impl_->device().abandoned()) vk::Device::keepUntilExit(impl_.release());
  impl_ = std::move(other.impl_);
  return *this;
}

OccupancyMap::Impl& OccupancyMap::self() const {
  if (!impl_)
    throw Error(ErrorCode::kInvalidArgument,
                "OccupancyMap: this map was moved from and holds nothing; assign a map to it "
                "before using it again");
  impl_->device().checkNotForked("OccupancyMap");
  return *impl_;
}

// A moved-from map has no parameters: default ones would pass for a real map's.
const MapParams& OccupancyMap::params() const { return self().params(); }

ScanStats OccupancyMap::insertPointCloud(std::span<const Eigen::Vector3f> points_world,
                                         const Eigen::Vector3f& origin_world,
                                         const ScanOptions& options) {
  return hostMemoryGuard("insertPointCloud", [&] {
    return self().insert({.points = points_world}, origin_world, nullptr, options);
  });
}

ScanStats OccupancyMap::insertPointCloud(std::span<const Eigen::Vector3f> points_sensor,
                                         const Eigen::Vector3f& origin_sensor,
                                         const Pose& T_world_sensor, const ScanOptions& options) {
  return hostMemoryGuard("insertPointCloud", [&] {
    const Eigen::Vector3f origin_world = T_world_sensor.transform(origin_sensor);
    return self().insert({.points = points_sensor}, origin_world, &T_world_sensor, options);
  });
}

ScanStats OccupancyMap::insertDepthImage(const DepthImage& image, const Pose& T_world_camera,
                                         const ScanOptions& options,
                                         const Eigen::Vector3f& origin_camera) {
  return hostMemoryGuard("insertDepthImage", [&] {
    if (std::string why = image.validate(); !why.empty())
      throw Error(ErrorCode::kInvalidArgument, "insertDepthImage: " + why);
    const Eigen::Vector3f origin_world = T_world_camera.transform(origin_camera);
    return self().insert({.depth = &image}, origin_world, &T_world_camera, options);
  });
}

ScanStats OccupancyMap::insertPointCloud(std::span<const Eigen::Vector3f> points_world,
                                         const Eigen::Vector3f& origin_world,
                                         const ScanOptions& options, const QueryRequest& queries,
                                         QueryResults& results) {
  return hostMemoryGuard("insertPointCloud", [&] {
    ScanStats stats =
        self().insert({.points = points_world}, origin_world, nullptr, options, &queries, &results);
    addHitPayloads(results.rays);
    return stats;
  });
}

ScanTicket OccupancyMap::submitPointCloud(std::span<const Eigen::Vector3f> points_world,
                                          const Eigen::Vector3f& origin_world,
                                          const ScanOptions& options) {
  return hostMemoryGuard("submitPointCloud", [&] {
    return self().submit({.points = points_world}, origin_world, nullptr, options);
  });
}

ScanTicket OccupancyMap::submitPointCloud(std::span<const Eigen::Vector3f> points_sensor,
                                          const Eigen::Vector3f& origin_sensor,
                                          const Pose& T_world_sensor, const ScanOptions& options) {
  return hostMemoryGuard("submitPointCloud", [&] {
    const Eigen::Vector3f origin_world = T_world_sensor.transform(origin_sensor);
    return self().submit({.points = points_sensor}, origin_world, &T_world_sensor, options);
  });
}

ScanTicket OccupancyMap::submitDepthImage(const DepthImage& image, const Pose& T_world_camera,
                                          const ScanOptions& options,
                                          const Eigen::Vector3f& origin_camera) {
  return hostMemoryGuard("submitDepthImage", [&] {
    if (std::string why = image.validate(); !why.empty())
      throw Error(ErrorCode::kInvalidArgument, "submitDepthImage: " + why);
    const Eigen::Vector3f origin_world = T_world_camera.transform(origin_camera);
    return self().submit({.depth = &image}, origin_world, &T_world_camera, options);
  });
}

void OccupancyMap::flush() {
  return hostMemoryGuard("flush", [&] { self().flush(); });
}

bool OccupancyMap::finished(ScanTicket ticket) {
  return hostMemoryGuard("finished", [&] { return self().finished(ticket); });
}

std::vector<ScanStats> OccupancyMap::takeScanStats() {
  return hostMemoryGuard("takeScanStats", [&] { return self().takeStats(); });
}

std::size_t OccupancyMap::scansInFlight() const noexcept {
  return impl_ ? impl_->scansInFlight() : 0;
}

OccupancyMap::SyncCounts OccupancyMap::syncCounts() const noexcept {
  return impl_ ? impl_->syncCounts() : SyncCounts{};
}

std::vector<Lookup> OccupancyMap::search(std::span<const Eigen::Vector3f> points) {
  return hostMemoryGuard("search", [&] { return self().runQueries({points, {}}).lookups; });
}

void OccupancyMap::addHitPayloads(std::vector<RayHit>& hits) {
  if (self().params().payload == Payload::kNone) return;
  // A hit's end is the centre of the cell it hit: search() there finds that cell's node.
  std::vector<Eigen::Vector3f> ends;
  std::vector<std::size_t> which;
  for (std::size_t i = 0; i < hits.size(); ++i)
    if (hits[i].hit) {
      ends.push_back(hits[i].end);
      which.push_back(i);
    }
  if (ends.empty()) return;
  const std::vector<Lookup> found = self().runQueries({ends, {}}).lookups;
  for (std::size_t j = 0; j < which.size(); ++j) hits[which[j]].payload = found[j].payload;
}

std::vector<RayHit> OccupancyMap::castRays(std::span<const Ray> rays) {
  return hostMemoryGuard("castRays", [&] {
    std::vector<RayHit> hits = self().runQueries({{}, rays}).rays;
    addHitPayloads(hits);
    return hits;
  });
}

std::vector<OccupancyMap::LeafBoxHost> OccupancyMap::leavesInBox(const Eigen::Vector3f& min,
                                                                 const Eigen::Vector3f& max,
                                                                 bool occupied_only) {
  return hostMemoryGuard("leavesInBox",
                         [&] { return self().leavesInBox(min, max, occupied_only); });
}

void OccupancyMap::enableChangeDetection(bool enable) {
  hostMemoryGuard("enableChangeDetection", [&] { self().enableChangeDetection(enable); });
}

bool OccupancyMap::isChangeDetectionEnabled() const { return self().changeDetectionEnabled(); }

void OccupancyMap::resetChangeDetection() {
  hostMemoryGuard("resetChangeDetection", [&] { self().resetChangeDetection(); });
}

std::size_t OccupancyMap::numChangesDetected() {
  return hostMemoryGuard("numChangesDetected", [&] { return self().numChangesDetected(); });
}

std::vector<ChangedKey> OccupancyMap::changedKeys() {
  return hostMemoryGuard("changedKeys", [&] { return self().changedKeys(); });
}

void OccupancyMap::clearBox(const Eigen::Vector3f& min, const Eigen::Vector3f& max) {
  hostMemoryGuard("clearBox", [&] { self().clearBox(min, max); });
}

void OccupancyMap::keepBox(const Eigen::Vector3f& min, const Eigen::Vector3f& max) {
  hostMemoryGuard("keepBox", [&] { self().keepBox(min, max); });
}

void OccupancyMap::compact() {
  hostMemoryGuard("compact", [&] { self().compact(); });
}

std::size_t OccupancyMap::nodeCount() {
  return hostMemoryGuard("nodeCount", [&] { return self().nodeCount(); });
}

std::size_t OccupancyMap::leafCount() {
  return hostMemoryGuard("leafCount", [&] { return self().leafCount(); });
}

void OccupancyMap::spillTilesTo(std::shared_ptr<TileSpill> spill) {
  hostMemoryGuard("spillTilesTo", [&] { self().spillTilesTo(std::move(spill)); });
}

std::size_t OccupancyMap::spilledTiles() {
  return hostMemoryGuard("spilledTiles", [&] { return self().spilledTiles(); });
}

OccupancyMap::SpillCounts OccupancyMap::spillCounts() {
  return hostMemoryGuard("spillCounts", [&] { return self().spillCounts(); });
}

void OccupancyMap::setLeafBoxesEveryScan(bool every_scan) {
  return hostMemoryGuard("setLeafBoxesEveryScan",
                         [&] { self().setLeafBoxesEveryScan(every_scan); });
}

std::size_t OccupancyMap::deviceBytes() const {
  return hostMemoryGuard("deviceBytes", [&] { return self().deviceBytes(); });
}

OccupancyMap::CastRayInfo OccupancyMap::castRayInfo() const {
  return hostMemoryGuard("castRayInfo", [&] { return self().castRayInfo(); });
}

std::size_t OccupancyMap::poolBytes() const {
  return hostMemoryGuard("poolBytes", [&] { return self().poolBytes(); });
}

OccupancyMap::DeviceBytes OccupancyMap::deviceBytesByUse() const {
  return hostMemoryGuard("deviceBytesByUse", [&] { return self().deviceBytesByUse(); });
}

std::size_t OccupancyMap::scratchBytes() const {
  return hostMemoryGuard("scratchBytes", [&] { return self().deviceBytesByUse().scratch; });
}

void OccupancyMap::trim() {
  return hostMemoryGuard("trim", [&] { self().trim(); });
}

HostTree OccupancyMap::download() {
  return hostMemoryGuard("download", [&] { return self().download(); });
}

void OccupancyMap::upload(const HostTree& tree) {
  return hostMemoryGuard("upload", [&] { self().upload(tree); });
}

PoolCapture StoreAccess::capture(OccupancyMap& map, std::uint64_t since, unsigned depth) {
  return hostMemoryGuard("capture", [&] { return map.self().capture(since, depth); });
}

void StoreAccess::captureScans(OccupancyMap& map, unsigned depth) {
  map.self().captureScans(depth);
}

std::uint64_t StoreAccess::capturingTicket(OccupancyMap& map) {
  return map.self().capturingTicket();
}

std::optional<PoolCapture> StoreAccess::takeCapture(OccupancyMap& map, std::uint64_t ticket,
                                                    std::uint64_t since) {
  return hostMemoryGuard("capture", [&] { return map.self().takeCapture(ticket, since); });
}

std::vector<std::pair<std::uint64_t, HostTree>> StoreAccess::takeDirtyTiles(OccupancyMap& map) {
  return hostMemoryGuard("takeDirtyTiles", [&] { return map.self().takeDirtyTiles(); });
}

void StoreAccess::attach(OccupancyMap& map) {
  hostMemoryGuard("attach", [&] { map.self().noteCommittedPerScan(); });
}

std::uint64_t StoreAccess::version(OccupancyMap& map) {
  return hostMemoryGuard("version", [&] { return map.self().treeVersion(); });
}

std::vector<OccupancyMap::LeafBoxHost> OccupancyMap::downloadLeafBoxes() {
  return hostMemoryGuard("downloadLeafBoxes", [&] { return self().downloadLeafBoxes(); });
}

}  // namespace octovk
