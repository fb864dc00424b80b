// A depth image's checks, shared by the host calls (DepthImage::validate) and the caller's device
// buffer path (vulkan_interop.hpp), which has no host depths.
#pragma once

#include <string>

#include "octovk/scan.hpp"

namespace octovk {

/// Empty when `image` is valid, else a sentence naming the bad value. `host_depths`: the depths
/// must be on the host (DepthImage::depths of encoding's type, width * height of them); false:
/// they are in a device buffer and DepthImage::depths is not looked at.
std::string depthImageProblem(const DepthImage& image, bool host_depths);

}  // namespace octovk
