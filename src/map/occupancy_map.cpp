// OccupancyMap: owns the map's device buffers and records the passes of a scan.
// Each stage is one shader in shaders/ and one record* function here.
#include <algorithm>
#include <array>
#include <chrono>
#include <cmath>
#include <cstring>
#include <type_traits>

#include "map/reference.hpp"
#include "octovk/gpu_types.h"
#include "octovk/octovk.hpp"
#include "octovk/vulkan_interop.hpp"
#include "vk/device.hpp"

namespace octovk {

namespace {

constexpr std::uint32_t kInitialBlocks = 1024;
constexpr std::uint32_t kInitialHashLog2 = 12;
// Cell-list entries per brick slot of the cell set (rays touch 4-6 cells of most bricks they
// cross).
constexpr std::uint32_t kCellsPerBrickSlot = 4;
// Cell ids (brick slot * 64 + index) must fit 32 bits.
constexpr std::uint32_t kMaxHashLog2 = 26;

std::uint32_t groupsFor(std::size_t items) {
  return static_cast<std::uint32_t>((items + gpu::kWorkgroupSize - 1) / gpu::kWorkgroupSize);
}

std::uint32_t nextPow2Log2(std::size_t n) {
  std::uint32_t log2 = 0;
  while ((std::size_t{1} << log2) < n) ++log2;
  return log2;
}

// The first RayState after `results` results in the query output: castRay's walk states follow
// the results there, from the first element of a RayState array that lies past them.
std::uint32_t firstRayState(std::size_t results) {
  return static_cast<std::uint32_t>((results * sizeof(gpu::RayResult) + sizeof(gpu::RayState) - 1) /
                                    sizeof(gpu::RayState));
}

gpu::ScanCounters freshCounters() {
  gpu::ScanCounters c{};
  for (auto& a : c.touched_args) a = {0, 1, 1};
  for (auto& a : c.walk_args) a = {0, 1, 1};
  c.cell_args = {0, 1, 1};
  c.brick_args = {0, 1, 1};
  return c;
}

}  // namespace

class OccupancyMap::Impl {
 public:
  Impl(Context& context, const MapParams& params)
      : device_(context.vulkan()), params_(params), bindings_(device_), stream_(device_) {
    if (std::string why = params.validate(); !why.empty())
      throw Error(ErrorCode::kInvalidArgument, why);
    logs_ = ref::LogOddsParams::from(params);
    params_buf_ = vk::Buffer(device_, sizeof(gpu::ScanParams), false);
    counters_buf_ = vk::Buffer(device_, sizeof(gpu::ScanCounters), false);
    pool_buf_ = vk::Buffer(device_, sizeof(gpu::PoolState), false);
    readback_ = vk::Buffer(device_, sizeof(gpu::ScanCounters) + sizeof(gpu::PoolState), true);
    ensureQueryBuffers(64, 64);
    points_buf_ = vk::Buffer(device_, 16, false);
    walks_ = vk::Buffer(device_, 16, false);
    upload_ = vk::Buffer(device_, 16, true);
    allocateEndpoints(kInitialHashLog2);
    allocateHash(kInitialHashLog2);
    allocateLists(1024);
    allocatePool(std::min<std::uint32_t>(kInitialBlocks, blockLimit()), /*copy_old=*/false);
    resetPool();
  }

  ScanStats insert(std::span<const Eigen::Vector3f> points, const Eigen::Vector3f& origin,
                   const Pose* pose, double max_range, bool discretize,
                   const QueryRequest* queries = nullptr, QueryResults* results = nullptr);
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
  std::size_t deviceBytes() const;
  std::size_t poolBytes() const {
    return nodes_.size() + block_parents_.size() + free_stack_.size();
  }

  const MapParams& params() const { return params_; }
  void setLeafBoxesEveryScan(bool every_scan) { leaf_boxes_every_scan_ = every_scan; }
  /// Rebuilds the leaf boxes if scans were inserted without rebuilding them.
  void refreshLeafBoxes() {
    if (!leaf_boxes_dirty_) return;
    stream_.begin(bindings_);
    recordLeafBoxes();
    stream_.submitAndWait();
    leaf_boxes_dirty_ = false;
  }

 private:
  void allocateHash(std::uint32_t log2);
  void allocateLists(std::size_t active_capacity);
  void allocateEndpoints(std::uint32_t log2);
  void allocateSlots();
  void allocatePool(std::uint32_t blocks, bool copy_old);
  void resetPool();
  /// Most blocks the pool may have (MapParams::max_nodes, and 2^32 nodes).
  std::uint32_t blockLimit() const {
    constexpr std::uint64_t kMax = 0x1FFFFFFFu;
    if (params_.max_nodes == 0) return kMax;
    return static_cast<std::uint32_t>(std::clamp<std::uint64_t>(params_.max_nodes / 8, 2, kMax));
  }
  void rebind();
  void ensurePoints(std::size_t count);
  gpu::ScanParams scanParams(const Eigen::Vector3f& origin, const Pose* pose, double max_range,
                             std::size_t count) const;

  void recordRayKeys(const gpu::ScanParams& sp, bool transform, bool discretize, bool fill_sets);
  void recordClassify(bool discretize, std::uint32_t points);
  template <typename MakeConstants>
  void recordContinuations(const char* pass, std::uint32_t rounds, MakeConstants constants);
  void recordTreeUpdate(std::uint32_t new_blocks, std::uint32_t active, std::uint32_t descending);
  void recordLeafBoxes();
  void recordReadback();
  void readBack(gpu::ScanCounters& counters, gpu::PoolState& pool);
  void stageQueries(const QueryRequest& queries);
  void recordQueries(const QueryRequest& queries);
  void recordCastRays(std::uint32_t rays, std::uint32_t first_state);
  void recordLookups(std::uint32_t points, std::uint32_t first_result, std::uint32_t first_float);
  QueryResults collectQueries(const QueryRequest& queries);
  void ensureQueryBuffers(std::size_t in_bytes, std::size_t out_bytes);

  // Each pass reads the pipeline layout's 16-byte push range as its own struct (gpu_types.h);
  // these record it with that struct, or NoConstants for the passes that take none. The
  // constants' type is always spelled out at the call: a braced list does not deduce one.
  template <typename Constants>
  static void checkConstants() {
    static_assert(
        sizeof(Constants) == sizeof(gpu::PassConstants) && std::is_trivially_copyable_v<Constants>,
        "push constants are one of gpu_types.h's 16-byte structs");
  }
  /// One invocation per work item.
  template <typename Constants>
  void dispatch(const char* pass, std::size_t items, const Constants& pc) {
    checkConstants<Constants>();
    stream_.dispatch(device_.pass(pass), groupsFor(items), &pc, sizeof(pc));
    stream_.barrier();
  }
  void dispatch(const char* pass, std::size_t items) { dispatch(pass, items, gpu::NoConstants{}); }
  /// Groups read from the counters at byte `args_offset` (a DispatchArgs).
  template <typename Constants>
  void dispatchIndirect(const char* pass, std::size_t args_offset, const Constants& pc) {
    checkConstants<Constants>();
    stream_.dispatchIndirect(device_.pass(pass), counters_buf_, args_offset, &pc, sizeof(pc));
    stream_.barrier();
  }
  void dispatchIndirect(const char* pass, std::size_t args_offset) {
    dispatchIndirect(pass, args_offset, gpu::NoConstants{});
  }

