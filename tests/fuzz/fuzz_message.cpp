// libFuzzer target of the map message body reader (messageToMap's check and OctoMap's data
// reader): the first byte's lowest bit says binary (writeBinaryData) or full (writeData), its next
// two bits the tree type (0 OcTree, 1 ColorOcTree, 2 OcTreeStamped, 3 OcTree), the rest is the
// body, read at 0.1 m as a tree of that type. A refusal must be a kFormat error; an accepted tree
// must have at most 16 levels and finite log-odds everywhere. Anything else (a crash, a sanitizer
// report, a hang, an allocation past the limits) is a finding.
#include <cstdint>
#include <string_view>

#include "io/parse.hpp"
#include "tree_check.hpp"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  if (size == 0) return 0;
  const bool binary = (data[0] & 1u) != 0;
  static constexpr const char* kTypes[] = {"OcTree", "ColorOcTree", "OcTreeStamped", "OcTree"};
  const char* type = kTypes[(data[0] >> 1) & 3u];
  const std::string_view body(reinterpret_cast<const char*>(data + 1), size - 1);
  octovk::fuzz::checkTreeReader(
      [&] { return octovk::io::parseTreeBody(body, binary, type, 0.1, "fuzz-input"); });
  return 0;
}
