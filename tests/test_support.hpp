// Shared helpers of the test executables: the Vulkan context (a failure under CI, a skip with a
// reason elsewhere) and tree comparison against OctoMap.
#pragma once

#include <gtest/gtest.h>
#include <octomap/OcTree.h>
#include <unistd.h>

#include <cstdlib>
#include <memory>
#include <random>
#include <sstream>
#include <string>
#include <vector>

#include "octovk/octomap_io.hpp"
#include "octovk/octovk.hpp"
#include "test_paths.hpp"

namespace octovk::test {

/// Holds the process-wide context and destroys it when the test program's run ends (a gtest
/// environment's TearDown, inside RUN_ALL_TESTS), not in a static's destructor after main: a
/// driver may register exit handlers of its own when it is loaded, after such a static was made,
/// which then run first and leave the context's destructor a torn-down driver. NVIDIA's does: on
/// an H200 every test program that used the context passed its tests and died of SIGSEGV at exit.
class SharedContextEnvironment : public ::testing::Environment {
 public:
  void TearDown() override { context.reset(); }

  std::unique_ptr<Context> context;
  std::string error;
  bool tried = false;
};

/// Registered before main, as gtest asks of global environments.
inline SharedContextEnvironment* const kSharedContextEnvironment =
    static_cast<SharedContextEnvironment*>(
        ::testing::AddGlobalTestEnvironment(new SharedContextEnvironment));

/// The process-wide context, or nullptr with `why` set.
inline Context* sharedContext(std::string* why) {
  SharedContextEnvironment& shared = *kSharedContextEnvironment;
  if (!shared.tried) {
    shared.tried = true;
    // Under OCTOVK_VALIDATION (the library turns the layer on), every validation message fails
    // the test in whose Vulkan call it arose.
    ContextOptions options;
    options.on_validation_message = [](const std::string& message) {
      ADD_FAILURE() << "Vulkan validation " << message;
    };
    auto result = Context::create(options);
    if (result)
      shared.context = std::move(result.value());
    else
      shared.error = result.error().what();
  }
  if (why) *why = shared.error;
  return shared.context.get();
}

/// A context on the shared one's device with one descriptor binding's range forced down to
/// `bytes` (ContextOptions::max_binding_bytes): the limit's paths, cheaply.
inline Result<std::unique_ptr<Context>> contextWithBindingLimit(const Context& ctx,
                                                                std::uint64_t bytes) {
  ContextOptions options;
  options.selector = std::to_string(ctx.device().index);
  options.max_binding_bytes = bytes;
  return Context::create(options);
}

/// Half the side, in whole metres, of a square box from z = -10 to 10 m whose distance field at
/// 0.1 m ((20 h + 1)^2 x 201 cells, 20 bytes or more each) needs more than `ctx`'s device has in
/// all, within a field's limits (fewer than 2^32 cells: h <= 230); 0 where the device holds even
/// the largest such field (an H200's 140 GiB does: about 80 GiB).
inline int fieldHalfSideBeyondDevice(const Context& ctx) {
  for (int h = 100; h <= 230; ++h) {
    const double side = 20.0 * h + 1.0;
    if (side * side * 201.0 * 20.0 > static_cast<double>(ctx.device().memory_bytes)) return h;
  }
  return 0;
}

/// "N x N x 201 cells", the box of fieldHalfSideBeyondDevice's `h` as messages name it.
inline std::string fieldBoxCells(int h) {
  const std::string side = std::to_string(20 * h + 1);
  return side + " x " + side + " x 201 cells";
}

/// Whether this executable is built with AddressSanitizer (scripts/sanitize.sh): the programs it
/// runs reserve terabytes of shadow memory, so `ulimit -v` stops them at start, and their RSS is
/// ASan's, not the program's. Tests leave out those limits and measurements there; the other
/// steps of scripts/test.sh make them.
#if defined(__SANITIZE_ADDRESS__)
inline constexpr bool kAddressSanitizer = true;
#else
inline constexpr bool kAddressSanitizer = false;
#endif

inline bool runningInCi() {
  const char* ci = std::getenv("CI");
  return ci && *ci && std::string(ci) != "0" && std::string(ci) != "false";
}

/// Whether `path` names a program this process may run.
inline bool isExecutable(const std::string& path) {
  return !path.empty() && ::access(path.c_str(), X_OK) == 0;
}

}  // namespace octovk::test

