// What the tree fuzz targets (fuzz_tree.cpp, fuzz_message.cpp) require of a reader: a refusal is
// a kFormat error; an accepted tree (of any type the reader takes: OcTree, ColorOcTree,
// OcTreeStamped) has at most 16 levels, finite log-odds everywhere and as many nodes as it says.
// Anything else aborts (a finding).
#pragma once

#include <cmath>
#include <cstdlib>
#include <memory>
#include <variant>

#include "io/parse.hpp"

namespace octovk::fuzz {

/// Runs `parse` (returning the tree) and checks its outcome as above.
template <class Parse>
void checkTreeReader(Parse&& parse) {
  octovk::io::AnyTree any;
  try {
    any = parse();
  } catch (const octovk::Error& e) {
    if (e.code() != octovk::ErrorCode::kFormat) std::abort();
    return;
  }
  std::visit(
      [](const auto& tree) {
        if (!tree) std::abort();
        std::size_t nodes = 0;
        for (auto it = tree->begin_tree(), end = tree->end_tree(); it != end; ++it) {
          ++nodes;
          if (it.getDepth() > 16 || !std::isfinite(it->getLogOdds())) std::abort();
        }
        if (nodes != tree->size()) std::abort();
      },
      any);
}

}  // namespace octovk::fuzz
