// What a scan inserts (points or a depth image, from the host or from a caller's device buffer),
// its checks, and how it reaches the device: written into a frame's upload staging, or read
// from the caller's buffer.
#pragma once

#include <cstddef>
#include <cstdint>
#include <span>

#include "map/map_buffers.hpp"
#include "map/passes/passes.hpp"
#include "octovk/octovk.hpp"
#include "vk/device.hpp"

namespace octovk {

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

/// Throws kInvalidArgument naming the first bad input of a scan of `count` points on `device`.
void checkScan(const vk::Device& device, std::size_t count, const Eigen::Vector3f& origin,
               const Pose* pose, const ScanOptions& options);
/// Throws kInvalidArgument where a scan's colours do not fit the map (no colour payload, a count
/// other than the points', a fold the device does not do).
void checkPayloadOptions(Payload payload, std::size_t count, const ScanOptions& options);
/// Bytes of depth-image buffer a scan needs (DepthCamera and whole words of pixels); 0 for
/// points.
std::size_t depthBytesOf(const ScanSource& source);
/// An upper bound of the DDA steps of the scan's longest ray: from the host's points or pixels,
/// or unbounded for a caller's device buffer.
double worstSteps(const ScanSource& source, const Eigen::Vector3f& origin_world, const Pose* pose,
                  double max_range, double resolution);
/// Where the ray pass reads the scan's input: `upload` (a frame's staging), after writing the
/// host's points or pixels into it, or the caller's buffer.
passes::RayKeysInput stage(const ScanSource& source, vk::Buffer& upload);
/// Writes a colour scan's colours (packed words) into `upload` after what stage() put there
/// (`input`), and returns their offset.
VkDeviceSize stageColors(const ScanSource& source, const passes::RayKeysInput& input,
                         std::span<const Rgb> colors, vk::Buffer& upload);

}  // namespace octovk