  vk::Device& device_;
  MapParams params_;
  ref::LogOddsParams logs_;
  vk::BindingSet bindings_;
  vk::CommandStream stream_;

  vk::Buffer params_buf_, counters_buf_, pool_buf_, readback_, points_buf_, upload_;
  vk::Buffer hash_keys_, hash_flags_, cell_list_, cells_, endpoint_keys_;
  vk::Buffer touched_;
  vk::Buffer prefix_blocks_;  // gpu::NewBlock per slot of the second set
  vk::Buffer nodes_, block_parents_, free_stack_, leaf_boxes_;
  vk::Buffer query_in_, query_out_, query_staging_in_, query_staging_out_;
  vk::Buffer walks_;  // ray walks saved between segments (two lists of point_capacity_)
  vk::Buffer slots_;  // filled slots of the cell set, then of the second set
  // Whether the sets must be cleared whole (new, or left in an unknown state by a failed scan);
  // else only the slots the last scan filled are cleared.
  bool sets_need_fill_ = true;
  std::uint32_t filled_bricks_ = 0, filled_endpoints_ = 0;
  std::uint32_t hash_log2_ = 0, endpoint_log2_ = 0;
  std::size_t active_capacity_ = 0;
  std::uint32_t pool_blocks_ = 0;
  std::size_t point_capacity_ = 0;
  bool leaf_boxes_every_scan_ = false;
  bool leaf_boxes_dirty_ = false;
};

// ---- buffers ---------------------------------------------------------------------------------

// The cell set: 2^log2 brick slots, and lists for 4 cells per brick slot (a list that outgrows
// them makes the set grow like a full set does).
void OccupancyMap::Impl::allocateHash(std::uint32_t log2) {
  const std::size_t cap = std::size_t{1} << log2;
  const std::size_t cell_cap = cap * kCellsPerBrickSlot;
  vk::Buffer keys(device_, cap * sizeof(std::uint64_t), false);
  vk::Buffer flags(device_, cap * gpu::kBrickFlagWords * sizeof(std::uint32_t), false);
  vk::Buffer cell_list(device_, cell_cap * sizeof(std::uint32_t), false);
  vk::Buffer cells(device_, cell_cap * sizeof(gpu::ActiveCell), false);
  hash_keys_ = std::move(keys);
  hash_flags_ = std::move(flags);
  cell_list_ = std::move(cell_list);
  cells_ = std::move(cells);
  hash_log2_ = log2;
  // The second set holds about as many entries as the first (end cells, or new-block prefixes).
  if (endpoint_keys_.valid() && endpoint_log2_ < log2) allocateEndpoints(log2);
  allocateSlots();
}

void OccupancyMap::Impl::allocateEndpoints(std::uint32_t log2) {
  vk::Buffer keys(device_, (std::size_t{1} << log2) * sizeof(std::uint64_t), false);
  vk::Buffer blocks(device_, (std::size_t{1} << log2) * sizeof(gpu::NewBlock), false);
  endpoint_keys_ = std::move(keys);
  prefix_blocks_ = std::move(blocks);
  endpoint_log2_ = log2;
  allocateSlots();
}

// The slot lists cover both sets; new sets start unfilled and are cleared whole once.
void OccupancyMap::Impl::allocateSlots() {
  const std::size_t entries = (std::size_t{1} << hash_log2_) + (std::size_t{1} << endpoint_log2_);
  if (slots_.size() < entries * sizeof(std::uint32_t)) {
    vk::Buffer slots(device_, entries * sizeof(std::uint32_t), false);
    slots_ = std::move(slots);
  }
  sets_need_fill_ = true;
  rebind();
}

void OccupancyMap::Impl::allocateLists(std::size_t active_capacity) {
  vk::Buffer touched(device_, active_capacity * gpu::kTreeDepth * sizeof(std::uint32_t), false);
  touched_ = std::move(touched);
  active_capacity_ = active_capacity;
  rebind();
}

// Grows the pool to `blocks`, keeping the tree. All new buffers are made before any old one is
// dropped, so a failed allocation leaves the map as it was.
void OccupancyMap::Impl::allocatePool(std::uint32_t blocks, bool copy_old) {
  vk::Buffer nodes(device_, std::size_t{blocks} * 8 * sizeof(gpu::Node), false);
  vk::Buffer parents(device_, std::size_t{blocks} * sizeof(std::uint32_t), false);
  vk::Buffer free_stack(device_, std::size_t{blocks} * sizeof(std::uint32_t), false);
  vk::Buffer leaves(device_, std::size_t{blocks} * 8 * sizeof(gpu::LeafBox), false);
  if (copy_old) {
    stream_.begin(bindings_);
    stream_.copy(nodes_, nodes, nodes_.size());
    stream_.copy(block_parents_, parents, block_parents_.size());
    stream_.copy(free_stack_, free_stack, free_stack_.size());
    stream_.update(pool_buf_, &blocks, sizeof(blocks), offsetof(gpu::PoolState, capacity));
    stream_.submitAndWait();
  }
  nodes_ = std::move(nodes);
  block_parents_ = std::move(parents);
  free_stack_ = std::move(free_stack);
  leaf_boxes_ = std::move(leaves);
  pool_blocks_ = blocks;
  rebind();
}

void OccupancyMap::Impl::resetPool() {
  gpu::PoolState pool{};
  pool.bump = 1;  // block 0 is the root's
  pool.capacity = pool_blocks_;
  const gpu::ScanCounters counters = freshCounters();
  stream_.begin(bindings_);
  stream_.update(pool_buf_, &pool, sizeof(pool));
  stream_.update(counters_buf_, &counters, sizeof(counters));
  stream_.submitAndWait();
}

void OccupancyMap::Impl::rebind() {
  if (!nodes_.valid() || !hash_keys_.valid() || !touched_.valid() || !query_in_.valid() ||
      !slots_.valid())
    return;
  const std::array<const vk::Buffer*, gpu::kBindingCount> buffers = {
      &params_buf_, &counters_buf_,  &pool_buf_,      &points_buf_,    &hash_keys_,
      &hash_flags_, &nodes_,         &block_parents_, &free_stack_,    &cells_,
      &touched_,    &prefix_blocks_, &leaf_boxes_,    &endpoint_keys_, &query_in_,
      &query_out_,  &walks_,         &slots_,         &cell_list_};
  bindings_.update(buffers);
}

void OccupancyMap::Impl::ensurePoints(std::size_t count) {
  if (count <= point_capacity_) return;
  const std::size_t cap = std::max(count, point_capacity_ * 2);
  vk::Buffer device_points(device_, cap * 3 * sizeof(float), false);
  vk::Buffer staging(device_, cap * 3 * sizeof(float), true);
  vk::Buffer walks(device_, 2 * cap * sizeof(gpu::WalkState), false);
  points_buf_ = std::move(device_points);
  upload_ = std::move(staging);
  walks_ = std::move(walks);
  point_capacity_ = cap;
  rebind();
}

void OccupancyMap::Impl::ensureQueryBuffers(std::size_t in_bytes, std::size_t out_bytes) {
  in_bytes = std::max<std::size_t>(in_bytes, 64);
  out_bytes = std::max<std::size_t>(out_bytes, 64);
  if (query_in_.size() < in_bytes) {
    vk::Buffer device_in(device_, in_bytes, false);
    vk::Buffer staging(device_, in_bytes, true);
    query_in_ = std::move(device_in);
    query_staging_in_ = std::move(staging);
  }
  if (query_out_.size() < out_bytes) {
    vk::Buffer device_out(device_, out_bytes, false);
    vk::Buffer staging(device_, out_bytes, true);
    query_out_ = std::move(device_out);
    query_staging_out_ = std::move(staging);
  }
  rebind();
}

std::size_t OccupancyMap::Impl::deviceBytes() const {
  std::size_t total = 0;
  for (const vk::Buffer* b :
       {&params_buf_, &counters_buf_, &pool_buf_, &points_buf_, &hash_keys_, &hash_flags_, &cells_,
        &endpoint_keys_, &touched_, &prefix_blocks_, &nodes_, &block_parents_, &free_stack_,
        &leaf_boxes_, &query_in_, &query_out_, &walks_, &slots_, &cell_list_})
    total += b->size();
  return total;
}

// ---- one scan --------------------------------------------------------------------------------

gpu::ScanParams OccupancyMap::Impl::scanParams(const Eigen::Vector3f& origin, const Pose* pose,
                                               double max_range, std::size_t count) const {
  gpu::ScanParams sp{};
  sp.resolution = params_.resolution;
  sp.resolution_factor = 1.0 / params_.resolution;
  sp.max_range = max_range;
  sp.origin_x = origin.x();
  sp.origin_y = origin.y();
  sp.origin_z = origin.z();
  sp.prob_hit_log = logs_.hit;
  sp.prob_miss_log = logs_.miss;
  sp.clamp_min_log = logs_.clamp_min;
  sp.clamp_max_log = logs_.clamp_max;
  sp.point_count = static_cast<std::uint32_t>(count);
  sp.hash_capacity = 1u << hash_log2_;
  sp.hash_log2 = hash_log2_;
  sp.endpoint_capacity = 1u << endpoint_log2_;
  sp.endpoint_log2 = endpoint_log2_;
  sp.active_capacity = static_cast<std::uint32_t>(active_capacity_);
  sp.cell_capacity = (1u << hash_log2_) * kCellsPerBrickSlot;
  sp.occupancy_log = logs_.occupancy;
  if (pose) {
    sp.rot_u = pose->rotation.w();
    sp.rot_x = pose->rotation.x();
    sp.rot_y = pose->rotation.y();
    sp.rot_z = pose->rotation.z();
    sp.trans_x = pose->translation.x();
    sp.trans_y = pose->translation.y();
    sp.trans_z = pose->translation.z();
  }
  return sp;
}

// Records `rounds` indirect dispatches of `pass` that continue the walks listed in the two lists
// of ScanCounters::walk_count, alternately: each round empties the other list, then continues
// the listed walks, which list the ones still unfinished in it.
// `constants(from, last)` gives the pass's push constants for the round that continues list
// `from` (`last`: the last round).
template <typename MakeConstants>
void OccupancyMap::Impl::recordContinuations(const char* pass, std::uint32_t rounds,
                                             MakeConstants constants) {
  for (std::uint32_t round = 0; round < rounds; ++round) {
    const std::uint32_t from = round % 2, to = 1 - from;
    stream_.fill(counters_buf_, 0u, offsetof(gpu::ScanCounters, walk_count) + 4 * to, 4);
    stream_.fill(counters_buf_, 0u,
                 offsetof(gpu::ScanCounters, walk_args) + to * sizeof(gpu::DispatchArgs), 4);
    stream_.barrier();
    dispatchIndirect(pass,
                     offsetof(gpu::ScanCounters, walk_args) + from * sizeof(gpu::DispatchArgs),
                     constants(from, round + 1 == rounds));
  }
}

void OccupancyMap::Impl::recordRayKeys(const gpu::ScanParams& sp, bool transform, bool discretize,
                                       bool fill_sets) {
  const gpu::ScanCounters counters = freshCounters();
  stream_.timestamp();
  stream_.update(params_buf_, &sp, sizeof(sp));
  stream_.update(counters_buf_, &counters, sizeof(counters));
  stream_.copy(upload_, points_buf_, std::size_t{sp.point_count} * 3 * sizeof(float));
  if (fill_sets) {
    stream_.fill(hash_keys_, 0xFFFFFFFFu);
    stream_.fill(hash_flags_, 0u);
    stream_.fill(endpoint_keys_, 0xFFFFFFFFu);
  } else {
    stream_.barrier();
    dispatch(
        "clear_sets", std::max(filled_bricks_, filled_endpoints_),
        gpu::ClearSetsConstants{
            .mode = gpu::kClearPrevious, .bricks = filled_bricks_, .endpoints = filled_endpoints_});
  }
  stream_.barrier();
  stream_.timestamp();
  if (transform)
    dispatch("transform_points", sp.point_count,
             gpu::TransformPointsConstants{.point_count = sp.point_count});
  // Where the driver ends an invocation's loops early (the device probe measures it: llvmpipe
  // after 65535 iterations in total, silently, counted for 8 lanes at once), a walk stops after
  // its budget of iterations (steps and hash probes; 30000 there) and is continued by more
  // dispatches, each over the walks left unfinished (3 * 65536 steps reach any border, 24 of
  // 30000 leave room for the probes). A walk still unfinished after them is reported. Where no
  // limit was seen, every ray is walked in one go.
  const std::uint32_t budget = device_.walkBudget();
  if (discretize) {
    dispatch("discretize", sp.point_count, gpu::DiscretizeConstants{.point_count = sp.point_count});
    dispatch("ray_keys", sp.point_count,
             gpu::RayKeysConstants{
                 .budget = budget, .point_count = sp.point_count, .mode = gpu::kRayKeysEndCells});
  } else {
    dispatch("ray_keys", sp.point_count,
             gpu::RayKeysConstants{
                 .budget = budget, .point_count = sp.point_count, .mode = gpu::kRayKeysPoints});
  }
  const std::uint32_t continuations = device_.walkContinuations(24u * 30000u);
  recordContinuations("ray_keys", continuations, [&](std::uint32_t from, bool last) {
    return gpu::RayKeysConstants{.budget = budget,
                                 .point_count = sp.point_count,
                                 .mode = last ? gpu::kRayKeysContinueLast : gpu::kRayKeysContinue,
                                 .from_list = from};
  });
}

void OccupancyMap::Impl::recordClassify(bool discretize, std::uint32_t points) {
  stream_.timestamp();
  // The second set now collects the prefixes of nodes that get a block: empty discretize's end
  // cells out of it first.
  if (discretize)
    dispatch("clear_sets", points, gpu::ClearSetsConstants{.mode = gpu::kClearEndCells});
  dispatchIndirect("list_cells", offsetof(gpu::ScanCounters, brick_args));
  dispatchIndirect("classify", offsetof(gpu::ScanCounters, cell_args));
  stream_.timestamp();
}

// new_blocks: the blocks alloc hands out (counted by classify); active: the cells to update, of
// which the first `descending` need nodes created on their path.
void OccupancyMap::Impl::recordTreeUpdate(std::uint32_t new_blocks, std::uint32_t active,
                                          std::uint32_t descending) {
  dispatch("tree_begin", 1);
  if (new_blocks > 0) {
    dispatch("alloc", new_blocks);
    dispatch("tree_fixup", 1);
    dispatch("link", new_blocks);
  }
  dispatch("descend", active,
           gpu::DescendConstants{.cell_count = active, .descending = descending});
  stream_.timestamp();
  for (std::uint32_t level = gpu::kTreeDepth; level-- > 0;)
    dispatchIndirect("prune",
                     offsetof(gpu::ScanCounters, touched_args) + level * sizeof(gpu::DispatchArgs),
                     gpu::PruneConstants{.level = level});
  stream_.timestamp();
}

void OccupancyMap::Impl::recordLeafBoxes() {
  stream_.fill(pool_buf_, 0u, offsetof(gpu::PoolState, leaf_count), sizeof(std::uint32_t));
  stream_.barrier();
  dispatch("leaf_boxes", pool_blocks_, gpu::LeafBoxesConstants{.mode = gpu::kLeafBoxesRebuild});
  stream_.timestamp();
}

void OccupancyMap::Impl::recordReadback() {
  stream_.copy(counters_buf_, readback_, sizeof(gpu::ScanCounters));
  stream_.copy(pool_buf_, readback_, sizeof(gpu::PoolState), 0, sizeof(gpu::ScanCounters));
}

void OccupancyMap::Impl::readBack(gpu::ScanCounters& counters, gpu::PoolState& pool) {
  const auto* bytes = static_cast<const unsigned char*>(readback_.mapped());
  std::memcpy(&counters, bytes, sizeof(counters));
  std::memcpy(&pool, bytes + sizeof(counters), sizeof(pool));
}

gpu::PoolState OccupancyMap::Impl::readPool() {
  stream_.begin(bindings_);
  recordReadback();
  stream_.submitAndWait();
  gpu::ScanCounters counters;
  gpu::PoolState pool;
  readBack(counters, pool);
  return pool;
}

ScanStats OccupancyMap::Impl::insert(std::span<const Eigen::Vector3f> points,
                                     const Eigen::Vector3f& origin, const Pose* pose,
                                     double max_range, bool discretize, const QueryRequest* queries,
                                     QueryResults* results) {
  const auto start = std::chrono::steady_clock::now();
  if (!origin.allFinite())
    throw Error(ErrorCode::kInvalidArgument,
                "insertPointCloud: the sensor origin is not finite (NaN or inf); pass the "
                "sensor position in metres");
  if (pose && (!pose->translation.allFinite() || !pose->rotation.coeffs().allFinite()))
    throw Error(ErrorCode::kInvalidArgument,
                "insertPointCloud: the sensor pose is not finite (NaN or inf)");
  if (std::isnan(max_range))
    throw Error(ErrorCode::kInvalidArgument,
                "insertPointCloud: max_range is NaN; use a negative value for unlimited range");
  // Lists of points and cells are walked by indirect dispatches of one group per 64 entries.
  const std::size_t max_items = std::size_t{device_.maxGroupsX()} * gpu::kWorkgroupSize;
  if (points.size() > std::min<std::size_t>(0x7FFFFFFFu, max_items))
    throw Error(ErrorCode::kInvalidArgument,
                "insertPointCloud: " + std::to_string(points.size()) +
                    " points in one scan; the device '" + device_.info().name + "' takes at most " +
                    std::to_string(std::min<std::size_t>(0x7FFFFFFFu, max_items)) +
                    " (maxComputeWorkGroupCount x 64); split the scan");

  ScanStats stats;
  stats.points = points.size();
  gpu::ScanCounters counters{};
  gpu::PoolState pool{};
  if (points.empty()) {
    if (queries) *results = runQueries(*queries);
    pool = readPool();
    stats.nodes = pool.root_exists ? pool.live_nodes : 0;
    return stats;
  }
  ensurePoints(points.size());
  // First guess of the cell set's size: 4 brick slots (16 cells) per point (a 320x240 depth view
  // at 0.05 m touches 0.6-1 million cells in about a quarter as many bricks), at most 2^20 brick
  // slots; it grows (and the ray pass is redone) when a scan needs more, and keeps its size for
  // the next scans.
  std::vector<double> t1;  // timestamps of group 1: start, uploaded, rays done, classified
  const std::uint32_t guess = std::min<std::uint32_t>(nextPow2Log2(points.size() * 4), 20);
  if (guess > hash_log2_) allocateHash(guess);
  static_assert(sizeof(Eigen::Vector3f) == 3 * sizeof(float));
  std::memcpy(upload_.mapped(), points.data(), points.size() * sizeof(Eigen::Vector3f));

  // Until this scan succeeds, the sets' contents are not known to be only its listed slots.
  bool fill_sets = sets_need_fill_;
  sets_need_fill_ = true;

  // Pass group 1: ray keys into the hash set and the early-abort classification. The counters
  // come back so the host can grow the hash set (and retry) or the pool before the tree changes.
  for (;; fill_sets = true) {
    const gpu::ScanParams sp = scanParams(origin, pose, max_range, points.size());
    stream_.begin(bindings_);
    recordRayKeys(sp, pose != nullptr, discretize, fill_sets);
    recordClassify(discretize, static_cast<std::uint32_t>(points.size()));
    recordReadback();
    stream_.submitAndWait();
    t1 = stream_.timestampsNs();
    ++stats.cell_set_attempts;
    readBack(counters, pool);
    if (counters.status & gpu::kStatusRayCut)
      throw Error(ErrorCode::kMissingFeature,
                  "insertPointCloud: a ray crosses more cells than octovk walks on the device '" +
                      device_.info().name +
                      "' (about 196,000 steps); the map is unchanged. Use a coarser resolution "
                      "or a max range");
    if (counters.status & gpu::kStatusHashFull) {
      if (hash_log2_ + 2 > kMaxHashLog2)
        throw Error(ErrorCode::kOutOfDeviceMemory,
                    "insertPointCloud: a scan touches more than 2^25 bricks of 4x4x4 cells; the "
                    "map is unchanged. Split the scan");
      allocateHash(hash_log2_ + 2);
      continue;
    }
    if (counters.status & gpu::kStatusEndpointHashFull) {
      if (endpoint_log2_ >= 30)
        throw Error(ErrorCode::kOutOfDeviceMemory,
                    "insertPointCloud: a scan creates more than 2^29 blocks; split the scan");
      allocateEndpoints(endpoint_log2_ + 2);
      continue;
    }
    break;
  }
  if (t1.size() == 4) {
    stats.device.upload_ms = (t1[1] - t1[0]) * 1e-6;
    stats.device.ray_keys_ms = (t1[2] - t1[1]) * 1e-6;
    stats.device.classify_ms = (t1[3] - t1[2]) * 1e-6;
  }
  stats.skipped_nonfinite = counters.skipped_nonfinite;
  stats.skipped_outside = counters.skipped_outside;
  stats.free_cells = counters.free_cells;
  stats.occupied_cells = counters.occupied_cells;
  stats.aborted_cells = counters.aborted;

  // Cells to update: those whose path needs nodes (descending), and those whose leaf exists.
  const std::uint32_t descending = counters.active_cells;
  const std::uint32_t active = descending + counters.leaf_cells;
  if (active > 0) {
    // Exactly the blocks the tree passes will take (counted by the classify pass).
    const std::uint64_t bound = counters.new_blocks;
    const std::uint64_t available = std::uint64_t{pool.capacity} - pool.bump + pool.free_count;
    if (bound > available) {
      const std::uint64_t needed = std::uint64_t{pool.bump} + bound - pool.free_count + 1;
      const std::uint64_t limit = blockLimit();
      if (needed > limit)
        throw Error(ErrorCode::kOutOfDeviceMemory,
                    "insertPointCloud: the scan needs a node pool of " +
                        std::to_string(needed * 8) + " nodes, over the limit of " +
                        std::to_string(limit * 8) +
                        " (MapParams::max_nodes or 2^32); the map is unchanged");
      const std::uint64_t blocks = std::min<std::uint64_t>(
          limit, std::max<std::uint64_t>(needed, std::uint64_t{pool_blocks_} + pool_blocks_ / 2));
      try {
        allocatePool(static_cast<std::uint32_t>(blocks), /*copy_old=*/true);
      } catch (const Error& e) {
        throw Error(ErrorCode::kOutOfDeviceMemory,
                    std::string("insertPointCloud: the device has no room to grow the node pool "
                                "to ") +
                        std::to_string(blocks * 8) + " nodes; the map is unchanged (" + e.what() +
                        ")");
      }
    }
    if (active > active_capacity_) allocateLists(std::size_t{1} << nextPow2Log2(active));

    if (queries) stageQueries(*queries);

    // Pass group 2: the tree update, pruning and the leaf-box rebuild (then the queries).
    const gpu::ScanParams sp = scanParams(origin, pose, max_range, points.size());
    stream_.begin(bindings_);
    stream_.update(params_buf_, &sp, sizeof(sp));
    stream_.barrier();
    stream_.timestamp();
    recordTreeUpdate(counters.new_blocks, active, descending);
    if (leaf_boxes_every_scan_) recordLeafBoxes();
    leaf_boxes_dirty_ = !leaf_boxes_every_scan_;
    if (queries) {
      stream_.barrier();
      recordQueries(*queries);
    }
    recordReadback();
    stream_.submitAndWait();
    if (queries) {
      *results = collectQueries(*queries);
      queries = nullptr;  // answered
    }
    if (const auto t2 = stream_.timestampsNs(); t2.size() >= 3) {
      stats.device.tree_update_ms = (t2[1] - t2[0]) * 1e-6;
      stats.device.prune_ms = (t2[2] - t2[1]) * 1e-6;
      if (t2.size() >= 4) stats.device.leaf_boxes_ms = (t2[3] - t2[2]) * 1e-6;
    }
    readBack(counters, pool);
    if (counters.status & gpu::kStatusPoolFull)
      throw Error(ErrorCode::kVulkan,
                  "internal error: the node pool ran out during a scan despite its size check; "
                  "please report this with the input");
  }
  filled_bricks_ = counters.brick_entries;
  filled_endpoints_ = counters.new_blocks;
  sets_need_fill_ = false;
  // A scan that changed nothing still answers its queries.
  if (queries) *results = runQueries(*queries);
  stats.nodes = pool.root_exists ? pool.live_nodes : 0;
  stats.wall_ms =
      std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - start).count();
  return stats;
}

