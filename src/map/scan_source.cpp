#include "map/scan_source.hpp"

#include <algorithm>
#include <cmath>
#include <cstring>
#include <string>
#include <type_traits>
#include <variant>

#include "gpu/gpu_types.h"

namespace octovk {

namespace {

// A depth image's pixel bytes, and those rounded up to whole words (the shader reads words):
// what `stage` copies and what the growth policy makes room for.
std::size_t pixelBytes(const ScanSource& source) {
  return source.count() * (source.depth->encoding == DepthImage::Encoding::kUint16 ? 2 : 4);
}
std::size_t wholeWords(std::size_t bytes) { return (bytes + 3) & ~std::size_t{3}; }

}  // namespace

void checkScan(const vk::Device& device, std::size_t count, const Eigen::Vector3f& origin,
               const Pose* pose, const ScanOptions& options) {
  if (!origin.allFinite())
    throw Error(ErrorCode::kInvalidArgument,
                "insertPointCloud: the sensor origin is not finite (NaN or inf); pass the "
                "sensor position in metres");
  if (pose && (!pose->translation.allFinite() || !pose->rotation.coeffs().allFinite()))
    throw Error(ErrorCode::kInvalidArgument,
                "insertPointCloud: the sensor pose is not finite (NaN or inf)");
  if (std::isnan(options.max_range_m))
    throw Error(ErrorCode::kInvalidArgument,
                "insertPointCloud: max_range is NaN; use a negative value for unlimited range");
  // Lists of points and cells are walked by indirect dispatches of one group per 64 entries.
  const std::size_t max_items =
      std::min<std::size_t>(0x7FFFFFFFu, std::size_t{device.maxGroupsX()} * gpu::kWorkgroupSize);
  if (count > max_items)
    throw Error(ErrorCode::kInvalidArgument,
                "insertPointCloud: " + std::to_string(count) + " points in one scan; the device '" +
                    device.info().name + "' takes at most " + std::to_string(max_items) +
                    " (maxComputeWorkGroupCount x 64); split the scan");
}

void checkPayloadOptions(Payload payload, std::size_t count, const ScanOptions& options) {
  if (options.stamp != 0 && payload != Payload::kStamp)
    throw Error(ErrorCode::kInvalidArgument,
                "insertPointCloud: a time stamp (" + std::to_string(options.stamp) +
                    ") was given, but the map is a " + treeTypeName(payload) +
                    ", which holds no stamps; make a StampedMap (MapParams::payload = "
                    "Payload::kStamp) to keep them");
  if (options.colors.empty()) return;
  if (payload != Payload::kColor)
    throw Error(ErrorCode::kInvalidArgument,
                std::string("insertPointCloud: colours were given, but the map is a ") +
                    treeTypeName(payload) +
                    ", which holds no colour; make a ColorMap (MapParams::payload = "
                    "Payload::kColor) to keep colours");
  if (options.colors.size() != count)
    throw Error(ErrorCode::kInvalidArgument,
                "insertPointCloud: " + std::to_string(options.colors.size()) + " colours for " +
                    std::to_string(count) +
                    " points (or depth pixels); give exactly one colour per point");
  if (options.color_fold != ColorFold::kAverage && options.color_fold != ColorFold::kIntegrate)
    throw Error(ErrorCode::kInvalidArgument,
                "insertPointCloud: ScanOptions::color_fold is " +
                    std::to_string(static_cast<std::uint32_t>(options.color_fold)) +
                    ", neither ColorFold::kAverage nor ColorFold::kIntegrate");
}

VkDeviceSize stageColors(const ScanSource& source, const passes::RayKeysInput& input,
                         std::span<const Rgb> colors, vk::Buffer& upload) {
  // After the points or pixels the frame staged; at 0 where they come from a caller's buffer.
  const std::size_t offset =
      source.device != VK_NULL_HANDLE ? 0 : wholeWords(static_cast<std::size_t>(input.bytes));
  auto* words =
      reinterpret_cast<std::uint32_t*>(static_cast<unsigned char*>(upload.mapped()) + offset);
  // color_fold's layout: a colour and a link word per point (the link is written on the device).
  for (std::size_t i = 0; i < colors.size(); ++i) {
    words[2 * i] = packRgb(colors[i]);
    words[2 * i + 1] = 0;
  }
  return offset;
}

std::size_t depthBytesOf(const ScanSource& source) {
  if (!source.depth) return 0;
  return sizeof(gpu::DepthCamera) + wholeWords(pixelBytes(source));
}

passes::RayKeysInput stage(const ScanSource& source, vk::Buffer& upload) {
  passes::RayKeysInput in;
  in.source = upload.handle();
  if (!source.depth) {
    static_assert(sizeof(Eigen::Vector3f) == 3 * sizeof(float));
    in.bytes = source.count() * sizeof(Eigen::Vector3f);
    if (source.device != VK_NULL_HANDLE) {
      in.source = source.device;
      in.source_offset = source.device_offset;
    } else {
      std::memcpy(upload.mapped(), source.points.data(), in.bytes);
    }
    return in;
  }
  const DepthImage& image = *source.depth;
  const bool u16 = image.encoding == DepthImage::Encoding::kUint16;
  in.unproject = true;
  in.camera = {
      image.fx,          image.fy,    image.cx,     image.cy,
      image.depth_scale, image.width, image.height, u16 ? gpu::kDepthUint16 : gpu::kDepthFloat32};
  const std::size_t pixel_bytes = pixelBytes(source);
  in.bytes = wholeWords(pixel_bytes);
  if (source.device != VK_NULL_HANDLE) {
    in.source = source.device;
    in.source_offset = source.device_offset;
    in.bytes = pixel_bytes;  // the caller's range may end there; the last half word is unused
  } else {
    auto* bytes = static_cast<unsigned char*>(upload.mapped());
    std::visit(
        [&](const auto& d) {  // validate() made the depths the encoding's, width * height
          if constexpr (!std::is_same_v<std::decay_t<decltype(d)>, std::monostate>)
            std::memcpy(bytes, d.data(), pixel_bytes);
        },
        image.depths);
    std::memset(bytes + pixel_bytes, 0, in.bytes - pixel_bytes);
  }
  return in;
}

// An upper bound of the DDA steps of the scan's longest ray (each axis crosses at most
// |d| / resolution + 1 cell borders): from the host's points or pixels, or unbounded for a
// caller's device buffer. Ray lengths do not change with the pose (a rotation and a translation
// of both ends), so they are measured in the frame the input is given in.
double worstSteps(const ScanSource& source, const Eigen::Vector3f& origin_world, const Pose* pose,
                  double max_range, double resolution) {
  if (source.device != VK_NULL_HANDLE) return HUGE_VAL;
  const Eigen::Vector3f origin = pose ? pose->inverse().transform(origin_world) : origin_world;
  double longest = 0.0;  // metres
  if (source.depth) {
    const DepthImage& im = *source.depth;
    double z_max = 0.0;
    const std::size_t n = std::size_t{im.width} * im.height;
    if (im.encoding == DepthImage::Encoding::kUint16) {
      const std::uint16_t* d = std::get<std::span<const std::uint16_t>>(im.depths).data();
      std::uint16_t m = 0;
      for (std::size_t i = 0; i < n; ++i) m = std::max(m, d[i]);
      z_max = m / static_cast<double>(im.depth_scale);
    } else {
      const float* d = std::get<std::span<const float>>(im.depths).data();
      float m = 0.0f;
      for (std::size_t i = 0; i < n; ++i)
        if (std::isfinite(d[i])) m = std::max(m, std::fabs(d[i]));
      z_max = m / static_cast<double>(std::fabs(im.depth_scale));
    }
    const double cx = im.cx, cy = im.cy;
    const double u = std::max(std::fabs(cx), std::fabs(im.width - 1.0 - cx)) / std::fabs(im.fx);
    const double v = std::max(std::fabs(cy), std::fabs(im.height - 1.0 - cy)) / std::fabs(im.fy);
    longest = z_max * std::sqrt(1.0 + u * u + v * v) + origin.norm();
  } else {
    for (const Eigen::Vector3f& p : source.points)
      if (p.allFinite()) longest = std::max(longest, static_cast<double>((p - origin).norm()));
  }
  if (max_range > 0) longest = std::min(longest, max_range);
  // Float rounding of the ends, a discretized end cell's centre: a cell more at each end.
  return 1.8 * (longest / resolution + 2.0) + 3.0;
}

}  // namespace octovk
