// Depth images: their validation and the host's unprojection, operation for operation the one
// shaders/unproject.comp does on the device (float, correctly rounded, no contraction).
#include <cmath>
#include <cstring>
#include <sstream>

#include "octovk/octovk.hpp"

namespace octovk {

std::string DepthImage::validate() const {
  std::ostringstream why;
  if (width == 0 || height == 0) {
    why << "the depth image is empty (" << width << " x " << height << " pixels)";
  } else if (width > 65536 || height > 65536) {
    why << "the depth image is " << width << " x " << height
        << " pixels; at most 65536 in each direction";
  } else if (pixels == nullptr) {
    why << "the depth image has no pixels (DepthImage::pixels is null)";
  } else if (encoding != Encoding::kUint16 && encoding != Encoding::kFloat32) {
    why << "the depth image's encoding " << static_cast<std::uint32_t>(encoding)
        << " is neither kUint16 nor kFloat32";
  } else if (!std::isnormal(fx) || !std::isnormal(fy)) {
    why << "the focal lengths fx, fy must be finite, non-zero and not subnormal (got " << fx
        << ", " << fy << ")";
  } else if (!std::isfinite(cx) || !std::isfinite(cy) ||
             std::fpclassify(cx) == FP_SUBNORMAL || std::fpclassify(cy) == FP_SUBNORMAL) {
    why << "the principal point cx, cy must be finite and not subnormal (got " << cx << ", " << cy
        << ")";
  } else if (!std::isnormal(depth_scale) || depth_scale < 0.0f) {
    why << "depth_scale must be a finite positive number of depth units per metre (got "
        << depth_scale << ")";
  }
  return why.str();
}

std::vector<Eigen::Vector3f> unprojectDepthImage(const DepthImage& image, std::size_t* skipped) {
  if (std::string why = image.validate(); !why.empty())
    throw Error(ErrorCode::kInvalidArgument, "unprojectDepthImage: " + why);
  std::vector<Eigen::Vector3f> points;
  points.reserve(std::size_t{image.width} * image.height);
  std::size_t none = 0;
  const auto* bytes = static_cast<const unsigned char*>(image.pixels);
  for (std::uint32_t v = 0; v < image.height; ++v) {
    for (std::uint32_t u = 0; u < image.width; ++u) {
      const std::size_t i = std::size_t{v} * image.width + u;
      float d;
      if (image.encoding == DepthImage::Encoding::kUint16) {
        std::uint16_t raw;
        std::memcpy(&raw, bytes + i * sizeof(raw), sizeof(raw));
        d = static_cast<float>(raw);
      } else {
        std::memcpy(&d, bytes + i * sizeof(d), sizeof(d));
      }
      // As shaders/unproject.comp: no usable depth when d or z is zero, subnormal or not finite.
      const float z = std::isnormal(d) ? d / image.depth_scale : 0.0f;
      if (!std::isnormal(d) || !std::isnormal(z)) {
        ++none;
        continue;
      }
      const float du = static_cast<float>(u) - image.cx;
      const float dv = static_cast<float>(v) - image.cy;
      const float xz = du * z;
      const float yz = dv * z;
      points.emplace_back(xz / image.fx, yz / image.fy, z);
    }
  }
  if (skipped) *skipped = none;
  return points;
}

}  // namespace octovk