// ---- queries ---------------------------------------------------------------------------------
// One batch: the rays, then the lookup points, in the input; their results in the same order in
// the output.

void OccupancyMap::Impl::stageQueries(const QueryRequest& q) {
  const std::size_t ray_bytes = q.rays.size() * sizeof(gpu::RayQuery);
  const std::size_t point_bytes = q.lookups.size() * 3 * sizeof(float);
  // The results, then (castRay) the walks' states from the first RayState past them.
  const std::size_t results = q.rays.size() + q.lookups.size();
  const std::size_t out_bytes = (firstRayState(results) + q.rays.size()) * sizeof(gpu::RayState);
  static_assert(sizeof(gpu::RayResult) == sizeof(gpu::LookupResult));
  ensureQueryBuffers(ray_bytes + point_bytes, out_bytes);
  auto* bytes = static_cast<unsigned char*>(query_staging_in_.mapped());
  for (std::size_t i = 0; i < q.rays.size(); ++i) {
    const Ray& r = q.rays[i];
    gpu::RayQuery g{};
    g.max_range = r.max_range_m;
    g.origin_x = r.origin.x();
    g.origin_y = r.origin.y();
    g.origin_z = r.origin.z();
    g.direction_x = r.direction.x();
    g.direction_y = r.direction.y();
    g.direction_z = r.direction.z();
    g.ignore_unknown = r.ignore_unknown ? 1u : 0u;
    std::memcpy(bytes + i * sizeof(g), &g, sizeof(g));
  }
  static_assert(sizeof(Eigen::Vector3f) == 3 * sizeof(float));
  if (point_bytes) std::memcpy(bytes + ray_bytes, q.lookups.data(), point_bytes);
}

