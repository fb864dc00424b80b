// Shared by the consumer programs: a project outside octovk's build that uses the installed
// package (scripts/consumer.sh builds them with CMake's find_package and with pkg-config).
// Exit status: 0 passed, 1 failed, 77 skipped (no Vulkan device and CI unset; under CI a missing
// device fails).
#pragma once

#include <octovk/octovk.hpp>

#include <cstdio>
#include <cstdlib>
#include <memory>
#include <string>
#include <vector>

namespace consumer {

inline int fail(const std::string& why) {
  std::fprintf(stderr, "consumer: FAILED: %s\n", why.c_str());
  return 1;
}

inline bool runningInCi() {
  const char* ci = std::getenv("CI");
  return ci && *ci && std::string(ci) != "0" && std::string(ci) != "false";
}

/// The context, or null with `exit_code` set (1 under CI, else 77 = skipped).
inline std::unique_ptr<octovk::Context> context(int& exit_code) {
  auto result = octovk::Context::create();
  if (result) return std::move(result.value());
  if (runningInCi()) {
    exit_code = fail(std::string("no Vulkan device under CI: ") + result.error().what());
  } else {
    std::fprintf(stderr, "consumer: skipped: no Vulkan device: %s\n", result.error().what());
    exit_code = 77;
  }
  return nullptr;
}

/// A wall of points 2 m in front of the origin: the cells between are free, the wall occupied.
/// Empty string if the map shows that, else what is wrong.
inline std::string insertWall(octovk::OccupancyMap& map) {
  std::vector<Eigen::Vector3f> points;
  for (int y = -5; y <= 5; ++y)
    for (int z = -5; z <= 5; ++z)
      points.emplace_back(2.0f, 0.05f * static_cast<float>(y), 0.05f * static_cast<float>(z));
  const octovk::ScanStats stats = map.insertPointCloud(points, Eigen::Vector3f::Zero());
  if (stats.points != points.size())
    return "the scan counted " + std::to_string(stats.points) + " points";
  if (map.nodeCount() == 0) return "nodeCount() is 0 after a scan";
  const std::vector<Eigen::Vector3f> probes = {
      {2.0f, 0.0f, 0.0f}, {1.0f, 0.0f, 0.0f}, {0.0f, 3.0f, 0.0f}};
  const std::vector<octovk::Lookup> cells = map.search(probes);
  if (cells.size() != 3 || cells[0].state != octovk::CellState::kOccupied ||
      cells[1].state != octovk::CellState::kFree || cells[2].state != octovk::CellState::kUnknown)
    return "search() does not see the wall occupied, the space before it free, the side unknown";
  // A ceiling 6 m up, cut at 3 m by ScanOptions: the rays clear the space below 3 m and mark
  // nothing occupied (OctoMap's max range).
  std::vector<Eigen::Vector3f> ceiling;
  for (int x = -5; x <= 5; ++x)
    for (int y = -5; y <= 5; ++y)
      ceiling.emplace_back(0.05f * static_cast<float>(x), 0.05f * static_cast<float>(y), 6.0f);
  map.insertPointCloud(ceiling, Eigen::Vector3f::Zero(), {.max_range_m = 3.0});
  const std::vector<Eigen::Vector3f> up = {{0.0f, 0.0f, 2.0f}, {0.0f, 0.0f, 6.0f}};
  const std::vector<octovk::Lookup> above = map.search(up);
  if (above.size() != 2 || above[0].state != octovk::CellState::kFree ||
      above[1].state != octovk::CellState::kUnknown)
    return "insertPointCloud(..., {.max_range_m = 3.0}) did not clear 2 m up and leave 6 m unknown";
  return {};
}

}  // namespace consumer
