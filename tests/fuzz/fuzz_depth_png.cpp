// libFuzzer target of the depth-image reader (readDepthPng's decoder, libpng on memory). Built
// with FUZZING_BUILD_MODE_UNSAFE_FOR_PRODUCTION, so libpng ignores damaged chunk checksums and
// mutated chunks reach the decoder. A refusal must be a kFormat error; an accepted image must be
// at most 65536 pixels each way, hold width x height depths, and be no larger than the bytes can
// hold (deflate's 1032:1). Anything else (a crash, a sanitizer report, a hang, an allocation past
// -rss_limit_mb) is a finding.
#include <cstdint>
#include <cstdlib>
#include <string_view>

#include "io/tum_parse.hpp"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  const std::string_view bytes(reinterpret_cast<const char*>(data), size);
  octovk::DepthPng png;
  try {
    png = octovk::io::decodeDepthPng(bytes, "fuzz-input.png");
  } catch (const octovk::Error& e) {
    if (e.code() != octovk::ErrorCode::kFormat) std::abort();
    return 0;
  }
  if (png.width == 0 || png.height == 0 || png.width > 65536 || png.height > 65536 ||
      png.depths.size() != std::size_t{png.width} * png.height ||
      png.depths.size() * 2 > octovk::io::kDeflateMaxRatio * size)
    std::abort();
  const octovk::DepthImage image = png.image(octovk::CameraIntrinsics{});
  const auto* view = std::get_if<std::span<const std::uint16_t>>(&image.depths);
  if (!view || view->data() != png.depths.data() || view->size() != png.depths.size() ||
      image.width != png.width)
    std::abort();
  return 0;
}