void OccupancyMap::Impl::recordQueries(const QueryRequest& q) {
  const auto rays = static_cast<std::uint32_t>(q.rays.size());
  const auto points = static_cast<std::uint32_t>(q.lookups.size());
  const std::size_t in_bytes = rays * sizeof(gpu::RayQuery) + points * 3 * sizeof(float);
  const gpu::ScanParams sp = scanParams(Eigen::Vector3f::Zero(), nullptr, -1.0, 0);
  stream_.update(params_buf_, &sp, sizeof(sp));
  stream_.copy(query_staging_in_, query_in_, in_bytes);
  stream_.barrier();
  // The walk states follow the results in the output buffer.
  if (rays) recordCastRays(rays, firstRayState(rays + points));
  if (points)
    recordLookups(points, rays,
                  static_cast<std::uint32_t>(rays * sizeof(gpu::RayQuery) / sizeof(float)));
  stream_.copy(query_out_, query_staging_out_, (rays + points) * sizeof(gpu::RayResult));
}

// castRay for `rays` queries at the start of the query input; results at the start of the
// output, the walks' states (and lists of unfinished walks) from its RayState `first_state` on.
void OccupancyMap::Impl::recordCastRays(std::uint32_t rays, std::uint32_t first_state) {
  // Where the driver limits loops (see recordRayKeys) the walk runs in segments of the walk
  // budget (30000 on llvmpipe); the longest castRay (3 * 65536 steps, each with a search of up
  // to 17 iterations) then needs 112 continuations, over ever fewer rays. Elsewhere each ray is
  // walked in one segment.
  const std::uint32_t budget = device_.walkBudget();
  const std::uint32_t continuations = device_.walkContinuations(3u * 65536u * 17u);
  // The unfinished walks are listed (walk_count / walk_args, free once the scan's rays are
  // walked) and continued by indirect dispatches, which cost next to nothing once empty.
  // Both lists empty, with whole dispatch arguments: the counters may hold anything here (a map
  // imported and queried before any scan has never had them reset).
  static_assert(offsetof(gpu::ScanCounters, walk_args) ==
                offsetof(gpu::ScanCounters, walk_count) + sizeof(gpu::ScanCounters::walk_count));
  const gpu::ScanCounters fresh = freshCounters();
  stream_.update(counters_buf_, &fresh.walk_count,
                 sizeof(fresh.walk_count) + sizeof(fresh.walk_args),
                 offsetof(gpu::ScanCounters, walk_count));
  stream_.barrier();
  dispatch("cast_ray", rays,
           gpu::CastRayConstants{
               .budget = budget, .ray_count = rays, .resume = 0, .first_state = first_state});
  recordContinuations("cast_ray", continuations, [&](std::uint32_t from, bool) {
    return gpu::CastRayConstants{
        .budget = budget, .ray_count = rays, .resume = from + 1, .first_state = first_state};
  });
}

