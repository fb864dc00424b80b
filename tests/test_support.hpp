// Shared helpers of the test executables: the Vulkan context (a failure under CI, a skip with a
// reason elsewhere) and tree comparison against OctoMap.
#pragma once

#include <gtest/gtest.h>
#include <octomap/OcTree.h>

#include <cstdlib>
#include <memory>
#include <random>
#include <sstream>
#include <string>
#include <vector>

#include "octovk/octomap_io.hpp"
#include "octovk/octovk.hpp"

namespace octovk::test {

/// The process-wide context, or nullptr with `why` set.
inline Context* sharedContext(std::string* why) {
  static std::unique_ptr<Context> context;
  static std::string error;
  static bool tried = false;
  if (!tried) {
    tried = true;
    auto result = Context::create();
    if (result) context = std::move(result.value());
    else error = result.error().what();
  }
  if (why) *why = error;
  return context.get();
}

inline bool runningInCi() {
  const char* ci = std::getenv("CI");
  return ci && *ci && std::string(ci) != "0" && std::string(ci) != "false";
}

}  // namespace octovk::test

/// Gives `ctx` (octovk::Context&) to the test; with CI set a missing device fails the test,
/// elsewhere it is skipped with the reason.
#define OCTOVK_REQUIRE_CONTEXT(ctx)                                                   \
  std::string octovk_why_;                                                            \
  ::octovk::Context* octovk_ctx_ = ::octovk::test::sharedContext(&octovk_why_);       \
  if (!octovk_ctx_) {                                                                 \
    if (::octovk::test::runningInCi()) FAIL() << "no Vulkan device under CI: " << octovk_why_; \
    GTEST_SKIP() << "no Vulkan device: " << octovk_why_;                              \
  }                                                                                   \
  ::octovk::Context& ctx = *octovk_ctx_

namespace octovk::test {

inline std::string otBytes(const octomap::OcTree& tree) {
  std::stringstream s;
  tree.write(s);
  return s.str();
}

inline std::string btBytes(const octomap::OcTree& tree) {
  std::stringstream s;
  tree.writeBinaryConst(s);
  return s.str();
}

/// Node-by-node equality (OcTree::operator==) and byte-identical .ot (log-odds bits included).
inline ::testing::AssertionResult sameTree(const octomap::OcTree& expected,
                                           const octomap::OcTree& actual) {
  if (expected.size() != actual.size())
    return ::testing::AssertionFailure()
           << "node count differs: OctoMap " << expected.size() << ", octovk " << actual.size();
  if (!(expected == actual)) return ::testing::AssertionFailure() << "OcTree::operator== is false";
  if (otBytes(expected) != otBytes(actual))
    return ::testing::AssertionFailure() << ".ot bytes differ";
  return ::testing::AssertionSuccess();
}

inline octomap::Pointcloud toPointcloud(const std::vector<Eigen::Vector3f>& pts) {
  octomap::Pointcloud pc;
  for (const auto& p : pts) pc.push_back(p.x(), p.y(), p.z());
  return pc;
}

inline octomap::OcTree makeOracle(const MapParams& p) {
  octomap::OcTree tree(p.resolution);
  tree.setProbHit(p.prob_hit);
  tree.setProbMiss(p.prob_miss);
  tree.setClampingThresMin(p.clamping_min);
  tree.setClampingThresMax(p.clamping_max);
  tree.setOccupancyThres(p.occupancy_threshold);
  return tree;
}

}  // namespace octovk::test
