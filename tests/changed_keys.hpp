// The change set as sorted (key, flag) tuples, from OctoMap's changedKeys and from octovk's, for
// tests that compare the two (change_detection_test, keep_box_test).
#pragma once

#include <octomap/octomap.h>

#include <algorithm>
#include <cstdint>
#include <tuple>
#include <vector>

#include "octovk/octovk.hpp"

namespace octovk::test {

using KeyFlag = std::tuple<std::uint16_t, std::uint16_t, std::uint16_t, bool>;

inline std::vector<KeyFlag> oracleChanges(const octomap::OcTree& tree) {
  std::vector<KeyFlag> out;
  for (auto it = tree.changedKeysBegin(); it != tree.changedKeysEnd(); ++it)
    out.emplace_back(it->first[0], it->first[1], it->first[2], it->second);
  std::sort(out.begin(), out.end());
  return out;
}

inline std::vector<KeyFlag> ourChanges(OccupancyMap& map) {
  std::vector<KeyFlag> out;
  for (const ChangedKey& c : map.changedKeys())
    out.emplace_back(c.key[0], c.key[1], c.key[2], c.created);
  std::sort(out.begin(), out.end());
  return out;
}

}  // namespace octovk::test