// search() for `points` points from float `first_float` of the query input; results from entry
// `first_result` of the output.
void OccupancyMap::Impl::recordLookups(std::uint32_t points, std::uint32_t first_result,
                                       std::uint32_t first_float) {
  dispatch("lookup", points,
           gpu::LookupConstants{
               .point_count = points, .first_float = first_float, .first_result = first_result});
}

void OccupancyMap::Impl::queryOnDevice(bool rays, VkBuffer in, VkDeviceSize in_offset,
                                       VkDeviceSize in_size, VkBuffer out, VkDeviceSize out_offset,
                                       VkDeviceSize out_size, std::uint32_t count) {
  const VkDeviceSize align = device_.storageOffsetAlignment();
  if (in == VK_NULL_HANDLE || out == VK_NULL_HANDLE)
    throw Error(ErrorCode::kInvalidArgument, "query on device: a buffer is VK_NULL_HANDLE");
  if (in_offset % align != 0 || out_offset % align != 0)
    throw Error(ErrorCode::kInvalidArgument,
                "query on device: buffer offsets must be multiples of " + std::to_string(align) +
                    " (minStorageBufferOffsetAlignment)");
  if (count == 0) return;
  // The map's own query buffers are swapped for the caller's ranges for this one submission.
  bindings_.updateRange(gpu::kBindQueryIn, in, in_offset, in_size);
  bindings_.updateRange(gpu::kBindQueryOut, out, out_offset, out_size);
  try {
    const gpu::ScanParams sp = scanParams(Eigen::Vector3f::Zero(), nullptr, -1.0, 0);
    stream_.begin(bindings_);
    stream_.update(params_buf_, &sp, sizeof(sp));
    stream_.barrier();
    if (rays)
      recordCastRays(count, firstRayState(count));
    else
      recordLookups(count, 0, 0);
    stream_.submitAndWait();
  } catch (...) {
    rebind();
    throw;
  }
  rebind();
}

