// Queries on data that already lives in the caller's Vulkan buffers (vulkan_interop.hpp): the
// buffers are made with plain Vulkan on the context's device, as an application would, and the
// answers must equal the host API's (which the query tests compare with OctoMap).
#include <octomap/octomap.h>

#include <cstring>

#include "octovk/vulkan_interop.hpp"
#include "test_support.hpp"

namespace octovk {
namespace {

// A host-visible storage buffer made with the Vulkan API alone.
class CallerBuffer {
 public:
  CallerBuffer(const VulkanHandles& vk, VkDeviceSize bytes) : device_(vk.device) {
    VkBufferCreateInfo info{VK_STRUCTURE_TYPE_BUFFER_CREATE_INFO};
    info.size = bytes;
    info.usage = VK_BUFFER_USAGE_STORAGE_BUFFER_BIT;
    EXPECT_EQ(vkCreateBuffer(device_, &info, nullptr, &buffer_), VK_SUCCESS);
    VkMemoryRequirements req;
    vkGetBufferMemoryRequirements(device_, buffer_, &req);
    VkPhysicalDeviceMemoryProperties props;
    vkGetPhysicalDeviceMemoryProperties(vk.physical_device, &props);
    const VkMemoryPropertyFlags want =
        VK_MEMORY_PROPERTY_HOST_VISIBLE_BIT | VK_MEMORY_PROPERTY_HOST_COHERENT_BIT;
    std::uint32_t type = 0;
    while (type < props.memoryTypeCount &&
           !((req.memoryTypeBits & (1u << type)) &&
             (props.memoryTypes[type].propertyFlags & want) == want))
      ++type;
    VkMemoryAllocateInfo alloc{VK_STRUCTURE_TYPE_MEMORY_ALLOCATE_INFO};
    alloc.allocationSize = req.size;
    alloc.memoryTypeIndex = type;
    EXPECT_EQ(vkAllocateMemory(device_, &alloc, nullptr, &memory_), VK_SUCCESS);
    vkBindBufferMemory(device_, buffer_, memory_, 0);
    vkMapMemory(device_, memory_, 0, VK_WHOLE_SIZE, 0, &mapped_);
  }
  ~CallerBuffer() {
    vkDestroyBuffer(device_, buffer_, nullptr);
    vkFreeMemory(device_, memory_, nullptr);
  }
  CallerBuffer(const CallerBuffer&) = delete;
  CallerBuffer& operator=(const CallerBuffer&) = delete;
  BufferRange range() const { return {buffer_, 0, VK_WHOLE_SIZE}; }
  void* data() const { return mapped_; }

 private:
  VkDevice device_;
  VkBuffer buffer_ = VK_NULL_HANDLE;
  VkDeviceMemory memory_ = VK_NULL_HANDLE;
  void* mapped_ = nullptr;
};

TEST(Interop, QueriesOnCallerBuffersEqualTheHostApi) {
  OCTOVK_REQUIRE_CONTEXT(ctx);
  MapParams params;
  params.resolution = 0.1;
  OccupancyMap map(ctx, params);
  std::mt19937 rng(5);
  map.insertPointCloud(test::randomScan(rng, Eigen::Vector3f::Zero(), 2000, 3.0f),
                       Eigen::Vector3f::Zero());

  std::uniform_real_distribution<float> u(-3.5f, 3.5f);
  std::vector<Eigen::Vector3f> points;
  for (int i = 0; i < 2000; ++i) points.emplace_back(u(rng), u(rng), u(rng));
  std::vector<Ray> rays;
  for (int i = 0; i < 500; ++i)
    rays.push_back({Eigen::Vector3f(0.1f * u(rng), 0.1f * u(rng), 0.0f),
                    Eigen::Vector3f(u(rng), u(rng), u(rng)), i % 3 ? -1.0 : 2.0, i % 2 == 0});

  const VulkanHandles vk = vulkanHandles(ctx);
  ASSERT_NE(vk.device, VK_NULL_HANDLE);
  const auto n_points = static_cast<std::uint32_t>(points.size());
  const auto n_rays = static_cast<std::uint32_t>(rays.size());

  CallerBuffer point_buf(vk, n_points * 12), lookup_buf(vk, n_points * sizeof(gpu::LookupResult));
  std::memcpy(point_buf.data(), points.data(), n_points * 12);
  searchOnDevice(map, point_buf.range(), n_points, lookup_buf.range());
  const auto want_lookups = map.search(points);
  const auto* got_lookups = static_cast<const gpu::LookupResult*>(lookup_buf.data());
  std::size_t known = 0;
  for (std::uint32_t i = 0; i < n_points; ++i) {
    EXPECT_EQ(got_lookups[i].state, static_cast<std::uint32_t>(want_lookups[i].state)) << i;
    EXPECT_EQ(got_lookups[i].log_odds, want_lookups[i].log_odds) << i;
    known += want_lookups[i].state != CellState::kUnknown;
  }
  EXPECT_GT(known, 100u);

  CallerBuffer ray_buf(vk, n_rays * sizeof(gpu::RayQuery)),
      hit_buf(vk, castRaysResultBytes(n_rays));
  auto* queries = static_cast<gpu::RayQuery*>(ray_buf.data());
  for (std::uint32_t i = 0; i < n_rays; ++i) {
    queries[i] = {};
    queries[i].max_range = rays[i].max_range_m;
    queries[i].origin_x = rays[i].origin.x();
    queries[i].origin_y = rays[i].origin.y();
    queries[i].origin_z = rays[i].origin.z();
    queries[i].direction_x = rays[i].direction.x();
    queries[i].direction_y = rays[i].direction.y();
    queries[i].direction_z = rays[i].direction.z();
    queries[i].ignore_unknown = rays[i].ignore_unknown ? 1u : 0u;
  }
  castRaysOnDevice(map, ray_buf.range(), n_rays, hit_buf.range());
  const auto want_hits = map.castRays(rays);
  const auto* got_hits = static_cast<const gpu::RayResult*>(hit_buf.data());
  std::size_t hits = 0;
  for (std::uint32_t i = 0; i < n_rays; ++i) {
    EXPECT_EQ(got_hits[i].hit != 0, want_hits[i].hit) << i;
    EXPECT_EQ(got_hits[i].end_x, want_hits[i].end.x()) << i;
    EXPECT_EQ(got_hits[i].end_y, want_hits[i].end.y()) << i;
    EXPECT_EQ(got_hits[i].end_z, want_hits[i].end.z()) << i;
    hits += want_hits[i].hit;
  }
  EXPECT_GT(hits, 10u);

  // The map's own query buffers are bound again afterwards.
  EXPECT_EQ(map.search(points).size(), points.size());
  // Too small a result range is refused before any work.
  try {
    castRaysOnDevice(map, ray_buf.range(), n_rays, {hit_buf.range().buffer, 0, 16});
    FAIL() << "a too small result range was accepted";
  } catch (const Error& e) {
    EXPECT_EQ(e.code(), ErrorCode::kInvalidArgument);
  }
}

}  // namespace
}  // namespace octovk
