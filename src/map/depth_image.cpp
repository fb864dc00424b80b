// Depth images: their validation and the host's unprojection, operation for operation the one
// shaders/unproject.comp does on the device (float, correctly rounded, no contraction).
#include "map/depth_image.hpp"

#include <cmath>
#include <sstream>

#include "octovk/octovk.hpp"

namespace octovk {

namespace {

const char* encodingName(DepthImage::Encoding encoding) {
  return encoding == DepthImage::Encoding::kUint16 ? "kUint16" : "kFloat32";
}

// What `depths` holds, in words, and how many depths.
struct Held {
  const char* type;
  DepthImage::Encoding encoding;
  std::size_t count;
};
Held held(const DepthImage::Depths& depths) {
  if (const auto* u16 = std::get_if<std::span<const std::uint16_t>>(&depths))
    return {"std::uint16_t", DepthImage::Encoding::kUint16, u16->size()};
  const auto& f32 = std::get<std::span<const float>>(depths);
  return {"float", DepthImage::Encoding::kFloat32, f32.size()};
}

}  // namespace

std::string depthImageProblem(const DepthImage& image, bool host_depths) {
  std::ostringstream why;
  const std::uint64_t pixels = std::uint64_t{image.width} * image.height;
  if (image.width == 0 || image.height == 0) {
    why << "the depth image is empty (" << image.width << " x " << image.height << " pixels)";
  } else if (image.width > 65536 || image.height > 65536) {
    why << "the depth image is " << image.width << " x " << image.height
        << " pixels; at most 65536 in each direction";
  } else if (image.encoding != DepthImage::Encoding::kUint16 &&
             image.encoding != DepthImage::Encoding::kFloat32) {
    why << "the depth image's encoding " << static_cast<std::uint32_t>(image.encoding)
        << " is neither kUint16 nor kFloat32";
  } else if (host_depths && std::holds_alternative<std::monostate>(image.depths)) {
    why << "the depth image has no depths (DepthImage::depths is empty): give a "
        << (image.encoding == DepthImage::Encoding::kUint16 ? "std::span<const std::uint16_t>"
                                                            : "std::span<const float>")
        << " of its " << pixels << " depths";
  } else if (host_depths && held(image.depths).encoding != image.encoding) {
    const Held h = held(image.depths);
    why << "the depth image's depths are " << h.type << " but its encoding is "
        << encodingName(image.encoding)
        << ": set encoding = DepthImage::Encoding::" << encodingName(h.encoding)
        << ", or give depths of the type the encoding names";
  } else if (host_depths && held(image.depths).count != pixels) {
    const Held h = held(image.depths);
    why << "the depth image is " << image.width << " x " << image.height << " = " << pixels
        << " pixels but DepthImage::depths holds " << h.count << " " << h.type
        << " depths: give exactly width * height, row by row"
        << (h.count < pixels ? " (the buffer is short)" : "");
  } else if (!std::isnormal(image.fx) || !std::isnormal(image.fy)) {
    why << "the focal lengths fx, fy must be finite, non-zero and not subnormal (got " << image.fx
        << ", " << image.fy << ")";
  } else if (!std::isfinite(image.cx) || !std::isfinite(image.cy) ||
             std::fpclassify(image.cx) == FP_SUBNORMAL ||
             std::fpclassify(image.cy) == FP_SUBNORMAL) {
    why << "the principal point cx, cy must be finite and not subnormal (got " << image.cx << ", "
        << image.cy << ")";
  } else if (!std::isnormal(image.depth_scale) || image.depth_scale < 0.0f) {
    why << "depth_scale must be a finite positive number of depth units per metre (got "
        << image.depth_scale << ")";
  }
  return why.str();
}

std::string DepthImage::validate() const { return depthImageProblem(*this, true); }

std::vector<Eigen::Vector3f> unprojectDepthImage(const DepthImage& image, std::size_t* skipped) {
  if (std::string why = image.validate(); !why.empty())
    throw Error(ErrorCode::kInvalidArgument, "unprojectDepthImage: " + why);
  std::vector<Eigen::Vector3f> points;
  points.reserve(std::size_t{image.width} * image.height);
  std::size_t none = 0;
  const auto* raw = std::get_if<std::span<const std::uint16_t>>(&image.depths);
  const auto* metres = std::get_if<std::span<const float>>(&image.depths);
  for (std::uint32_t v = 0; v < image.height; ++v) {
    for (std::uint32_t u = 0; u < image.width; ++u) {
      const std::size_t i = std::size_t{v} * image.width + u;
      const float d = raw ? static_cast<float>((*raw)[i]) : (*metres)[i];
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