QueryResults OccupancyMap::Impl::collectQueries(const QueryRequest& q) {
  QueryResults out;
  const auto* bytes = static_cast<const unsigned char*>(query_staging_out_.mapped());
  out.rays.resize(q.rays.size());
  for (std::size_t i = 0; i < q.rays.size(); ++i) {
    gpu::RayResult r;
    std::memcpy(&r, bytes + i * sizeof(r), sizeof(r));
    out.rays[i] = {r.hit != 0, Eigen::Vector3f(r.end_x, r.end_y, r.end_z)};
  }
  out.lookups.resize(q.lookups.size());
  for (std::size_t i = 0; i < q.lookups.size(); ++i) {
    gpu::LookupResult r;
    std::memcpy(&r, bytes + (q.rays.size() + i) * sizeof(r), sizeof(r));
    out.lookups[i] = {static_cast<CellState>(r.state), r.log_odds, r.depth};
  }
  return out;
}

QueryResults OccupancyMap::Impl::runQueries(const QueryRequest& q) {
  if (q.rays.empty() && q.lookups.empty()) return {};
  if (q.rays.size() + q.lookups.size() > 0x7FFFFFFFu)
    throw Error(ErrorCode::kInvalidArgument, "queries: more than 2^31 queries in one batch");
  // Unfinished castRay walks are continued by indirect dispatches of one group per 64 rays.
  const std::size_t max_rays = std::size_t{device_.maxGroupsX()} * gpu::kWorkgroupSize;
  if (q.rays.size() > max_rays)
    throw Error(ErrorCode::kInvalidArgument,
                "castRays: " + std::to_string(q.rays.size()) + " rays in one batch; the device '" +
                    device_.info().name + "' takes at most " + std::to_string(max_rays) +
                    " (maxComputeWorkGroupCount x 64); split the batch");
  stageQueries(q);
  stream_.begin(bindings_);
  recordQueries(q);
  stream_.submitAndWait();
  return collectQueries(q);
}

