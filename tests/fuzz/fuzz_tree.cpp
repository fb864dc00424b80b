// libFuzzer target of the .bt (OCTOVK_FUZZ_BINARY=1) or .ot reader: the bytes go through the same
// check and OctoMap data reader as readMapFile. A refusal must be a kFormat error; an accepted
// tree must have the announced shape: at most 16 levels and finite log-odds everywhere. Anything
// else (a crash, a sanitizer report, a hang, an allocation past -rss_limit_mb) is a finding.
#include <cstdint>
#include <string_view>

#include "io/parse.hpp"
#include "tree_check.hpp"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  const std::string_view bytes(reinterpret_cast<const char*>(data), size);
  octovk::fuzz::checkTreeReader(
      [&] { return octovk::io::parseTreeFile(bytes, OCTOVK_FUZZ_BINARY != 0, "fuzz-input"); });
  return 0;
}
