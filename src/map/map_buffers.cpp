#include "map/map_buffers.hpp"

#include <algorithm>
#include <array>
#include <cstddef>
#include <cstdio>
#include <limits>
#include <string>
#include <utility>
#include <vector>

#include "map/buffer_sizes.hpp"
#include "map/walk_budget.hpp"

namespace octovk {

std::uint32_t nextPow2Log2(std::size_t n) {
  std::uint32_t log2 = 0;
  while ((std::size_t{1} << log2) < n) ++log2;
  return log2;
}

gpu::ScanCounters freshCounters() {
  gpu::ScanCounters c{};
  for (auto& a : c.touched_args) a = {0, 1, 1};
  for (auto& a : c.walk_args) a = {0, 1, 1};
  c.cell_args = {0, 1, 1};
  c.brick_args = {0, 1, 1};
  c.block_args = {0, 1, 1};
  c.active_args = {0, 1, 1};
  c.clear_args = {0, 1, 1};
  return c;
}

using namespace sizes;

namespace {

std::string mib(std::size_t bytes) {
  char text[64];
  std::snprintf(text, sizeof(text), "%zu bytes (%.1f MiB)", bytes,
                static_cast<double>(bytes) / (1024.0 * 1024.0));
  return text;
}

}  // namespace

MapBuffers::MapBuffers(vk::Device& device, vk::CommandStream& stream, std::uint32_t block_limit,
                       std::size_t max_bytes, Payload payload_kind)
    : bindings(device),
      device_(device),
      stream_(stream),
      block_limit_(block_limit),
      max_bytes_(max_bytes),
      payload_kind_(payload_kind) {
  // MapParams::validate refuses a cap below initialBytes(); the checks below hold it anyway.
  params = vk::Buffer(device_, sizeof(gpu::ScanParams), false);
  counters = vk::Buffer(device_, sizeof(gpu::ScanCounters), false);
  pool = vk::Buffer(device_, sizeof(gpu::PoolState), false);
  readback = vk::Buffer(device_, kFramesInFlight * kReadbackBytes, true);
  ensureQueries(kSmallQuery, kSmallQuery);
  points = vk::Buffer(device_, kSmallBuffer, false);
  walks = vk::Buffer(device_, kSmallBuffer, false);
  uploads.resize(kFramesInFlight);
  for (vk::Buffer& u : uploads) u = vk::Buffer(device_, kSmallBuffer, true);
  depth = vk::Buffer(device_, kSmallBuffer, false);
  color_fold = vk::Buffer(device_, kSmallBuffer, false);
  allocateSets(kInitialHashLog2, kInitialHashLog2, /*exact_slots=*/true);
  allocateLists(kInitialListEntries);
  allocatePool(std::min<std::uint32_t>(kInitialBlocks, block_limit_), /*copy_old=*/false);
  (void)replaceChanges(0);  // the last buffer: binds them all
  resetPool();
}

BufferBytes MapBuffers::bytesByUse() const {
  BufferBytes b;
  b.pool = poolBytes();
  b.leaf_boxes = leaf_boxes.size();
  b.queries = query_in.size() + query_out.size() + query_staging_in.size() +
              query_staging_out.size() + scene_bytes_;
  for (const vk::Buffer* x :
       {&params, &counters, &pool, &readback, &points, &walks, &depth, &color_fold, &cell_set_keys,
        &cell_set_flags, &cell_list, &cells, &endpoint_keys, &prefix_blocks, &slots, &touched})
    b.scratch += x->size();
  b.scratch += uploadBytes();
  b.changes = changes.size();
  b.fields = field_bytes_;
  return b;
}

bool MapBuffers::fits(std::size_t freed, std::size_t added) const {
  return max_bytes_ == 0 || deviceBytes() - freed + added <= max_bytes_;
}

void MapBuffers::checkBudget(std::size_t freed, std::size_t added, const std::string& what) const {
  if (fits(freed, added)) return;
  const BufferBytes b = bytesByUse();
  throw BudgetError(
      "the map's device-memory cap (MapParams::max_device_bytes = " + mib(max_bytes_) +
      ") does not allow " + what + ": the map would hold " + mib(b.total() - freed + added) +
      "; it holds " + mib(b.total()) + " (node pool " + mib(b.pool) + ", leaf boxes " +
      mib(b.leaf_boxes) + ", scan scratch " + mib(b.scratch) + ", query buffers " +
      mib(b.queries - scene_bytes_) + ", acceleration structures " + mib(scene_bytes_) +
      ", change set " + mib(b.changes) + ", distance fields " + mib(b.fields) +
      "); the map is unchanged. Raise max_device_bytes, split the scan or the "
      "query batch into smaller ones, or call OccupancyMap::trim() to release scratch");
}

void MapBuffers::setsDelta(std::uint32_t hash_log2, std::uint32_t endpoint_log2, bool exact_slots,
                           std::size_t& freed, std::size_t& added) const {
  freed = added = 0;
  if (!cell_set_keys.valid() || hash_log2 != hash_log2_) {
    freed += cell_set_keys.size() + cell_set_flags.size() + cell_list.size() + cells.size();
    added += brickBytes(hash_log2) + cellBytes(cellEntriesFor(hash_log2));
  }
  if (!endpoint_keys.valid() || endpoint_log2 != endpoint_log2_) {
    freed += endpoint_keys.size() + prefix_blocks.size();
    added += endpointBytes(endpoint_log2);
  }
  const std::size_t s = slotBytes(hash_log2, endpoint_log2);
  if (slots.size() < s || (exact_slots && slots.size() != s)) {
    freed += slots.size();
    added += s;
  }
}

void MapBuffers::allocateSets(std::uint32_t hash_log2, std::uint32_t endpoint_log2,
                              bool exact_slots) {
  std::size_t freed = 0, added = 0;
  setsDelta(hash_log2, endpoint_log2, exact_slots, freed, added);
  checkBudget(freed, added,
              "growing the scan's cell sets to 2^" + std::to_string(hash_log2) + " and 2^" +
                  std::to_string(endpoint_log2) + " slots");
  const bool new_hash = !cell_set_keys.valid() || hash_log2 != hash_log2_;
  const bool new_endpoints = !endpoint_keys.valid() || endpoint_log2 != endpoint_log2_;
  const std::size_t slot_bytes = slotBytes(hash_log2, endpoint_log2);
  const bool new_slots = slots.size() < slot_bytes || (exact_slots && slots.size() != slot_bytes);
  vk::Buffer keys, flags, list, active, end_keys, blocks, s;
  const std::size_t cell_cap = cellEntriesFor(hash_log2);
  if (new_hash) {
    const std::size_t cap = std::size_t{1} << hash_log2;
    keys = vk::Buffer(device_, cap * sizeof(std::uint64_t), false);
    flags = vk::Buffer(device_, cap * gpu::kBrickFlagWords * sizeof(std::uint32_t), false);
    list = vk::Buffer(device_, cell_cap * sizeof(std::uint32_t), false);
    active = vk::Buffer(device_, cell_cap * sizeof(gpu::ActiveCell), false);
  }
  if (new_endpoints) {
    end_keys =
        vk::Buffer(device_, (std::size_t{1} << endpoint_log2) * sizeof(std::uint64_t), false);
    blocks = vk::Buffer(device_, (std::size_t{1} << endpoint_log2) * sizeof(gpu::NewBlock), false);
  }
  if (new_slots) s = vk::Buffer(device_, slot_bytes, false);
  // All made: nothing below throws.
  if (new_hash) {
    cell_set_keys = std::move(keys);
    cell_set_flags = std::move(flags);
    cell_list = std::move(list);
    cells = std::move(active);
    cell_entries_ = cell_cap;
    hash_log2_ = hash_log2;
  }
  if (new_endpoints) {
    endpoint_keys = std::move(end_keys);
    prefix_blocks = std::move(blocks);
    endpoint_log2_ = endpoint_log2;
  }
  if (new_slots) slots = std::move(s);
  // New sets start unfilled and are cleared whole once.
  sets_need_fill_ = true;
  rebind();
}

std::size_t MapBuffers::cellEntriesFor(std::uint32_t hash_log2) const noexcept {
  const std::size_t made = (std::size_t{1} << hash_log2) * kCellsPerBrickSlot;
  // A set grown keeps cell lists lengthened before (allocateCells); a set made smaller does not.
  return hash_log2 > hash_log2_ ? std::max(made, cell_entries_) : made;
}

void MapBuffers::allocateCells(std::size_t entries) {
  const std::size_t limit = std::size_t{0xFFFFFFFFu};  // ScanParams::cell_capacity
  entries = std::min(entries, limit);
  if (entries <= cell_entries_) return;
  checkBudget(cell_list.size() + cells.size(), cellBytes(entries),
              "lengthening the scan's cell lists to " + std::to_string(entries) + " cells");
  vk::Buffer list(device_, entries * sizeof(std::uint32_t), false);
  vk::Buffer active(device_, entries * sizeof(gpu::ActiveCell), false);
  cell_list = std::move(list);
  cells = std::move(active);
  cell_entries_ = entries;
  rebind();
}

// The second set holds about as many entries as the first (end cells, or new-block prefixes).
void MapBuffers::allocateHash(std::uint32_t log2) {
  allocateSets(log2, std::max(endpoint_log2_, log2), /*exact_slots=*/false);
}

// Under a cap the guess may take at most half of it, so that it does not crowd out what the
// scan needs for sure (lists, pool); the ray pass grows the sets on demand beyond that.
void MapBuffers::growHashToward(std::uint32_t log2) {
  for (; log2 > hash_log2_; --log2) {
    std::size_t freed = 0, added = 0;
    setsDelta(log2, std::max(endpoint_log2_, log2), false, freed, added);
    if (max_bytes_ == 0 || deviceBytes() - freed + added <= max_bytes_ / 2) {
      allocateHash(log2);
      return;
    }
  }
}

void MapBuffers::allocateEndpoints(std::uint32_t log2) {
  allocateSets(hash_log2_, log2, /*exact_slots=*/false);
}

void MapBuffers::allocateLists(std::size_t entries, std::size_t keep_entries) {
  checkBudget(touched.size(), listBytes(entries),
              "growing the scan's touched lists to " + std::to_string(entries) + " entries");
  vk::Buffer t(device_, listBytes(entries), false);
  if (keep_entries > 0 && keep_entries <= std::min(entries, list_entries_) && touched.valid()) {
    // The last scan's lists stay its own (the store's capture reads them): the same offsets.
    stream_.begin(bindings);
    stream_.copy(touched, t, keep_entries * sizeof(std::uint32_t));
    stream_.submitAndWait();
  } else {
    ++lists_generation_;
  }
  touched = std::move(t);
  list_entries_ = entries;
  rebind();
}

void MapBuffers::allocatePool(std::uint32_t blocks, bool copy_old) {
  allocatePoolAtLeast(blocks, 0, copy_old);
}

void MapBuffers::allocatePoolAtLeast(std::uint32_t blocks, std::uint32_t min_blocks,
                                     bool copy_old) {
  if (copy_old && blocks < pool_blocks_) blocks = pool_blocks_;  // never smaller than the tree
  const bool with_payload = payload_kind_ != Payload::kNone;
  const auto [block_bytes, held, small] = poolBytesNow();
  if (min_blocks > 0 && min_blocks < blocks &&
      !fits(held, std::size_t{blocks} * block_bytes + small)) {
    // The most blocks the cap leaves room for, if that is enough.
    const std::size_t room = poolBlocksWithinCap();
    if (room >= min_blocks)
      blocks = static_cast<std::uint32_t>(std::min<std::size_t>(room, blocks));
  }
  checkBudget(held, std::size_t{blocks} * block_bytes + small,
              "growing the node pool to " + std::to_string(std::size_t{blocks} * 8) + " nodes (" +
                  std::to_string(block_bytes) + " bytes per block of 8" +
                  (leaf_boxes_on_ ? ", with their leaf boxes" : "") + ")");
  vk::Buffer new_nodes(device_, std::size_t{blocks} * 8 * sizeof(gpu::Node), false);
  vk::Buffer parents(device_, std::size_t{blocks} * sizeof(std::uint32_t), false);
  vk::Buffer stack(device_, std::size_t{blocks} * sizeof(std::uint32_t), false);
  vk::Buffer leaves(device_,
                    leaf_boxes_on_ ? std::size_t{blocks} * 8 * sizeof(gpu::LeafBox) : kSmallBuffer,
                    false);
  vk::Buffer words(device_,
                   with_payload ? std::size_t{blocks} * 8 * sizeof(std::uint32_t) : kSmallBuffer,
                   false);
  if (copy_old) {
    stream_.begin(bindings);
    stream_.copy(nodes, new_nodes, nodes.size());
    stream_.copy(block_parents, parents, block_parents.size());
    stream_.copy(free_stack, stack, free_stack.size());
    if (leaf_boxes_on_)  // as they were: a rebuild may not follow
      stream_.copy(leaf_boxes, leaves, leaf_boxes.size());
    if (with_payload && payload.valid()) stream_.copy(payload, words, payload.size());
    stream_.update(pool, &blocks, sizeof(blocks), offsetof(gpu::PoolState, capacity));
    stream_.submitAndWait();
  }
  nodes = std::move(new_nodes);
  block_parents = std::move(parents);
  free_stack = std::move(stack);
  leaf_boxes = std::move(leaves);
  payload = std::move(words);
  pool_blocks_ = blocks;
  rebind();
}

MapBuffers::PoolBytes MapBuffers::poolBytesNow() const {
  const bool with_payload = payload_kind_ != Payload::kNone;
  return {.block = blockBytes(with_payload, leaf_boxes_on_),
          .held = nodes.size() + block_parents.size() + free_stack.size() + leaf_boxes.size() +
                  payload.size(),
          // A map without leaf boxes or payload holds a small buffer in their place.
          .small = (leaf_boxes_on_ ? 0 : kSmallBuffer) + (with_payload ? 0 : kSmallBuffer)};
}

std::size_t MapBuffers::poolBlocksWithinCap() const {
  if (max_bytes_ == 0) return std::numeric_limits<std::size_t>::max();
  const PoolBytes pool_bytes = poolBytesNow();
  const std::size_t others = deviceBytes() - pool_bytes.held + pool_bytes.small;
  return max_bytes_ > others ? (max_bytes_ - others) / pool_bytes.block : 0;
}

bool MapBuffers::ensureLeafBoxes() {
  if (leaf_boxes_on_) return false;
  const std::size_t bytes = std::size_t{pool_blocks_} * 8 * sizeof(gpu::LeafBox);
  checkBudget(leaf_boxes.size(), bytes,
              "making the map's leaf boxes (" + std::to_string(std::size_t{pool_blocks_} * 8) +
                  " of 20 bytes, one per node slot: what leafCount, downloadLeafBoxes, castRay "
                  "through ray tracing and the map edits use)");
  vk::Buffer leaves(device_, bytes, false);
  leaf_boxes = std::move(leaves);
  leaf_boxes_on_ = true;
  rebind();
  return true;
}

bool MapBuffers::releaseSetsAndLists(std::size_t keep_list_entries) {
  const std::size_t before = deviceBytes();
  allocateSets(kInitialHashLog2, kInitialHashLog2, /*exact_slots=*/true);
  if (list_entries_ != kInitialListEntries) allocateLists(kInitialListEntries, keep_list_entries);
  return deviceBytes() < before;
}

void MapBuffers::releaseScratch(std::size_t keep_list_entries, std::size_t keep_fold_at,
                                std::size_t keep_fold_bytes) {
  // Smaller buffers: these fit whatever the cap.
  releaseSetsAndLists(keep_list_entries);
  if (point_capacity_ > 0 || uploadBytes() != kFramesInFlight * kSmallBuffer ||
      depth.size() != kSmallBuffer) {
    vk::Buffer p(device_, kSmallBuffer, false), w(device_, kSmallBuffer, false);
    vk::Buffer d(device_, kSmallBuffer, false);
    vk::Buffer f(device_, std::max(kSmallBuffer, keep_fold_bytes), false);
    if (keep_fold_bytes) {  // no scan is in flight
      stream_.begin(bindings);
      stream_.copy(color_fold, f, keep_fold_bytes, keep_fold_at);
      stream_.submitAndWait();
    }
    std::vector<vk::Buffer> u(kFramesInFlight);
    for (vk::Buffer& x : u) x = vk::Buffer(device_, kSmallBuffer, true);
    points = std::move(p);
    walks = std::move(w);
    walk_capacity_ = 0;
    uploads = std::move(u);
    depth = std::move(d);
    color_fold = std::move(f);
    ++fold_generation_;
    point_capacity_ = 0;
    rebind();
  }
}

void MapBuffers::releaseQueries() {
  if (query_in.size() == kSmallQuery && query_out.size() == kSmallQuery &&
      query_staging_in.size() == kSmallQuery && query_staging_out.size() == kSmallQuery)
    return;
  vk::Buffer in(device_, kSmallQuery, false), staging_in(device_, kSmallQuery, true);
  vk::Buffer out(device_, kSmallQuery, false), staging_out(device_, kSmallQuery, true);
  query_in = std::move(in);
  query_staging_in = std::move(staging_in);
  query_out = std::move(out);
  query_staging_out = std::move(staging_out);
  rebind();
}

void MapBuffers::resetPool() {
  gpu::PoolState state{};
  state.bump = 1;  // block 0 is the root's
  state.capacity = pool_blocks_;
  const gpu::ScanCounters fresh = freshCounters();
  stream_.begin(bindings);
  stream_.update(pool, &state, sizeof(state));
  stream_.update(counters, &fresh, sizeof(fresh));
  stream_.submitAndWait();
}

void MapBuffers::ensurePoints(std::size_t count) {
  if (count <= point_capacity_) return;
  const bool colors = payload_kind_ == Payload::kColor;
  // Walks are saved between rounds only where the device ends loops early (walk_budget.hpp):
  // elsewhere every ray is walked in one go and the lists stay unused. They start short and
  // grow when a scan leaves more walks unfinished (ensureWalks).
  const bool new_walks = device_.loopLimit() != 0 && walk_capacity_ < kInitialWalkEntries;
  const std::size_t walk_bytes = new_walks ? walkBytes(kInitialWalkEntries) : 0;
  const std::size_t held =
      points.size() + uploadBytes() + (new_walks ? walks.size() : 0) + color_fold.size();
  // A colour map's staging holds each point's colour after the points, and its fold buffer the
  // colours, links and table.
  const auto bytesFor = [&](std::size_t n) {
    return pointBytes(n) + (colors ? n * 2 * sizeof(std::uint32_t) * kFramesInFlight +
                                         colorFoldBytes(n, colorChunk())
                                   : 0);
  };
  std::size_t cap = std::max(count, point_capacity_ * 2);
  if (!fits(held, bytesFor(cap) + walk_bytes))
    cap = count;  // no headroom where the cap allows none
  checkBudget(held, bytesFor(cap) + walk_bytes,
              "taking a scan of " + std::to_string(count) + " points (" +
                  std::to_string(bytesFor(1)) + " bytes per point: points, staging" +
                  (colors ? ", colours" : "") + ")" +
                  (new_walks ? " and " + std::to_string(walk_bytes) + " bytes of saved ray walks"
                             : std::string()));
  vk::Buffer device_points(device_, cap * 3 * sizeof(float), false);
  std::vector<vk::Buffer> staging(kFramesInFlight);
  for (vk::Buffer& x : staging) x = vk::Buffer(device_, cap * stagingBytesPerPoint(), true);
  vk::Buffer walk_lists;
  if (new_walks) walk_lists = vk::Buffer(device_, walk_bytes, false);
  vk::Buffer fold(device_, colors ? colorFoldBytes(cap, colorChunk()) : kSmallBuffer, false);
  color_fold = std::move(fold);
  ++fold_generation_;
  points = std::move(device_points);
  uploads = std::move(staging);
  if (new_walks) {
    walks = std::move(walk_lists);
    walk_capacity_ = kInitialWalkEntries;
  }
  point_capacity_ = cap;
  rebind();
}

void MapBuffers::ensureWalks(std::size_t entries) {
  if (device_.loopLimit() == 0 || entries <= walk_capacity_) return;
  checkBudget(walks.size(), walkBytes(entries),
              "saving " + std::to_string(entries) +
                  " unfinished ray walks between rounds (the device ends shader loops early; " +
                  std::to_string(walkBytes(1)) + " bytes per walk)");
  vk::Buffer lists(device_, walkBytes(entries), false);
  walks = std::move(lists);
  walk_capacity_ = entries;
  rebind();
}

std::size_t MapBuffers::colorChunk() const noexcept { return colorFoldChunk(device_); }

void MapBuffers::ensureDepth(std::size_t bytes) {
  const bool grow_depth = depth.size() < bytes, grow_upload = uploads[0].size() < bytes;
  std::size_t depth_bytes = grow_depth ? std::max(bytes, depth.size() * 2) : depth.size();
  const std::size_t freed = (grow_depth ? depth.size() : 0) + (grow_upload ? uploadBytes() : 0);
  const std::size_t upload_add = grow_upload ? kFramesInFlight * bytes : 0;
  if (grow_depth && !fits(freed, depth_bytes + upload_add)) depth_bytes = bytes;
  checkBudget(freed, (grow_depth ? depth_bytes : 0) + upload_add,
              "taking a depth image of " + std::to_string(bytes) +
                  " bytes (device copy and upload staging)");
  vk::Buffer image;
  std::vector<vk::Buffer> staging;
  if (grow_depth) image = vk::Buffer(device_, depth_bytes, false);
  if (grow_upload) {
    staging.resize(kFramesInFlight);
    for (vk::Buffer& x : staging) x = vk::Buffer(device_, bytes, true);
  }
  if (grow_depth) depth = std::move(image);
  if (grow_upload) uploads = std::move(staging);
  rebind();
}

void MapBuffers::ensureQueries(std::size_t in_bytes, std::size_t out_bytes) {
  in_bytes = std::max<std::size_t>(in_bytes, kSmallQuery);
  out_bytes = std::max<std::size_t>(out_bytes, kSmallQuery);
  // Both are bound by descriptor: a size no binding may hold is refused before anything grows,
  // so the map's bindings stay valid (QueryRunner splits its batches to stay within it).
  const std::uint64_t binding = device_.maxBindingBytes();
  if (in_bytes > binding || out_bytes > binding)
    throw Error(ErrorCode::kInvalidArgument,
                "queries need " + std::to_string(std::max(in_bytes, out_bytes)) +
                    " bytes in one buffer binding, more than this device binds (" +
                    std::to_string(binding) + " bytes, maxStorageBufferRange); split the request");
  const bool grow_in = query_in.size() < in_bytes, grow_out = query_out.size() < out_bytes;
  checkBudget((grow_in ? query_in.size() + query_staging_in.size() : 0) +
                  (grow_out ? query_out.size() + query_staging_out.size() : 0),
              (grow_in ? 2 * in_bytes : 0) + (grow_out ? 2 * out_bytes : 0),
              "growing the query buffers to " + std::to_string(in_bytes) + " bytes in and " +
                  std::to_string(out_bytes) + " bytes out (each with its staging)");
  vk::Buffer device_in, staging_in, device_out, staging_out;
  if (grow_in) {
    device_in = vk::Buffer(device_, in_bytes, false);
    staging_in = vk::Buffer(device_, in_bytes, true);
  }
  if (grow_out) {
    device_out = vk::Buffer(device_, out_bytes, false);
    staging_out = vk::Buffer(device_, out_bytes, true);
  }
  if (grow_in) {
    query_in = std::move(device_in);
    query_staging_in = std::move(staging_in);
  }
  if (grow_out) {
    query_out = std::move(device_out);
    query_staging_out = std::move(staging_out);
  }
  rebind();
}

void MapBuffers::rebind() {
  if (!nodes.valid() || !cell_set_keys.valid() || !touched.valid() || !query_in.valid() ||
      !slots.valid() || !changes.valid() || !payload.valid() || !color_fold.valid())
    return;
  const std::array<const vk::Buffer*, gpu::kBindingCount> buffers = {
      &params,     &counters,      &pool,       &points,    &cell_set_keys, &cell_set_flags,
      &nodes,      &block_parents, &free_stack, &cells,     &touched,       &prefix_blocks,
      &leaf_boxes, &endpoint_keys, &query_in,   &query_out, &walks,         &slots,
      &cell_list,  &depth,         &changes,    &payload,   &color_fold};
  bindings.update(buffers);
}

vk::Buffer MapBuffers::replaceChanges(std::uint32_t log2) {
  const std::size_t bytes = changesBytes(log2);
  checkBudget(changes.size(), bytes,
              "growing the change set to 2^" + std::to_string(log2) + " keys");
  vk::Buffer fresh(device_, bytes, false);
  std::swap(changes, fresh);
  const std::uint32_t old_log2 = std::exchange(changes_log2_, log2);
  rebind();
  try {
    stream_.begin(bindings);
    recordEmptyChanges();
    stream_.submitAndWait();
  } catch (...) {  // the old set stays, as before the call
    std::swap(changes, fresh);
    changes_log2_ = old_log2;
    rebind();
    throw;
  }
  return fresh;
}

void MapBuffers::recordEmptyChanges() {
  stream_.fill(changes, 0xFFFFFFFFu);
  stream_.barrier();
  stream_.fill(changes, 0u, 0, sizeof(gpu::ChangeHeader));
  stream_.barrier();
}

void MapBuffers::resetChanges() {
  stream_.begin(bindings);
  recordEmptyChanges();
  stream_.submitAndWait();
}

void MapBuffers::restoreChanges(vk::Buffer old, std::uint32_t log2) {
  changes = std::move(old);
  changes_log2_ = log2;
  rebind();
}

}  // namespace octovk
