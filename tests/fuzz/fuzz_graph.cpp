// libFuzzer target of the .graph reader (readScanGraph's parser). A refusal must be a kFormat
// error; accepted scans must have finite poses (points may be NaN) and as many points as the
// bytes can hold. Anything else (a crash, a sanitizer report, a hang, an allocation past
// -rss_limit_mb) is a finding.
#include <cmath>
#include <cstdint>
#include <cstdlib>
#include <string_view>

#include "io/parse.hpp"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  const std::string_view bytes(reinterpret_cast<const char*>(data), size);
  std::vector<octovk::GraphScan> scans;
  try {
    scans = octovk::io::parseScanGraph(bytes, "fuzz-input");
  } catch (const octovk::Error& e) {
    if (e.code() != octovk::ErrorCode::kFormat) std::abort();
    return 0;
  }
  std::size_t points = 0;
  for (const octovk::GraphScan& scan : scans) {
    points += scan.points_sensor.size();
    if (!scan.T_world_sensor.translation.allFinite() ||
        !scan.T_world_sensor.rotation.coeffs().allFinite())
      std::abort();
    (void)octovk::graph2treeSensorOrigin(scan.T_world_sensor);
  }
  if (points * 28 > size) std::abort();  // a point takes 28 bytes in the file
  return 0;
}