std::vector<OccupancyMap::LeafBoxHost> OccupancyMap::Impl::leavesInBox(const Eigen::Vector3f& min,
                                                                       const Eigen::Vector3f& max,
                                                                       bool occupied_only) {
  gpu::BoxQuery box{};
  const double factor = 1.0 / params_.resolution;
  if (!ref::coordToKeyChecked(factor, min.x(), box.min_x) ||
      !ref::coordToKeyChecked(factor, min.y(), box.min_y) ||
      !ref::coordToKeyChecked(factor, min.z(), box.min_z) ||
      !ref::coordToKeyChecked(factor, max.x(), box.max_x) ||
      !ref::coordToKeyChecked(factor, max.y(), box.max_y) ||
      !ref::coordToKeyChecked(factor, max.z(), box.max_z))
    return {};  // as OctoMap's iterator: a corner outside the map gives no leaves
  box.occupied_only = occupied_only ? 1u : 0u;
  ensureQueryBuffers(sizeof(box), std::size_t{pool_blocks_} * 8 * sizeof(gpu::LeafBox));
  const gpu::ScanParams sp = scanParams(Eigen::Vector3f::Zero(), nullptr, -1.0, 0);
  stream_.begin(bindings_);
  stream_.update(params_buf_, &sp, sizeof(sp));
  stream_.update(query_in_, &box, sizeof(box));
  stream_.fill(counters_buf_, 0u, offsetof(gpu::ScanCounters, query_results),
               sizeof(std::uint32_t));
  stream_.barrier();
  dispatch("leaf_boxes", pool_blocks_, gpu::LeafBoxesConstants{.mode = gpu::kLeafBoxesInBox});
  recordReadback();
  stream_.submitAndWait();
  gpu::ScanCounters counters;
  gpu::PoolState pool;
  readBack(counters, pool);
  std::vector<LeafBoxHost> out(counters.query_results);
  if (out.empty()) return out;
  const std::size_t bytes = out.size() * sizeof(gpu::LeafBox);
  stream_.begin(bindings_);
  stream_.copy(query_out_, query_staging_out_, bytes);
  stream_.submitAndWait();
  static_assert(sizeof(LeafBoxHost) == sizeof(gpu::LeafBox));
  std::memcpy(out.data(), query_staging_out_.mapped(), bytes);
  return out;
}

// ---- explicit transfers ----------------------------------------------------------------------

HostTree OccupancyMap::Impl::download() {
  const gpu::PoolState pool = readPool();
  HostTree tree;
  tree.root_exists = pool.root_exists != 0;
  const std::size_t count = std::size_t{pool.bump} * 8;
  vk::Buffer staging(device_, count * sizeof(gpu::Node), true);
  stream_.begin(bindings_);
  stream_.copy(nodes_, staging, count * sizeof(gpu::Node));
  stream_.submitAndWait();
  // Device nodes keep a node's existence in the node itself (kFlagLive); the host tree keeps a
  // parent's child bits.
  const auto* nodes = static_cast<const gpu::Node*>(staging.mapped());
  tree.nodes.resize(count);
  for (std::size_t i = 0; i < count; ++i) {
    const std::uint32_t block = nodes[i].link & gpu::kBlockMask;
    HostTree::Node& n = tree.nodes[i];
    n.log_odds = nodes[i].log_odds;
    n.children = gpu::kNoBlock;
    n.mask = 0;
    if (block == gpu::kNoChildren || block >= pool.bump) continue;
    n.children = block;
    for (std::uint32_t s = 0; s < 8; ++s)
      if (nodes[std::size_t{block} * 8 + s].link & gpu::kFlagLive) n.mask |= 1u << s;
  }
  // Free blocks keep stale contents; only what hangs from the root is the tree.
  return tree;
}

void OccupancyMap::Impl::upload(const HostTree& tree) {
  const std::size_t blocks = std::max<std::size_t>((tree.nodes.size() + 7) / 8, 1);
  if (blocks > blockLimit())
    throw Error(ErrorCode::kOutOfDeviceMemory,
                "upload: the tree needs " + std::to_string(blocks * 8) +
                    " pool nodes, over the limit of " + std::to_string(blockLimit() * 8ull) +
                    " (MapParams::max_nodes or 2^32); the map is unchanged");
  std::vector<std::uint32_t> parents(blocks, gpu::kNoBlock);
  std::vector<gpu::Node> nodes(blocks * 8, gpu::Node{0.0f, gpu::kNoChildren});
  std::uint32_t live = 0;
  if (tree.root_exists) {
    if (tree.nodes.empty()) throw Error(ErrorCode::kFormat, "upload: the tree has no root node");
    // Walk from the root: each node that hangs in the tree exists (kFlagLive) and each child
    // block records its parent.
    struct Item {
      std::uint32_t node, depth;
    };
    std::vector<Item> stack{{gpu::kRootNode, 0}};
    while (!stack.empty()) {
      const Item it = stack.back();
      stack.pop_back();
      ++live;
      const HostTree::Node& n = tree.nodes[it.node];
      gpu::Node& g = nodes[it.node];
      g.log_odds = n.log_odds;
      g.link = gpu::kNoChildren | gpu::kFlagLive;
      if ((n.mask & gpu::kChildMask) == 0) continue;
      if (it.depth >= gpu::kTreeDepth)
        throw Error(ErrorCode::kFormat, "upload: the tree has nodes below depth 16");
      if (n.children >= blocks || n.children == 0 ||
          std::size_t{n.children} * 8 + 8 > tree.nodes.size())
        throw Error(ErrorCode::kFormat, "upload: the tree has a child block outside its nodes");
      if (parents[n.children] != gpu::kNoBlock)
        throw Error(ErrorCode::kFormat,
                    "upload: the tree has a child block shared by two nodes (a cycle or a copy)");
      g.link = n.children | gpu::kFlagLive;
      parents[n.children] = it.node;
      for (std::uint32_t s = 0; s < 8; ++s)
        if (n.mask & (1u << s)) stack.push_back({n.children * 8 + s, it.depth + 1});
    }
  }
  // Blocks that nothing points at go onto the free stack.
  std::vector<std::uint32_t> free_blocks;
  for (std::uint32_t b = 1; b < blocks; ++b)
    if (parents[b] == gpu::kNoBlock) free_blocks.push_back(b);

  const std::uint32_t capacity = std::min<std::uint32_t>(
      blockLimit(),
      std::max<std::uint32_t>(static_cast<std::uint32_t>(blocks + blocks / 4), kInitialBlocks));
  if (capacity > pool_blocks_) allocatePool(capacity, /*copy_old=*/false);
  gpu::PoolState pool{};
  pool.bump = static_cast<std::uint32_t>(blocks);
  pool.capacity = pool_blocks_;
  pool.free_count = static_cast<std::uint32_t>(free_blocks.size());
  pool.root_exists = tree.root_exists ? 1u : 0u;
  pool.live_nodes = live;

  const std::size_t node_bytes = nodes.size() * sizeof(gpu::Node);
  const std::size_t meta_bytes = parents.size() * sizeof(std::uint32_t);
  const std::size_t free_bytes = free_blocks.size() * sizeof(std::uint32_t);
  vk::Buffer staging(device_, node_bytes + meta_bytes + free_bytes, true);
  auto* bytes = static_cast<unsigned char*>(staging.mapped());
  std::memcpy(bytes, nodes.data(), node_bytes);
  std::memcpy(bytes + node_bytes, parents.data(), meta_bytes);
  if (free_bytes) std::memcpy(bytes + node_bytes + meta_bytes, free_blocks.data(), free_bytes);
  gpu::ScanParams sp = scanParams(Eigen::Vector3f::Zero(), nullptr, -1.0, 0);
  stream_.begin(bindings_);
  stream_.update(params_buf_, &sp, sizeof(sp));
  stream_.update(pool_buf_, &pool, sizeof(pool));
  stream_.copy(staging, nodes_, node_bytes);
  stream_.copy(staging, block_parents_, meta_bytes, node_bytes);
  stream_.copy(staging, free_stack_, free_bytes, node_bytes + meta_bytes);
  stream_.barrier();
  recordLeafBoxes();
  stream_.submitAndWait();
  leaf_boxes_dirty_ = false;
}