/// Gives OctoMap's graph2tree to the test: with CI set a missing one fails the test, elsewhere it
/// is skipped with the package to install.
#define OCTOVK_REQUIRE_GRAPH2TREE()                                           \
  if (!::octovk::test::isExecutable(OCTOVK_PATH(OCTOVK_GRAPH2TREE))) {        \
    if (::octovk::test::runningInCi())                                        \
      FAIL() << "graph2tree missing under CI: apt-get install octomap-tools"; \
    GTEST_SKIP() << "graph2tree missing: apt-get install octomap-tools";      \
  }

/// Gives `ctx` (octovk::Context&) to the test; with CI set a missing device fails the test,
/// elsewhere it is skipped with the reason.
#define OCTOVK_REQUIRE_CONTEXT(ctx)                                                            \
  std::string octovk_why_;                                                                     \
  ::octovk::Context* octovk_ctx_ = ::octovk::test::sharedContext(&octovk_why_);                \
  if (!octovk_ctx_) {                                                                          \
    if (::octovk::test::runningInCi()) FAIL() << "no Vulkan device under CI: " << octovk_why_; \
    GTEST_SKIP() << "no Vulkan device: " << octovk_why_;                                       \
  }                                                                                            \
  ::octovk::Context& ctx = *octovk_ctx_

namespace octovk::test {

/// Whether this run must have ray queries (OCTOVK_EXPECT_RAY_QUERY set and not "0"; the Mesa 25
/// lavapipe step of scripts/test.sh sets it): then a device without them fails the tests of the
/// ray-tracing backend instead of skipping them.
inline bool rayQueryExpected() {
  const char* v = std::getenv("OCTOVK_EXPECT_RAY_QUERY");
  return v && *v && std::string(v) != "0";
}

}  // namespace octovk::test

/// Skips a test of castRay's ray-tracing backend, with the reason, on a device without ray
/// queries; fails it there when the run expects them (OCTOVK_EXPECT_RAY_QUERY).
#define OCTOVK_REQUIRE_RAY_QUERY(ctx)                                                         \
  if (!(ctx).device().ray_query_enabled) {                                                    \
    if (::octovk::test::rayQueryExpected())                                                   \
      FAIL() << "OCTOVK_EXPECT_RAY_QUERY is set but device '" << (ctx).device().name << "' (" \
             << (ctx).device().driver << ") has no ray queries enabled";                      \
    GTEST_SKIP() << "device '" << (ctx).device().name << "' (" << (ctx).device().driver       \
                 << ") has no VK_KHR_acceleration_structure + VK_KHR_ray_query: the "         \
                 << "ray-tracing backend is not tested here (Mesa 25 lavapipe has them)";     \
  }

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

/// The first node (depth-first, children in index order) where two trees differ, in words.
inline std::string firstDifference(const octomap::OcTree& expected, const octomap::OcTree& actual) {
  std::ostringstream out;
  struct Walk {
    const octomap::OcTree& a;
    const octomap::OcTree& b;
    std::ostringstream& out;
    bool operator()(const octomap::OcTreeNode* x, const octomap::OcTreeNode* y, unsigned depth,
                    unsigned kx, unsigned ky, unsigned kz) {
      auto where = [&] {
        const double size = a.getNodeSize(depth);
        out << "node at depth " << depth << " key (" << kx << ", " << ky << ", " << kz
            << ") centre ("
            << a.keyToCoord(octomap::OcTreeKey(static_cast<octomap::key_type>(kx),
                                               static_cast<octomap::key_type>(ky),
                                               static_cast<octomap::key_type>(kz)),
                            depth)
            << ") size " << size << ": ";
      };
      if (!x || !y) {
        if (x != y) {
          where();
          out << (x ? "missing in octovk" : "missing in OctoMap");
          return false;
        }
        return true;
      }
      if (x->getLogOdds() != y->getLogOdds()) {
        where();
        out.precision(9);
        out << "log-odds OctoMap " << x->getLogOdds() << ", octovk " << y->getLogOdds();
        return false;
      }
      const bool cx = a.nodeHasChildren(x), cy = b.nodeHasChildren(y);
      if (cx != cy) {
        where();
        out << (cx ? "inner in OctoMap, leaf in octovk" : "leaf in OctoMap, inner in octovk");
        return false;
      }
      if (depth >= 16 || !cx) return true;
      const unsigned bit = 15 - depth;
      for (unsigned i = 0; i < 8; ++i) {
        const octomap::OcTreeNode* xc = a.nodeChildExists(x, i) ? a.getNodeChild(x, i) : nullptr;
        const octomap::OcTreeNode* yc = b.nodeChildExists(y, i) ? b.getNodeChild(y, i) : nullptr;
        if (!(*this)(xc, yc, depth + 1, kx | ((i & 1u) << bit), ky | (((i >> 1) & 1u) << bit),
                     kz | (((i >> 2) & 1u) << bit)))
          return false;
      }
      return true;
    }
  };
  Walk walk{expected, actual, out};
  if (walk(expected.getRoot(), actual.getRoot(), 0, 0, 0, 0)) out << "no differing node found";
  return out.str();
}

