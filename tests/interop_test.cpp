// Queries on data that already lives in the caller's Vulkan buffers (vulkan_interop.hpp): the
// buffers are made with plain Vulkan on the context's device, as an application would, and the
// answers must equal the host API's (which the query tests compare with OctoMap).
#include <octomap/octomap.h>
#include <unistd.h>

#include <chrono>
#include <cstring>
#include <limits>
#include <random>
#include <thread>

#include "caller_buffer.hpp"
#include "octovk/vulkan_interop.hpp"
#include "test_support.hpp"

namespace octovk {
namespace {

using test::CallerBuffer;

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

namespace octovk {
namespace {

using test::CallerBuffer;

// Scans whose input already lives in a caller's buffer: the same map as the host overloads, and
// octovk reads the buffer only once the caller's timeline semaphore says it is ready.
TEST(Interop, ScansFromCallerBuffersWaitForTheSemaphoreAndEqualTheHostApi) {
  OCTOVK_REQUIRE_CONTEXT(ctx);
  const VulkanHandles vk = vulkanHandles(ctx);
  VkPhysicalDeviceVulkan12Features f12{VK_STRUCTURE_TYPE_PHYSICAL_DEVICE_VULKAN_1_2_FEATURES};
  VkPhysicalDeviceFeatures2 f2{VK_STRUCTURE_TYPE_PHYSICAL_DEVICE_FEATURES_2};
  f2.pNext = &f12;
  vkGetPhysicalDeviceFeatures2(vk.physical_device, &f2);
  ASSERT_TRUE(f12.timelineSemaphore) << "the device has no timeline semaphores";
  VkSemaphoreTypeCreateInfo type{VK_STRUCTURE_TYPE_SEMAPHORE_TYPE_CREATE_INFO};
  type.semaphoreType = VK_SEMAPHORE_TYPE_TIMELINE;
  type.initialValue = 0;
  VkSemaphoreCreateInfo sinfo{VK_STRUCTURE_TYPE_SEMAPHORE_CREATE_INFO};
  sinfo.pNext = &type;
  VkSemaphore ready = VK_NULL_HANDLE;
  ASSERT_EQ(vkCreateSemaphore(vk.device, &sinfo, nullptr, &ready), VK_SUCCESS);

  MapParams params;
  params.resolution = 0.05;
  OccupancyMap on_device(ctx, params), on_host(ctx, params);
  std::mt19937 rng(21);
  Pose pose;
  pose.rotation =
      Eigen::Quaternionf(Eigen::AngleAxisf(0.4f, Eigen::Vector3f(1, 2, 3).normalized()));
  pose.translation = Eigen::Vector3f(0.3f, -0.2f, 0.1f);
  const Eigen::Vector3f origin(0.02f, 0.0f, -0.01f);
  const auto points = test::randomScan(rng, origin, 2000, 3.0f);

  // The buffer holds NaN until the producer thread writes the points and signals value 1: a scan
  // that read it early would insert nothing.
  CallerBuffer buffer(vk, points.size() * sizeof(Eigen::Vector3f));
  std::vector<float> nan(points.size() * 3, std::numeric_limits<float>::quiet_NaN());
  std::memcpy(buffer.data(), nan.data(), nan.size() * sizeof(float));
  std::thread producer([&] {
    std::this_thread::sleep_for(std::chrono::milliseconds(300));
    std::memcpy(buffer.data(), points.data(), points.size() * sizeof(Eigen::Vector3f));
    VkSemaphoreSignalInfo signal{VK_STRUCTURE_TYPE_SEMAPHORE_SIGNAL_INFO};
    signal.semaphore = ready;
    signal.value = 1;
    EXPECT_EQ(vkSignalSemaphore(vk.device, &signal), VK_SUCCESS);
  });
  const ScanStats stats =
      insertPointCloudOnDevice(on_device, buffer.range(), static_cast<std::uint32_t>(points.size()),
                               origin, pose, {.max_range_m = 2.5}, WaitSemaphore{ready, 1});
  producer.join();
  EXPECT_EQ(stats.skipped_nonfinite, 0u) << "the scan read the buffer before it was ready";
  on_host.insertPointCloud(points, origin, pose, {.max_range_m = 2.5});
  ASSERT_TRUE(test::sameTree(*toOcTree(on_host), *toOcTree(on_device)));

  // A depth image in a caller's buffer (odd pixel count: the last word is half used).
  DepthImage image;
  image.width = 33;
  image.height = 25;
  image.fx = image.fy = 30.0f;
  image.cx = 16.0f;
  image.cy = 12.0f;
  std::vector<std::uint16_t> pixels(std::size_t{image.width} * image.height);
  std::uniform_int_distribution<int> d(0, 20000);
  for (auto& p : pixels) p = static_cast<std::uint16_t>(d(rng) < 1000 ? 0 : d(rng));
  CallerBuffer pixel_buffer(vk, pixels.size() * sizeof(std::uint16_t));
  std::memcpy(pixel_buffer.data(), pixels.data(), pixels.size() * sizeof(std::uint16_t));
  const ScanStats depth_stats = insertDepthImageOnDevice(
      on_device, pixel_buffer.range(), image, pose, ScanOptions{}, Eigen::Vector3f::Zero(), {});
  image.depths = std::span<const std::uint16_t>(pixels);
  std::size_t skipped = 0;
  on_host.insertPointCloud(unprojectDepthImage(image, &skipped), Eigen::Vector3f::Zero(), pose);
  EXPECT_EQ(depth_stats.skipped_no_depth, skipped);
  ASSERT_TRUE(test::sameTree(*toOcTree(on_host), *toOcTree(on_device)));

  // Ranges too small for the input are refused; the map stays.
  const std::size_t nodes = on_device.nodeCount();
  BufferRange small = buffer.range();
  small.size = 12;
  EXPECT_THROW(insertPointCloudOnDevice(on_device, small, 2, origin, pose), Error);
  EXPECT_EQ(on_device.nodeCount(), nodes);
  test::idleQueueBeforeDestroyingSemaphores(ctx, vk);
  vkDestroySemaphore(vk.device, ready, nullptr);
}

}  // namespace
}  // namespace octovk

namespace octovk {
namespace {

// The hand-over path a CUDA or PyTorch producer uses: memory allocated exportable on octovk's
// device (opaque fd), its fd exported, the points written into it, the scan read from it. Where
// the device lacks VK_KHR_external_memory_fd, octovk must say so (the flag) rather than claim it.
TEST(Interop, ExportableMemoryHandsPointsOver) {
  OCTOVK_REQUIRE_CONTEXT(ctx);
  const VulkanHandles vk = vulkanHandles(ctx);
  std::uint32_t count = 0;
  vkEnumerateDeviceExtensionProperties(vk.physical_device, nullptr, &count, nullptr);
  std::vector<VkExtensionProperties> extensions(count);
  vkEnumerateDeviceExtensionProperties(vk.physical_device, nullptr, &count, extensions.data());
  bool listed = false;
  for (const auto& e : extensions)
    listed = listed || std::string(e.extensionName) == VK_KHR_EXTERNAL_MEMORY_FD_EXTENSION_NAME;
  ASSERT_EQ(vk.external_memory_fd, listed);
  if (!listed) return;  // asserted above: octovk reports the device cannot export memory

  MapParams params;
  params.resolution = 0.1;
  OccupancyMap from_fd_memory(ctx, params), from_host(ctx, params);
  std::mt19937 rng(5);
  const auto points = test::randomScan(rng, Eigen::Vector3f::Zero(), 1500, 4.0f);
  const VkDeviceSize bytes = points.size() * sizeof(Eigen::Vector3f);

  VkExternalMemoryBufferCreateInfo external{VK_STRUCTURE_TYPE_EXTERNAL_MEMORY_BUFFER_CREATE_INFO};
  external.handleTypes = VK_EXTERNAL_MEMORY_HANDLE_TYPE_OPAQUE_FD_BIT;
  VkBufferCreateInfo info{VK_STRUCTURE_TYPE_BUFFER_CREATE_INFO};
  info.pNext = &external;
  info.size = bytes;
  info.usage = VK_BUFFER_USAGE_STORAGE_BUFFER_BIT | VK_BUFFER_USAGE_TRANSFER_SRC_BIT;
  VkBuffer buffer = VK_NULL_HANDLE;
  ASSERT_EQ(vkCreateBuffer(vk.device, &info, nullptr, &buffer), VK_SUCCESS);
  VkMemoryRequirements req;
  vkGetBufferMemoryRequirements(vk.device, buffer, &req);
  VkPhysicalDeviceMemoryProperties props;
  vkGetPhysicalDeviceMemoryProperties(vk.physical_device, &props);
  const VkMemoryPropertyFlags want =
      VK_MEMORY_PROPERTY_HOST_VISIBLE_BIT | VK_MEMORY_PROPERTY_HOST_COHERENT_BIT;
  std::uint32_t type = 0;
  while (type < props.memoryTypeCount && !((req.memoryTypeBits & (1u << type)) &&
                                           (props.memoryTypes[type].propertyFlags & want) == want))
    ++type;
  ASSERT_LT(type, props.memoryTypeCount);
  VkExportMemoryAllocateInfo export_info{VK_STRUCTURE_TYPE_EXPORT_MEMORY_ALLOCATE_INFO};
  export_info.handleTypes = VK_EXTERNAL_MEMORY_HANDLE_TYPE_OPAQUE_FD_BIT;
  VkMemoryAllocateInfo alloc{VK_STRUCTURE_TYPE_MEMORY_ALLOCATE_INFO};
  alloc.pNext = &export_info;
  alloc.allocationSize = req.size;
  alloc.memoryTypeIndex = type;
  VkDeviceMemory memory = VK_NULL_HANDLE;
  ASSERT_EQ(vkAllocateMemory(vk.device, &alloc, nullptr, &memory), VK_SUCCESS);
  ASSERT_EQ(vkBindBufferMemory(vk.device, buffer, memory, 0), VK_SUCCESS);
  auto get_fd =
      reinterpret_cast<PFN_vkGetMemoryFdKHR>(vkGetDeviceProcAddr(vk.device, "vkGetMemoryFdKHR"));
  ASSERT_NE(get_fd, nullptr) << "VK_KHR_external_memory_fd reported but not enabled";
  VkMemoryGetFdInfoKHR fd_info{VK_STRUCTURE_TYPE_MEMORY_GET_FD_INFO_KHR};
  fd_info.memory = memory;
  fd_info.handleType = VK_EXTERNAL_MEMORY_HANDLE_TYPE_OPAQUE_FD_BIT;
  int fd = -1;
  ASSERT_EQ(get_fd(vk.device, &fd_info, &fd), VK_SUCCESS);
  EXPECT_GE(fd, 0);  // what a CUDA producer would import (cudaImportExternalMemory)
  void* mapped = nullptr;
  ASSERT_EQ(vkMapMemory(vk.device, memory, 0, VK_WHOLE_SIZE, 0, &mapped), VK_SUCCESS);
  std::memcpy(mapped, points.data(), bytes);
  vkUnmapMemory(vk.device, memory);

  insertPointCloudOnDevice(from_fd_memory, {buffer, 0, bytes},
                           static_cast<std::uint32_t>(points.size()), Eigen::Vector3f::Zero(),
                           Pose{});
  from_host.insertPointCloud(points, Eigen::Vector3f::Zero(), Pose{});
  EXPECT_TRUE(test::sameTree(*toOcTree(from_host), *toOcTree(from_fd_memory)));
  if (fd >= 0) close(fd);
  vkDestroyBuffer(vk.device, buffer, nullptr);
  vkFreeMemory(vk.device, memory, nullptr);
}

}  // namespace
}  // namespace octovk