std::vector<OccupancyMap::LeafBoxHost> OccupancyMap::Impl::downloadLeafBoxes() {
  refreshLeafBoxes();
  const gpu::PoolState pool = readPool();
  std::vector<LeafBoxHost> out(pool.leaf_count);
  if (out.empty()) return out;
  const std::size_t bytes = out.size() * sizeof(gpu::LeafBox);
  vk::Buffer staging(device_, bytes, true);
  stream_.begin(bindings_);
  stream_.copy(leaf_boxes_, staging, bytes);
  stream_.submitAndWait();
  static_assert(sizeof(LeafBoxHost) == sizeof(gpu::LeafBox));
  std::memcpy(out.data(), staging.mapped(), bytes);
  return out;
}

// ---- public face -----------------------------------------------------------------------------

OccupancyMap::OccupancyMap(Context& context, const MapParams& params)
    : impl_(std::make_unique<Impl>(context, params)) {}
OccupancyMap::~OccupancyMap() = default;
OccupancyMap::OccupancyMap(OccupancyMap&&) noexcept = default;
OccupancyMap& OccupancyMap::operator=(OccupancyMap&&) noexcept = default;

const MapParams& OccupancyMap::params() const noexcept { return impl_->params(); }

ScanStats OccupancyMap::insertPointCloud(std::span<const Eigen::Vector3f> points_world,
                                         const Eigen::Vector3f& origin_world, double max_range_m,
                                         bool discretize) {
  return impl_->insert(points_world, origin_world, nullptr, max_range_m, discretize);
}

ScanStats OccupancyMap::insertPointCloud(std::span<const Eigen::Vector3f> points_sensor,
                                         const Eigen::Vector3f& origin_sensor,
                                         const Pose& T_world_sensor, double max_range_m,
                                         bool discretize) {
  const Eigen::Vector3f origin_world = T_world_sensor.transform(origin_sensor);
  return impl_->insert(points_sensor, origin_world, &T_world_sensor, max_range_m, discretize);
}

ScanStats OccupancyMap::insertDepthImage(const DepthImage& image, const Pose& T_world_camera,
                                         double max_range_m,
                                         const Eigen::Vector3f& origin_camera, bool discretize) {
  if (std::string why = image.validate(); !why.empty())
    throw Error(ErrorCode::kInvalidArgument, "insertDepthImage: " + why);
  // For now unprojected on the host; the device pass (shaders/unproject.comp) replaces this.
  std::size_t skipped = 0;
  const std::vector<Eigen::Vector3f> points = unprojectDepthImage(image, &skipped);
  ScanStats stats =
      insertPointCloud(points, origin_camera, T_world_camera, max_range_m, discretize);
  stats.skipped_no_depth = skipped;
  stats.points += skipped;
  return stats;
}

ScanStats OccupancyMap::insertPointCloud(std::span<const Eigen::Vector3f> points_world,
                                         const Eigen::Vector3f& origin_world, double max_range_m,
                                         bool discretize, const QueryRequest& queries,
                                         QueryResults& results) {
  return impl_->insert(points_world, origin_world, nullptr, max_range_m, discretize, &queries,
                       &results);
}

std::vector<Lookup> OccupancyMap::search(std::span<const Eigen::Vector3f> points) const {
  return impl_->runQueries({points, {}}).lookups;
}

std::vector<RayHit> OccupancyMap::castRays(std::span<const Ray> rays) const {
  return impl_->runQueries({{}, rays}).rays;
}

std::vector<OccupancyMap::LeafBoxHost> OccupancyMap::leavesInBox(const Eigen::Vector3f& min,
                                                                 const Eigen::Vector3f& max,
                                                                 bool occupied_only) const {
  return impl_->leavesInBox(min, max, occupied_only);
}

std::size_t OccupancyMap::nodeCount() const {
  const gpu::PoolState pool = impl_->readPool();
  return pool.root_exists ? pool.live_nodes : 0;
}

std::size_t OccupancyMap::leafCount() const {
  impl_->refreshLeafBoxes();
  return impl_->readPool().leaf_count;
}

void OccupancyMap::setLeafBoxesEveryScan(bool every_scan) {
  impl_->setLeafBoxesEveryScan(every_scan);
}

std::size_t OccupancyMap::deviceBytes() const { return impl_->deviceBytes(); }

std::size_t OccupancyMap::poolBytes() const { return impl_->poolBytes(); }

HostTree OccupancyMap::download() const { return impl_->download(); }

void OccupancyMap::upload(const HostTree& tree) { impl_->upload(tree); }

std::vector<OccupancyMap::LeafBoxHost> OccupancyMap::downloadLeafBoxes() const {
  return impl_->downloadLeafBoxes();
}

// ---- Vulkan interop (vulkan_interop.hpp) ------------------------------------------------------

class InteropAccess {
 public:
  static OccupancyMap::Impl& impl(OccupancyMap& map) { return *map.impl_; }
};

VulkanHandles vulkanHandles(Context& context) {
  vk::Device& d = context.vulkan();
  return {d.instance(), d.physical(),    d.handle(),
          d.queue(),    d.queueFamily(), d.storageOffsetAlignment()};
}

void searchOnDevice(OccupancyMap& map, BufferRange points, std::uint32_t count,
                    BufferRange results) {
  InteropAccess::impl(map).queryOnDevice(false, points.buffer, points.offset, points.size,
                                         results.buffer, results.offset, results.size, count);
}

std::size_t castRaysResultBytes(std::uint32_t count) {
  // The results, then from the first RayState past them one per ray (recordCastRays).
  return (std::size_t{firstRayState(count)} + count) * sizeof(gpu::RayState);
}

void castRaysOnDevice(OccupancyMap& map, BufferRange rays, std::uint32_t count,
                      BufferRange results) {
  if (results.size != VK_WHOLE_SIZE && results.size < castRaysResultBytes(count))
    throw Error(ErrorCode::kInvalidArgument,
                "castRaysOnDevice: the results range holds " + std::to_string(results.size) +
                    " bytes; castRaysResultBytes(" + std::to_string(count) +
                    ") = " + std::to_string(castRaysResultBytes(count)) + " are needed");
  InteropAccess::impl(map).queryOnDevice(true, rays.buffer, rays.offset, rays.size, results.buffer,
                                         results.offset, results.size, count);
}

}  // namespace octovk
