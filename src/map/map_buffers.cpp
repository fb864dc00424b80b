#include "map/map_buffers.hpp"

#include <algorithm>
#include <array>
#include <cstddef>

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
  return c;
}

MapBuffers::MapBuffers(vk::Device& device, vk::CommandStream& stream, std::uint32_t block_limit)
    : bindings(device), device_(device), stream_(stream), block_limit_(block_limit) {
  params = vk::Buffer(device_, sizeof(gpu::ScanParams), false);
  counters = vk::Buffer(device_, sizeof(gpu::ScanCounters), false);
  pool = vk::Buffer(device_, sizeof(gpu::PoolState), false);
  readback = vk::Buffer(device_, sizeof(gpu::ScanCounters) + sizeof(gpu::PoolState), true);
  ensureQueries(64, 64);
  points = vk::Buffer(device_, 16, false);
  walks = vk::Buffer(device_, 16, false);
  upload = vk::Buffer(device_, 16, true);
  depth = vk::Buffer(device_, 16, false);
  allocateEndpoints(kInitialHashLog2);
  allocateHash(kInitialHashLog2);
  allocateLists(1024);
  allocatePool(std::min<std::uint32_t>(kInitialBlocks, block_limit_), /*copy_old=*/false);
  resetPool();
}

void MapBuffers::allocateHash(std::uint32_t log2) {
  const std::size_t cap = std::size_t{1} << log2;
  const std::size_t cell_cap = cap * kCellsPerBrickSlot;
  vk::Buffer keys(device_, cap * sizeof(std::uint64_t), false);
  vk::Buffer flags(device_, cap * gpu::kBrickFlagWords * sizeof(std::uint32_t), false);
  vk::Buffer list(device_, cell_cap * sizeof(std::uint32_t), false);
  vk::Buffer active(device_, cell_cap * sizeof(gpu::ActiveCell), false);
  hash_keys = std::move(keys);
  hash_flags = std::move(flags);
  cell_list = std::move(list);
  cells = std::move(active);
  hash_log2_ = log2;
  // The second set holds about as many entries as the first (end cells, or new-block prefixes).
  if (endpoint_keys.valid() && endpoint_log2_ < log2) allocateEndpoints(log2);
  allocateSlots();
}

void MapBuffers::allocateEndpoints(std::uint32_t log2) {
  vk::Buffer keys(device_, (std::size_t{1} << log2) * sizeof(std::uint64_t), false);
  vk::Buffer blocks(device_, (std::size_t{1} << log2) * sizeof(gpu::NewBlock), false);
  endpoint_keys = std::move(keys);
  prefix_blocks = std::move(blocks);
  endpoint_log2_ = log2;
  allocateSlots();
}

// The slot lists cover both sets; new sets start unfilled and are cleared whole once.
void MapBuffers::allocateSlots() {
  const std::size_t entries = (std::size_t{1} << hash_log2_) + (std::size_t{1} << endpoint_log2_);
  if (slots.size() < entries * sizeof(std::uint32_t)) {
    vk::Buffer s(device_, entries * sizeof(std::uint32_t), false);
    slots = std::move(s);
  }
  sets_need_fill_ = true;
  rebind();
}

void MapBuffers::allocateLists(std::size_t active_capacity) {
  vk::Buffer t(device_, active_capacity * gpu::kTreeDepth * sizeof(std::uint32_t), false);
  touched = std::move(t);
  active_capacity_ = active_capacity;
  rebind();
}

void MapBuffers::allocatePool(std::uint32_t blocks, bool copy_old) {
  vk::Buffer new_nodes(device_, std::size_t{blocks} * 8 * sizeof(gpu::Node), false);
  vk::Buffer parents(device_, std::size_t{blocks} * sizeof(std::uint32_t), false);
  vk::Buffer stack(device_, std::size_t{blocks} * sizeof(std::uint32_t), false);
  vk::Buffer leaves(device_, std::size_t{blocks} * 8 * sizeof(gpu::LeafBox), false);
  if (copy_old) {
    stream_.begin(bindings);
    stream_.copy(nodes, new_nodes, nodes.size());
    stream_.copy(block_parents, parents, block_parents.size());
    stream_.copy(free_stack, stack, free_stack.size());
    stream_.copy(leaf_boxes, leaves, leaf_boxes.size());  // as they were: a rebuild may not follow
    stream_.update(pool, &blocks, sizeof(blocks), offsetof(gpu::PoolState, capacity));
    stream_.submitAndWait();
  }
  nodes = std::move(new_nodes);
  block_parents = std::move(parents);
  free_stack = std::move(stack);
  leaf_boxes = std::move(leaves);
  pool_blocks_ = blocks;
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
  const std::size_t cap = std::max(count, point_capacity_ * 2);
  vk::Buffer device_points(device_, cap * 3 * sizeof(float), false);
  vk::Buffer staging(device_, cap * 3 * sizeof(float), true);
  vk::Buffer walk_lists(device_, 2 * cap * sizeof(gpu::WalkState), false);
  points = std::move(device_points);
  upload = std::move(staging);
  walks = std::move(walk_lists);
  point_capacity_ = cap;
  rebind();
}

void MapBuffers::ensureDepth(std::size_t bytes) {
  if (depth.size() < bytes) {
    vk::Buffer image(device_, std::max(bytes, depth.size() * 2), false);
    depth = std::move(image);
  }
  if (upload.size() < bytes) {
    vk::Buffer staging(device_, bytes, true);
    upload = std::move(staging);
  }
  rebind();
}

void MapBuffers::ensureQueries(std::size_t in_bytes, std::size_t out_bytes) {
  in_bytes = std::max<std::size_t>(in_bytes, 64);
  out_bytes = std::max<std::size_t>(out_bytes, 64);
  if (query_in.size() < in_bytes) {
    vk::Buffer device_in(device_, in_bytes, false);
    vk::Buffer staging(device_, in_bytes, true);
    query_in = std::move(device_in);
    query_staging_in = std::move(staging);
  }
  if (query_out.size() < out_bytes) {
    vk::Buffer device_out(device_, out_bytes, false);
    vk::Buffer staging(device_, out_bytes, true);
    query_out = std::move(device_out);
    query_staging_out = std::move(staging);
  }
  rebind();
}

void MapBuffers::rebind() {
  if (!nodes.valid() || !hash_keys.valid() || !touched.valid() || !query_in.valid() ||
      !slots.valid())
    return;
  const std::array<const vk::Buffer*, gpu::kBindingCount> buffers = {
      &params,     &counters, &pool,          &points,     &hash_keys,
      &hash_flags, &nodes,    &block_parents, &free_stack, &cells,
      &touched,    &prefix_blocks, &leaf_boxes, &endpoint_keys, &query_in,
      &query_out,  &walks,    &slots,         &cell_list,  &depth};
  bindings.update(buffers);
}

std::size_t MapBuffers::deviceBytes() const {
  std::size_t total = 0;
  for (const vk::Buffer* b :
       {&params, &counters, &pool, &points, &hash_keys, &hash_flags, &cells, &endpoint_keys,
        &touched, &prefix_blocks, &nodes, &block_parents, &free_stack, &leaf_boxes, &query_in,
        &query_out, &walks, &slots, &cell_list, &depth})
    total += b->size();
  return total;
}

}  // namespace octovk
