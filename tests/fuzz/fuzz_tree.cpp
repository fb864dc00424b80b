// libFuzzer target of the .bt (OCTOVK_FUZZ_BINARY=1) or .ot reader: the bytes go through the same
// check and OctoMap data reader as readMapFile. A refusal must be a kFormat error; an accepted
// tree must have the announced shape: at most 16 levels and finite log-odds everywhere. Anything
// else (a crash, a sanitizer report, a hang, an allocation past -rss_limit_mb) is a finding.
#include <cmath>
#include <cstdint>
#include <cstdlib>
#include <string_view>

#include "io/parse.hpp"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  const std::string_view bytes(reinterpret_cast<const char*>(data), size);
  std::unique_ptr<octomap::OcTree> tree;
  try {
    tree = octovk::io::parseTreeFile(bytes, OCTOVK_FUZZ_BINARY != 0, "fuzz-input");
  } catch (const octovk::Error& e) {
    if (e.code() != octovk::ErrorCode::kFormat) std::abort();
    return 0;
  }
  std::size_t nodes = 0;
  for (auto it = tree->begin_tree(), end = tree->end_tree(); it != end; ++it) {
    ++nodes;
    if (it.getDepth() > 16 || !std::isfinite(it->getLogOdds())) std::abort();
  }
  if (nodes != tree->size()) std::abort();
  return 0;
}