/// Node-by-node equality (OcTree::operator==) and byte-identical .ot (log-odds bits included).
inline ::testing::AssertionResult sameTree(const octomap::OcTree& expected,
                                           const octomap::OcTree& actual) {
  if (expected.size() != actual.size())
    return ::testing::AssertionFailure()
           << "node count differs: OctoMap " << expected.size() << ", octovk " << actual.size()
           << "; first difference: " << firstDifference(expected, actual);
  if (!(expected == actual))
    return ::testing::AssertionFailure() << "OcTree::operator== is false; first difference: "
                                         << firstDifference(expected, actual);
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

#include <octomap/Pointcloud.h>
#include <octomap/math/Pose6D.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdint>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <iostream>
#include <iterator>
#include <tuple>

namespace octovk::test {

inline octomap::point3d toPoint(const Eigen::Vector3f& v) {
  return octomap::point3d(v.x(), v.y(), v.z());
}

/// The same pose as OctoMap's Pose6D (octomath::Quaternion(u, x, y, z) = Eigen w, x, y, z).
inline octomath::Pose6D toPose6D(const Pose& pose) {
  return octomath::Pose6D(
      octomath::Vector3(pose.translation.x(), pose.translation.y(), pose.translation.z()),
      octomath::Quaternion(pose.rotation.w(), pose.rotation.x(), pose.rotation.y(),
                           pose.rotation.z()));
}

/// The test's scratch folder (OCTOVK_TEST_TMP), created when missing.
inline std::string tmpDir() {
  std::filesystem::create_directories(OCTOVK_PATH(OCTOVK_TEST_TMP));
  return OCTOVK_PATH(OCTOVK_TEST_TMP);
}

inline std::string tmpPath(const std::string& name) { return tmpDir() + "/" + name; }

inline std::string fileBytes(const std::string& path) {
  std::ifstream in(path, std::ios_base::binary);
  return std::string(std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>());
}

inline void writeBytes(const std::string& path, const std::string& bytes) {
  std::ofstream out(path, std::ios_base::binary | std::ios_base::trunc);
  out.write(bytes.data(), static_cast<std::streamsize>(bytes.size()));
}

/// Inserts one scan into both trees (world frame) and checks them equal.
inline ::testing::AssertionResult insertBoth(OccupancyMap& map, octomap::OcTree& oracle,
                                             const std::vector<Eigen::Vector3f>& points,
                                             const Eigen::Vector3f& origin, double max_range,
                                             bool discretize, ScanStats* stats = nullptr) {
  oracle.insertPointCloud(toPointcloud(points), toPoint(origin), max_range, false, discretize);
  const ScanStats s =
      map.insertPointCloud(points, origin, {.max_range_m = max_range, .discretize = discretize});
  if (stats) *stats = s;
  if (s.nodes != oracle.size())
    return ::testing::AssertionFailure()
           << "ScanStats::nodes " << s.nodes << " but OctoMap has " << oracle.size() << " nodes";
  auto ours = toOcTree(map);
  return sameTree(oracle, *ours);
}

/// Leaf boxes as comparable tuples: centre, size and log-odds bits.
using LeafTuple = std::array<std::uint32_t, 5>;

inline std::uint32_t floatBits(float f) {
  std::uint32_t u;
  std::memcpy(&u, &f, sizeof(u));
  return u;
}

/// OctoMap's leaves, sorted: centre keyToCoord(key, depth) as float, getNodeSize(depth), log-odds.
inline std::vector<LeafTuple> oracleLeaves(const octomap::OcTree& tree) {
  std::vector<LeafTuple> out;
  for (auto it = tree.begin_leafs(), end = tree.end_leafs(); it != end; ++it) {
    const octomap::point3d c = it.getCoordinate();
    out.push_back({floatBits(c.x()), floatBits(c.y()), floatBits(c.z()),
                   floatBits(static_cast<float>(it.getSize())), floatBits(it->getLogOdds())});
  }
  std::sort(out.begin(), out.end());
  return out;
}

inline std::vector<LeafTuple> mapLeaves(OccupancyMap& map) {
  std::vector<LeafTuple> out;
  for (const auto& b : map.downloadLeafBoxes())
    out.push_back({floatBits(b.center[0]), floatBits(b.center[1]), floatBits(b.center[2]),
                   floatBits(b.size), floatBits(b.log_odds)});
  std::sort(out.begin(), out.end());
  return out;
}

/// Same leaf multiset, with the first difference described.
inline ::testing::AssertionResult sameLeaves(const octomap::OcTree& expected, OccupancyMap& map) {
  const auto a = oracleLeaves(expected);
  const auto b = mapLeaves(map);
  if (a.size() != b.size())
    return ::testing::AssertionFailure()
           << "leaf count differs: OctoMap " << a.size() << ", octovk " << b.size();
  const auto [ia, ib] = std::mismatch(a.begin(), a.end(), b.begin());
  if (ia != a.end()) {
    auto f = [](std::uint32_t u) {
      float x;
      std::memcpy(&x, &u, sizeof(x));
      return x;
    };
    return ::testing::AssertionFailure()
           << "leaf " << (ia - a.begin()) << " differs: OctoMap (" << f((*ia)[0]) << ", "
           << f((*ia)[1]) << ", " << f((*ia)[2]) << ") size " << f((*ia)[3]) << " log-odds "
           << f((*ia)[4]) << "; octovk (" << f((*ib)[0]) << ", " << f((*ib)[1]) << ", "
           << f((*ib)[2]) << ") size " << f((*ib)[3]) << " log-odds " << f((*ib)[4]);
  }
  return ::testing::AssertionSuccess();
}

/// Silences std::cout while alive (OctoMap's ScanGraph reader reports every scan there).
class QuietCout {
 public:
  QuietCout() : old_(std::cout.rdbuf(sink_.rdbuf())) {}
  ~QuietCout() { std::cout.rdbuf(old_); }
  QuietCout(const QuietCout&) = delete;
  QuietCout& operator=(const QuietCout&) = delete;

 private:
  std::ostringstream sink_;
  std::streambuf* old_;
};

/// Runs a shell command, returning its exit status.
inline int shell(const std::string& command) { return std::system(command.c_str()); }

/// n points between 0.2 and 1 times `radius` from `origin`, in uniformly random directions.
inline std::vector<Eigen::Vector3f> randomScan(std::mt19937& rng, const Eigen::Vector3f& origin,
                                               std::size_t n, float radius) {
  std::uniform_real_distribution<float> u(-1.0f, 1.0f);
  std::uniform_real_distribution<float> r(0.2f * radius, radius);
  std::vector<Eigen::Vector3f> pts;
  while (pts.size() < n) {
    Eigen::Vector3f d(u(rng), u(rng), u(rng));
    if (d.norm() < 1e-3f) continue;
    d.normalize();
    pts.push_back(origin + d * r(rng));
  }
  return pts;
}

/// `n` points spread evenly over a sphere (a Fibonacci lattice), for scans of a known shape.
inline std::vector<Eigen::Vector3f> sphere(float radius, int n, const Eigen::Vector3f& centre) {
  std::vector<Eigen::Vector3f> pts;
  for (int i = 0; i < n; ++i) {
    const float z = -1.0f + 2.0f * (static_cast<float>(i) + 0.5f) / static_cast<float>(n);
    const float r = std::sqrt(1.0f - z * z);
    const float phi = 2.39996323f * static_cast<float>(i);
    pts.push_back(centre + radius * Eigen::Vector3f(r * std::cos(phi), r * std::sin(phi), z));
  }
  return pts;
}

inline MapParams withResolution(double resolution) {
  MapParams params;
  params.resolution = resolution;
  return params;
}

}  // namespace octovk::test
