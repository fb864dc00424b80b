// DistanceField (include/octovk/distance.hpp): the box's checks, the field's buffers under the
// map's cap, build/update, queries and download.
#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <sstream>
#include <utility>

#include "field/field_impl.hpp"
#include "field/field_passes.hpp"
#include "map/host_memory.hpp"
#include "map/reference.hpp"
#include "map/walk_budget.hpp"

namespace octovk {

namespace {

Error invalid(const std::string& what) {
  return Error(ErrorCode::kInvalidArgument, "DistanceField: " + what);
}

std::string corner(const Eigen::Vector3f& v) {
  std::ostringstream s;
  s << "(" << v.x() << ", " << v.y() << ", " << v.z() << ")";
  return s.str();
}

std::string bytesText(std::size_t bytes) {
  char text[64];
  if (bytes >= (std::size_t{1} << 30))
    std::snprintf(text, sizeof(text), "%.1f GiB", static_cast<double>(bytes) / (1 << 30));
  else
    std::snprintf(text, sizeof(text), "%.1f MiB", static_cast<double>(bytes) / (1 << 20));
  return text;
}

std::string cellsText(const FieldBox& box) {
  return std::to_string(box.size[0]) + " x " + std::to_string(box.size[1]) + " x " +
         std::to_string(box.size[2]) + " cells";
}

// The remedy for a field the device or the cap has no room for, with or without a cap: the box
// is what the caller chose, the cap what bounds the map and its fields together.
std::string capAdvice(std::size_t cap) {
  if (cap == 0)
    return "Shrink the box (MapParams::max_device_bytes is not set: only the device limits the "
           "map and its fields)";
  return "Shrink the box, or raise MapParams::max_device_bytes (now " + bytesText(cap) + ")";
}

// The first and last key of the map's leaves along each axis, or false for a map with none.
bool leafKeyBounds(OccupancyMap& map, std::array<std::uint32_t, 3>& lo,
                   std::array<std::uint32_t, 3>& hi) {
  const std::vector<OccupancyMap::LeafBoxHost> leaves = map.downloadLeafBoxes();
  if (leaves.empty()) return false;
  const double res = map.params().resolution;
  lo.fill(0xFFFFu);
  hi.fill(0u);
  for (const OccupancyMap::LeafBoxHost& leaf : leaves)
    for (int a = 0; a < 3; ++a) {
      // The centres of the leaf's first and last finest cells: their keys, away from any edge.
      const double half = 0.5 * (double(leaf.size) - res);
      const auto key = [&](double c) {
        return static_cast<std::uint32_t>(
            std::clamp<double>(std::floor(c / res) + 32768.0, 0.0, 65535.0));
      };
      lo[a] = std::min(lo[a], key(leaf.center[a] - half));
      hi[a] = std::max(hi[a], key(leaf.center[a] + half));
    }
  return true;
}

}  // namespace

std::uint32_t maxLineCells(const vk::Device& device) {
  // No limit seen: the passes' integer bound. Otherwise the walk budget (the measured limit
  // with room for the batch's other lanes) bounds one line's loop.
  if (device.loopLimit() == 0) return gpu::kFieldMaxAxisCells;
  const std::uint64_t budget = walkBudget(device);
  std::uint32_t n = budget > 8 ? static_cast<std::uint32_t>((budget - 8) / 4) : 0u;
  while (n > 0 && field::edtLoopIterations(n) > budget) --n;
  return std::min<std::uint32_t>(n, gpu::kFieldMaxAxisCells);
}

std::size_t fieldBytes(const FieldBox& box) {
  const auto dirty = box.dirtyWords();
  return 5 * box.cells() * sizeof(std::uint32_t) +
         (box.words() + dirty[0] + dirty[1] + dirty[2]) * sizeof(std::uint32_t) +
         sizeof(gpu::FieldHeader) * 2 + sizeof(gpu::ScanParams) + 512;
}

FieldBox fieldBox(double resolution, const Eigen::Vector3f& min, const Eigen::Vector3f& max,
                  const DistanceFieldOptions& options, std::uint32_t max_line_cells,
                  const std::string& name) {
  if (!(options.max_distance_m > 0.0f) || !std::isfinite(options.max_distance_m))
    throw invalid("max_distance_m is " + std::to_string(options.max_distance_m) +
                  "; give a finite distance > 0");
  if (!min.allFinite() || !max.allFinite())
    throw invalid("the box " + corner(min) + " - " + corner(max) +
                  " has a NaN or infinite corner; give finite corners");
  static const char* kAxis[3] = {"x", "y", "z"};
  FieldBox box;
  const double factor = 1.0 / resolution;
  for (int a = 0; a < 3; ++a) {
    if (min[a] > max[a])
      throw invalid(std::string("the box is inverted along ") + kAxis[a] + " (min " +
                    std::to_string(min[a]) + " > max " + std::to_string(max[a]) +
                    "); give min <= max on every axis");
    std::uint32_t lo = 0, hi = 0;
    if (!ref::coordToKeyChecked(factor, min[a], lo) || !ref::coordToKeyChecked(factor, max[a], hi))
      throw invalid("the box " + corner(min) + " - " + corner(max) +
                    " leaves the map's key range along " + kAxis[a] + " (+-" +
                    std::to_string(32768 * resolution) + " m at this resolution); keep it inside");
    box.min_key[a] = lo;
    box.size[a] = hi - lo + 1;
    if (box.size[a] > max_line_cells)
      throw invalid(name + " has " + std::to_string(box.size[a]) + " cells along " + kAxis[a] +
                    "; this device transforms lines of at most " + std::to_string(max_line_cells) +
                    " cells in one dispatch (its driver's loop limit, and at most " +
                    std::to_string(gpu::kFieldMaxAxisCells) + " for exact 32-bit integers); " +
                    (name == "the box" ? "split the box" : "give a smaller box"));
  }
  if (box.cells() >= gpu::kFieldNoSite)
    throw invalid(name + " has " + std::to_string(box.cells()) +
                  " cells; cell indices must fit 32 bits: " +
                  (name == "the box" ? "split the box" : "give a smaller box"));
  return box;
}

DistanceField::Impl::Impl(OccupancyMap::Impl& map, const FieldBox& box,
                          const DistanceFieldOptions& options)
    : device_owner_(map.deviceOwner()),
      map_(map.link()),
      device_(*device_owner_),
      box_(box),
      options_(options),
      stream_(device_, 1) {
  liveMap().requireResident("DistanceField");  // flushes
  MapBuffers& buffers = liveMap().fieldBuffers();
  const std::size_t bytes = fieldBytes(box_);
  // What was asked and what it needs, then why it cannot be had and what to change: the box,
  // or the cap (whether or not one is set), never the scans or query batches of the map.
  const std::string asked = "DistanceField: a field over a box of " + cellsText(box_) + " needs " +
                            bytesText(bytes) + " of device memory (" +
                            std::to_string(bytes / std::max<std::size_t>(box_.cells(), 1)) +
                            " bytes per cell)";
  const std::size_t cap = buffers.maxBytes();
  if (!buffers.fits(0, bytes)) {
    const std::size_t held = buffers.deviceBytes();
    throw BudgetError(
        asked + "; the map's device-memory cap (MapParams::max_device_bytes = " + bytesText(cap) +
        ") leaves " + bytesText(cap > held ? cap - held : 0) + " beside the " + bytesText(held) +
        " the map holds. " + capAdvice(cap) + "; the map is unchanged");
  }
  // More than the device has in all is refused before any of it is asked for (on a CPU device
  // the driver would first hand out gigabytes of host memory).
  const std::uint64_t device_bytes = device_.info().memory_bytes;
  if (device_bytes != 0 && bytes > device_bytes)
    throw Error(ErrorCode::kOutOfDeviceMemory, asked + "; the device has " +
                                                   bytesText(device_bytes) + " in all. " +
                                                   capAdvice(cap) + "; the map is unchanged");
  try {
    bindings_ = vk::BindingSet(device_);
    params_ = vk::Buffer(device_, sizeof(gpu::ScanParams), false);
    spare_ = vk::Buffer(device_, 512, false);
    header_ = vk::Buffer(device_, sizeof(gpu::FieldHeader), false);
    readback_ = vk::Buffer(device_, sizeof(gpu::FieldHeader), true);
    const std::size_t cell_bytes = box_.cells() * sizeof(std::uint32_t);
    const auto dirty = box_.dirtyWords();
    occupancy_ = vk::Buffer(device_, box_.words() * sizeof(std::uint32_t), false);
    line_x_ = vk::Buffer(device_, cell_bytes, false);
    plane_xy_ = vk::Buffer(device_, cell_bytes, false);
    sites_ = vk::Buffer(device_, cell_bytes, false);
    envelope_ = vk::Buffer(device_, 2 * cell_bytes, false);
    dirty_ = vk::Buffer(device_, (dirty[0] + dirty[1] + dirty[2]) * sizeof(std::uint32_t), false);
  } catch (const Error& e) {
    if (e.code() != ErrorCode::kOutOfDeviceMemory) throw;
    throw Error(ErrorCode::kOutOfDeviceMemory,
                asked + "; " + e.message() + " (the device has " + bytesText(device_bytes) +
                    " in all). " + capAdvice(cap) + "; the map is unchanged",
                0, e.detail());
  }
  bytes_ = bytes;
  buffers.noteFieldBytes(0, bytes_);
  try {
    update(/*building=*/true);
  } catch (...) {
    buffers.noteFieldBytes(bytes_, 0);
    throw;
  }
}

DistanceField::Impl::~Impl() {
  // A map destroyed first has nothing left to forget; otherwise its accounting forgets the
  // field's bytes, and change detection is released.
  if (*map_ == nullptr) return;
  OccupancyMap::Impl& map = **map_;
  map.fieldBuffers().noteFieldBytes(bytes_, 0);
  if (!follows_changes_) return;
  try {
    map.flush();  // the scans in flight note their changes first
    map.releaseChangesForField();
  } catch (...) {  // a destructor does not throw; change detection stays on (memory kept)
  }
}

OccupancyMap::Impl& DistanceField::Impl::liveMap() {
  if (*map_ == nullptr)
    throw Error(ErrorCode::kInvalidArgument,
                "distance field: the map it was built on has been destroyed; build a new field "
                "on a map that lives");
  return **map_;
}

std::size_t DistanceField::Impl::batchLimit() const {
  // At most 2^20 a batch (as the map's queries, QueryRunner::kMaxBatch): 64 MiB of buffers
  // however many points a call brings.
  return std::clamp<std::size_t>(device_.maxBindingBytes() / sizeof(gpu::DistanceResult), 1,
                                 std::size_t{1} << 20);
}

void DistanceField::Impl::rebind(MapBuffers& map) {
  std::array<const vk::Buffer*, gpu::kBindingCount> bound;
  bound.fill(&spare_);
  bound[gpu::kBindParams] = &params_;
  bound[gpu::kBindPool] = &map.pool;
  bound[gpu::kBindNodes] = &map.nodes;
  if (map.changesLog2() != 0) bound[gpu::kBindChanges] = &map.changes;
  if (query_in_.valid()) {
    bound[gpu::kBindQueryIn] = &query_in_;
    bound[gpu::kBindQueryOut] = &query_out_;
  }
  bindings_.update(bound);
}

bool DistanceField::Impl::fromChanges() {
  if (!liveMap().changeDetectionEnabled()) return false;
  // Anything the change set does not hold since the last update (an upload, clearBox, a scan
  // without change detection, a reset of the set, or a growth that dropped keys flipped back
  // after that update): the whole tree.
  const OccupancyMap::Impl::FieldTracking now = liveMap().fieldTracking();
  if (now.unnoted != tracking_.unnoted || now.epoch != tracking_.epoch ||
      (now.rehashes != tracking_.rehashes && !reset_changes_))
    return false;
  MapBuffers& map = liveMap().fieldBuffers();
  if (map.changesLog2() == 0) return false;
  // Reading the tree costs about a search per occupancy word (field_raster searches once per
  // run of cells one leaf answers, along paths the neighbouring words share); the change set a
  // search per key (measured about 4 words' worth on the paper map: its keys' paths are
  // scattered) and a read per slot.
  stream_.begin(bindings_);
  stream_.copy(map.changes, readback_, sizeof(gpu::ChangeHeader));
  stream_.submitAndWait();
  gpu::ChangeHeader header;
  std::memcpy(&header, readback_.mapped(), sizeof(header));
  return 4 * std::size_t{header.used} + (std::size_t{1} << map.changesLog2()) / 64 <= box_.words();
}

void DistanceField::Impl::update(bool building) {
  // Every scan submitted before is in the map (flushed), and the whole tree on the device.
  liveMap().requireResident("DistanceField::update");
  MapBuffers& map = liveMap().fieldBuffers();
  rebind(map);
  // A build, or an update of the lines whose input changed, reading the obstacles from the
  // change set or from the whole tree.
  const bool build = !built_ || stale_;
  const bool from_changes = !build && fromChanges();
  gpu::ScanParams sp{};
  sp.resolution = liveMap().params().resolution;
  sp.resolution_factor = 1.0 / liveMap().params().resolution;
  sp.occupancy_log = liveMap().logOdds().occupancy;
  const auto dirty = box_.dirtyWords();
  gpu::FieldHeader h{};
  h.occupancy = occupancy_.address();
  h.line_x = line_x_.address();
  h.plane_xy = plane_xy_.address();
  h.sites = sites_.address();
  h.envelope = envelope_.address();
  h.dirty = dirty_.address();
  h.min_key_x = box_.min_key[0];
  h.min_key_y = box_.min_key[1];
  h.min_key_z = box_.min_key[2];
  h.size_x = box_.size[0];
  h.size_y = box_.size[1];
  h.size_z = box_.size[2];
  h.words_per_row = box_.wordsPerRow();
  h.unknown_occupied = options_.treat_unknown_as_occupied ? 1u : 0u;
  h.max_distance_m = options_.max_distance_m;
  h.dirty_y = static_cast<std::uint32_t>(dirty[0]);
  h.dirty_z = static_cast<std::uint32_t>(dirty[0] + dirty[1]);
  passes::Recorder r(device_, stream_, map);
  stream_.begin(bindings_);
  const std::uint32_t start = stream_.timestamp();
  stream_.update(params_, &sp, sizeof(sp));
  stream_.update(header_, &h, sizeof(h));
  if (!build) stream_.fill(dirty_, 0u);
  stream_.barrier();
  if (from_changes)
    field::recordChanges(r, header_.address(), std::uint32_t{1} << map.changesLog2());
  else
    field::recordRaster(r, header_.address(), static_cast<std::uint32_t>(box_.words()), !build);
  field::recordNearestX(r, header_.address(), box_.size, build);
  field::recordEdt(r, header_.address(), box_.size, build);
  const std::uint32_t end = stream_.timestamp();
  stream_.copy(header_, readback_, sizeof(gpu::FieldHeader));
  stale_ = true;  // until the device says it finished
  built_ = false;
  stream_.submitAndWait();
  gpu::FieldHeader done;
  std::memcpy(&done, readback_.mapped(), sizeof(done));
  if (done.status & gpu::kFieldStatusCut)
    throw Error(ErrorCode::kInternal,
                "DistanceField: the device ended a line's loop early (its driver's loop limit is "
                "lower than the device probe measured); the field is not up to date, and queries "
                "refuse until update() succeeds. Use a box with shorter lines");
  stale_ = false;
  built_ = true;
  last_kind_ = build ? UpdateKind::kBuild
                     : (from_changes ? UpdateKind::kFromChanges : UpdateKind::kFromTree);
  // The change set's keys are in the field now: a set the fields turned on is emptied by the
  // one field following it (resetChangesForField; a set the user turned on is left alone, and
  // their next reset makes the next update read the tree).
  if (!building && !follows_changes_) {
    // From the first update() on, scans note their changed cells, which the next update starts
    // from (DynamicEDTOctomap's constructor turns change detection on; a field that is only
    // built and queried leaves the map as it was). See enableChangesForField.
    liveMap().enableChangesForField();
    follows_changes_ = true;
  }
  reset_changes_ = follows_changes_ && liveMap().resetChangesForField();
  tracking_ = liveMap().fieldTracking();
  const std::vector<double> ns = stream_.timestampsNs();
  last_ms_ = ns.size() > end ? (ns[end] - ns[start]) * 1e-6 : 0.0;
}

void DistanceField::Impl::checkFresh(const char* call) const {
  if (stale_)
    throw Error(ErrorCode::kInvalidArgument,
                std::string("DistanceField::") + call +
                    ": the last update() failed on the device; call update() again first");
}

void DistanceField::Impl::ensureQueries(std::size_t count) {
  count = std::min(count, batchLimit());
  if (count <= query_capacity_) return;
  const auto added = [](std::size_t n) {
    return 2 * n * (4 * sizeof(float) + sizeof(gpu::DistanceResult));  // each with its staging
  };
  const std::size_t freed =
      query_in_.size() + query_out_.size() + staging_in_.size() + staging_out_.size();
  MapBuffers& map = liveMap().fieldBuffers();
  // Queries run in batches of the capacity: a batch the cap has no room for runs as smaller
  // ones, and only where not even one query fits is it an error.
  std::size_t n = count;
  while (n > 1 && n > query_capacity_ && !map.fits(freed, added(n))) n /= 2;
  if (n <= query_capacity_) return;
  if (!map.fits(freed, added(n))) {
    const std::size_t cap = map.maxBytes(), held = map.deviceBytes();
    throw BudgetError("DistanceField: one query needs " + std::to_string(added(1)) +
                      " bytes of device memory for its buffers; the map's device-memory cap "
                      "(MapParams::max_device_bytes = " +
                      bytesText(cap) + ") leaves " + bytesText(cap > held ? cap - held : 0) +
                      " beside the " + bytesText(held) + " the map and its fields hold. " +
                      capAdvice(cap) + "; the map is unchanged");
  }
  try {
    vk::Buffer qi(device_, n * 4 * sizeof(float), false),
        qo(device_, n * sizeof(gpu::DistanceResult), false),
        si(device_, n * 4 * sizeof(float), true),
        so(device_, n * sizeof(gpu::DistanceResult), true);
    query_in_ = std::move(qi);
    query_out_ = std::move(qo);
    staging_in_ = std::move(si);
    staging_out_ = std::move(so);
  } catch (const Error& e) {
    if (e.code() != ErrorCode::kOutOfDeviceMemory) throw;
    throw Error(ErrorCode::kOutOfDeviceMemory,
                "DistanceField: buffers for a batch of " + std::to_string(n) + " queries need " +
                    bytesText(added(n)) + "; " + e.message() + ". Query fewer points per call",
                0, e.detail());
  }
  query_capacity_ = n;
  map.noteFieldBytes(freed, added(n));
  bytes_ = bytes_ - freed + added(n);
}

std::vector<DistanceSample> DistanceField::Impl::query(std::span<const float> spheres,
                                                       std::size_t count) {
  checkFresh("distances");
  std::vector<DistanceSample> out(count);
  if (count == 0) return out;
  ensureQueries(count);
  MapBuffers& map = liveMap().fieldBuffers();
  rebind(map);
  passes::Recorder r(device_, stream_, map);
  for (std::size_t first = 0; first < count; first += query_capacity_) {
    const std::size_t n = std::min(query_capacity_, count - first);
    std::memcpy(staging_in_.mapped(), spheres.data() + 4 * first, n * 4 * sizeof(float));
    stream_.begin(bindings_);
    stream_.copy(staging_in_, query_in_, n * 4 * sizeof(float));
    stream_.barrier();
    field::recordQueries(r, header_.address(), static_cast<std::uint32_t>(n));
    stream_.copy(query_out_, staging_out_, n * sizeof(gpu::DistanceResult));
    stream_.submitAndWait();
    const auto* res = static_cast<const gpu::DistanceResult*>(staging_out_.mapped());
    for (std::size_t i = 0; i < n; ++i) {
      const gpu::DistanceResult& g = res[i];
      DistanceSample& s = out[first + i];
      s.distance_m = g.distance;
      s.obstacle = {g.obstacle_x, g.obstacle_y, g.obstacle_z};
      s.gradient = {g.gradient_x, g.gradient_y, g.gradient_z};
      s.squared_cells = g.squared_cells;
    }
  }
  return out;
}

void DistanceField::Impl::queryOnDevice(VkBuffer in, VkDeviceSize in_offset, VkBuffer out,
                                        VkDeviceSize out_offset, std::uint32_t count,
                                        VkSemaphore wait, std::uint64_t wait_value) {
  checkFresh("distancesOnDevice");
  const VkDeviceSize align = device_.storageOffsetAlignment();
  if (in == VK_NULL_HANDLE || out == VK_NULL_HANDLE)
    throw Error(ErrorCode::kInvalidArgument, "distancesOnDevice: a buffer is VK_NULL_HANDLE");
  if (in_offset % align != 0 || out_offset % align != 0)
    throw Error(ErrorCode::kInvalidArgument,
                "distancesOnDevice: buffer offsets must be multiples of " + std::to_string(align) +
                    " (minStorageBufferOffsetAlignment)");
  if (count == 0) return;
  MapBuffers& map = liveMap().fieldBuffers();
  rebind(map);
  // The caller's ranges are bound in place of the field's query buffers for this submission
  // (BindingSet refuses a range beyond one binding's reach, naming it).
  bindings_.updateRange(gpu::kBindQueryIn, in, in_offset, VkDeviceSize{count} * 4 * sizeof(float));
  bindings_.updateRange(gpu::kBindQueryOut, out, out_offset,
                        VkDeviceSize{count} * sizeof(gpu::DistanceResult));
  passes::Recorder r(device_, stream_, map);
  if (wait != VK_NULL_HANDLE) stream_.waitBeforeNextSubmit(wait, wait_value);
  stream_.begin(bindings_);
  field::recordQueries(r, header_.address(), count);
  stream_.submitAndWait();
}

DistanceField::Grid DistanceField::Impl::download() {
  checkFresh("download");
  Grid g;
  g.size = box_.size;
  g.min_key = box_.min_key;
  const std::size_t cells = box_.cells();
  vk::Buffer staging;
  try {
    staging = vk::Buffer(device_, cells * sizeof(std::uint32_t), true);
  } catch (const Error& e) {
    if (e.code() != ErrorCode::kOutOfDeviceMemory) throw;
    throw Error(ErrorCode::kOutOfDeviceMemory,
                "DistanceField::download: the whole field (" + cellsText(box_) + ") needs " +
                    bytesText(cells * sizeof(std::uint32_t)) + " of host-visible memory; " +
                    e.message() + ". Read the cells you need with distances(), or shrink the box",
                0, e.detail());
  }
  MapBuffers& map = liveMap().fieldBuffers();
  rebind(map);
  stream_.begin(bindings_);
  stream_.copy(sites_, staging, cells * sizeof(std::uint32_t));
  stream_.submitAndWait();
  g.squared_cells.resize(cells);
  g.nearest.resize(cells);
  const auto* sites = static_cast<const std::uint32_t*>(staging.mapped());
  const std::size_t sx = box_.size[0], sy = box_.size[1];
  for (std::size_t i = 0; i < cells; ++i) {
    const std::uint32_t s = sites[i];
    if (s == gpu::kFieldNoSite) {
      g.squared_cells[i] = DistanceSample::kNoObstacleCells;
      g.nearest[i] = DistanceSample::kNoObstacleCells;
      continue;
    }
    // |cell - site|^2 < 2^31 (gpu::kFieldMaxAxisCells)
    const auto d = [&](std::size_t a, std::size_t b) {
      const std::int64_t v = static_cast<std::int64_t>(a) - static_cast<std::int64_t>(b);
      return v * v;
    };
    g.squared_cells[i] = static_cast<std::uint32_t>(
        d(i % sx, s % sx) + d((i / sx) % sy, (s / sx) % sy) + d(i / (sx * sy), s / (sx * sy)));
    g.nearest[i] = s;
  }
  return g;
}

// ---- the public class ----

DistanceField::DistanceField(OccupancyMap& map, const Eigen::Vector3f& box_min,
                             const Eigen::Vector3f& box_max, const DistanceFieldOptions& options) {
  hostMemoryGuard("DistanceField", [&] {
    OccupancyMap::Impl& m = FieldAccess::impl(map);
    const FieldBox box = fieldBox(m.params().resolution, box_min, box_max, options,
                                  maxLineCells(m.device()), "the box");
    impl_ = std::make_unique<Impl>(m, box, options);
  });
}

DistanceField::DistanceField(OccupancyMap& map, const DistanceFieldOptions& options) {
  hostMemoryGuard("DistanceField", [&] {
    OccupancyMap::Impl& m = FieldAccess::impl(map);
    std::array<std::uint32_t, 3> lo{}, hi{};
    if (!leafKeyBounds(map, lo, hi))
      throw invalid(
          "the map has no cells yet, so no bounds for the field to cover; insert a "
          "scan first or give a box");
    // One cell more on each side (within the key range): the unknown space around the map.
    Eigen::Vector3f min, max;
    const double res = m.params().resolution;
    for (int a = 0; a < 3; ++a) {
      min[a] = static_cast<float>((double(lo[a] > 0 ? lo[a] - 1 : 0) - 32768.0 + 0.5) * res);
      max[a] =
          static_cast<float>((double(hi[a] < 65535 ? hi[a] + 1 : 65535) - 32768.0 + 0.5) * res);
    }
    const FieldBox box = fieldBox(res, min, max, options, maxLineCells(m.device()),
                                  "the map's bounds (and one cell around them)");
    impl_ = std::make_unique<Impl>(m, box, options);
  });
}

// As a map (occupancy_map.cpp): a field made before fork() is left alone in the child, and one
// destroyed after exit() began.
DistanceField::~DistanceField() {
  if (impl_ && impl_->device().abandoned()) vk::Device::keepUntilExit(impl_.release());
}
DistanceField::DistanceField(DistanceField&&) noexcept = default;
DistanceField& DistanceField::operator=(DistanceField&& other) noexcept {
  if (impl_ && impl_->device().abandoned()) vk::Device::keepUntilExit(impl_.release());
  impl_ = std::move(other.impl_);
  return *this;
}

DistanceField::Impl& DistanceField::self() const {
  if (!impl_)
    throw Error(ErrorCode::kInvalidArgument, "DistanceField: used after it was moved from");
  impl_->device().checkNotForked("DistanceField");
  return *impl_;
}

void DistanceField::update() {
  hostMemoryGuard("DistanceField::update", [&] { self().update(); });
}

std::vector<DistanceSample> DistanceField::distances(
    std::span<const Eigen::Vector3f> points) const {
  return hostMemoryGuard("DistanceField::distances", [&] {
    std::vector<float> spheres(points.size() * 4);
    for (std::size_t i = 0; i < points.size(); ++i) {
      spheres[4 * i] = points[i].x();
      spheres[4 * i + 1] = points[i].y();
      spheres[4 * i + 2] = points[i].z();
      spheres[4 * i + 3] = 0.0f;
    }
    return self().query(spheres, points.size());
  });
}

std::vector<DistanceSample> DistanceField::clearances(
    std::span<const Eigen::Vector4f> spheres) const {
  static_assert(sizeof(Eigen::Vector4f) == 4 * sizeof(float));
  return hostMemoryGuard("DistanceField::clearances", [&] {
    if (spheres.empty()) return std::vector<DistanceSample>{};
    return self().query(std::span<const float>(spheres.data()->data(), spheres.size() * 4),
                        spheres.size());
  });
}

DistanceField::Grid DistanceField::download() const {
  return hostMemoryGuard("DistanceField::download", [&] { return self().download(); });
}

std::array<std::uint32_t, 3> DistanceField::size() const { return self().box().size; }
std::array<std::uint32_t, 3> DistanceField::minKey() const { return self().box().min_key; }
const DistanceFieldOptions& DistanceField::options() const { return self().options(); }
std::size_t DistanceField::deviceBytes() const { return self().deviceBytes(); }
double DistanceField::lastUpdateMs() const { return self().lastUpdateMs(); }
DistanceField::UpdateKind DistanceField::lastUpdateKind() const { return self().lastUpdateKind(); }

}  // namespace octovk
