// The most pixels a depth image may have for a map to insert it: the PNG readers check a header
// against it before decoding (not in the fuzz targets' readers: it needs the Vulkan device).
#include <algorithm>

#include "gpu/gpu_types.h"
#include "map/context_access.hpp"
#include "octovk/tum_sequence.hpp"

namespace octovk {

std::uint64_t maxDepthImagePixels(Context& context) {
  // checkScan's limit (src/map/scan_source.cpp): lists are walked by one group per 64 entries.
  return std::min<std::uint64_t>(
      0x7FFFFFFFu,
      std::uint64_t{ContextAccess::device(context).maxGroupsX()} * gpu::kWorkgroupSize);
}

}  // namespace octovk
