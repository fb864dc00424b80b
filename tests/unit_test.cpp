// Unit tests: pose arithmetic against octomath, parameter validation, bad input, device
// selection, node counts and leaf boxes against OctoMap.
#include <octomap/math/Pose6D.h>
#include <octomap/octomap.h>

#include <array>
#include <cmath>
#include <cstdlib>
#include <cstring>
#include <limits>
#include <span>

#include "gpu/gpu_types.h"
#include "map/context_access.hpp"
#include "map/device_probe.hpp"
#include "test_support.hpp"
#include "vk/device.hpp"

namespace octovk::test {
namespace {

bool sameBits(float a, float b) { return test::floatBits(a) == test::floatBits(b); }

::testing::AssertionResult sameBits(const Eigen::Vector3f& ours, const octomath::Vector3& theirs) {
  for (int i = 0; i < 3; ++i)
    if (!sameBits(ours[i], theirs(static_cast<unsigned>(i))))
      return ::testing::AssertionFailure() << "component " << i << ": octovk " << ours[i]
                                           << ", octomath " << theirs(static_cast<unsigned>(i));
  return ::testing::AssertionSuccess();
}

// ---- const says what a call does (issue 27.7) --------------------------------------------------

// Which of the calls that read the tree compile on an M: each waits for the submitted scans
// (flush()), may throw an earlier scan's error and records into the map's command buffers, so
// none may be const.
template <class M>
constexpr std::array<bool, 10> kReadsTheTree = {
    requires(M& m){m.search(std::span<const Eigen::Vector3f>{});
}  // namespace
, requires(M& m) { m.castRays(std::span<const Ray>{}); }
, requires(M& m, const Eigen::Vector3f& v) { m.leavesInBox(v, v); }
, requires(M& m) { m.numChangesDetected(); }
, requires(M& m) { m.changedKeys(); }
, requires(M& m) { m.nodeCount(); }
, requires(M& m) { m.leafCount(); }
, requires(M& m) { m.download(); }
, requires(M& m) { m.downloadLeafBoxes(); }
, requires(M& m) { toOcTree(m); }
};  // namespace octovk::test
static_assert(kReadsTheTree<OccupancyMap> ==
              std::array<bool, 10>{true, true, true, true, true, true, true, true, true, true});
static_assert(kReadsTheTree<const OccupancyMap> == std::array<bool, 10>{},
              "a call that waits for the scans and may throw their error is not const");
// What stays const reads host state only: callable on a const map.
template <class M>
constexpr bool kReadsHostState = requires(M& m) {
  m.params();
  m.deviceBytes();
  m.deviceBytesByUse();
  m.poolBytes();
  m.scratchBytes();
  m.castRayInfo();
  m.isChangeDetectionEnabled();
  m.scansInFlight();
  m.syncCounts();
};
static_assert(kReadsHostState<const OccupancyMap>);

// ---- Pose vs octomath::Pose6D (host only) -----------------------------------------------------

TEST(Pose, TransformAndInverseBitExactWithPose6D) {
  std::mt19937 rng(2024);
  std::normal_distribution<float> n(0.0f, 1.0f);
  std::uniform_real_distribution<float> t(-50.0f, 50.0f);
  for (int i = 0; i < 20000; ++i) {
    // Unit and (i % 5 == 4) slightly non-unit quaternions, as read from files.
    Eigen::Quaternionf q(n(rng), n(rng), n(rng), n(rng));
    q.normalize();
    if (i % 5 == 4) q.coeffs() *= 1.0f + 1e-4f * n(rng);
    Pose pose;
    pose.rotation = q;
    pose.translation = Eigen::Vector3f(t(rng), t(rng), t(rng));
    const octomath::Pose6D theirs = test::toPose6D(pose);
    const Eigen::Vector3f v(t(rng), t(rng), t(rng));

    ASSERT_TRUE(
        sameBits(pose.transform(v), theirs.transform(octomath::Vector3(v.x(), v.y(), v.z()))))
        << "transform, sample " << i;

    const Pose inv = pose.inverse();
    const octomath::Pose6D theirs_inv = theirs.inv();
    ASSERT_TRUE(sameBits(inv.translation, theirs_inv.trans())) << "inverse translation, " << i;
    ASSERT_TRUE(sameBits(inv.rotation.w(), theirs_inv.rot().u())) << "inverse rotation u, " << i;
    ASSERT_TRUE(sameBits(inv.rotation.x(), theirs_inv.rot().x())) << "inverse rotation x, " << i;
    ASSERT_TRUE(sameBits(inv.rotation.y(), theirs_inv.rot().y())) << "inverse rotation y, " << i;
    ASSERT_TRUE(sameBits(inv.rotation.z(), theirs_inv.rot().z())) << "inverse rotation z, " << i;
    ASSERT_TRUE(
        sameBits(inv.transform(v), theirs_inv.transform(octomath::Vector3(v.x(), v.y(), v.z()))))
        << "inverse transform, sample " << i;

    // graph2tree's sensor origin: pose.inv().transform(pose.trans()).
    ASSERT_TRUE(sameBits(graph2treeSensorOrigin(pose), theirs.inv().transform(theirs.trans())))
        << "graph2tree origin, sample " << i;
  }
}

TEST(Pose, IdentityAndSpecialRotations) {
  const Pose identity;
  const Eigen::Vector3f v(1.5f, -2.25f, 3.0f);
  EXPECT_EQ(identity.transform(v), v);
  const Pose inv = identity.inverse();
  EXPECT_EQ(inv.transform(v), v);
  // Rotations about single axes by right angles, compared with Pose6D from roll/pitch/yaw.
  for (double yaw : {M_PI_2, M_PI, -M_PI_2})
    for (double roll : {0.0, M_PI_2}) {
      const octomath::Pose6D theirs(0.5f, -1.0f, 2.0f, roll, 0.0, yaw);
      Pose pose;
      pose.translation = Eigen::Vector3f(0.5f, -1.0f, 2.0f);
      pose.rotation = Eigen::Quaternionf(theirs.rot().u(), theirs.rot().x(), theirs.rot().y(),
                                         theirs.rot().z());
      EXPECT_TRUE(
          sameBits(pose.transform(v), theirs.transform(octomath::Vector3(v.x(), v.y(), v.z()))));
      EXPECT_TRUE(sameBits(pose.inverse().translation, theirs.inv().trans()));
    }
}

// ---- MapParams ----------------------------------------------------------------------------------

TEST(MapParams, DefaultsAreOctoMaps) {
  const MapParams p;
  EXPECT_EQ(p.validate(), "");
  octomap::OcTree tree(0.1);
  // OcTree keeps the log-odds (its probability getters convert back, not exactly).
  EXPECT_EQ(octomap::logodds(p.prob_hit), tree.getProbHitLog());
  EXPECT_EQ(octomap::logodds(p.prob_miss), tree.getProbMissLog());
  EXPECT_EQ(octomap::logodds(p.clamping_min), tree.getClampingThresMinLog());
  EXPECT_EQ(octomap::logodds(p.clamping_max), tree.getClampingThresMaxLog());
  EXPECT_EQ(octomap::logodds(p.occupancy_threshold), tree.getOccupancyThresLog());
}

struct BadParams {
  const char* name;
  MapParams params;
  const char* field;
};

std::vector<BadParams> badParams() {
  std::vector<BadParams> out;
  auto add = [&](const char* name, const char* field, auto mutate) {
    MapParams p;
    mutate(p);
    out.push_back({name, p, field});
  };
  add("resolution_zero", "resolution", [](MapParams& p) { p.resolution = 0.0; });
  add("resolution_negative", "resolution", [](MapParams& p) { p.resolution = -1.0; });
  add("resolution_nan", "resolution",
      [](MapParams& p) { p.resolution = std::numeric_limits<double>::quiet_NaN(); });
  add("resolution_inf", "resolution",
      [](MapParams& p) { p.resolution = std::numeric_limits<double>::infinity(); });
  add("prob_hit_below_half", "prob_hit", [](MapParams& p) { p.prob_hit = 0.3; });
  add("prob_hit_one", "prob_hit", [](MapParams& p) { p.prob_hit = 1.0; });
  add("prob_miss_above_half", "prob_miss", [](MapParams& p) { p.prob_miss = 0.7; });
  add("prob_miss_zero", "prob_miss", [](MapParams& p) { p.prob_miss = 0.0; });
  add("clamping_equal", "clamping_min", [](MapParams& p) {
    p.clamping_min = 0.5;
    p.clamping_max = 0.5;
  });
  add("clamping_inverted", "clamping_min", [](MapParams& p) {
    p.clamping_min = 0.9;
    p.clamping_max = 0.2;
  });
  add("occupancy_threshold_one", "occupancy_threshold",
      [](MapParams& p) { p.occupancy_threshold = 1.0; });
  // The backend enums are numbered alike; 0 is CastRayBackend::kAuto and no ScanRays.
  static_assert(static_cast<std::uint32_t>(ScanRays::kWalk) ==
                    static_cast<std::uint32_t>(CastRayBackend::kWalk) &&
                static_cast<std::uint32_t>(ScanRays::kRayTracing) ==
                    static_cast<std::uint32_t>(CastRayBackend::kRayTracing));
  add("scan_rays_zero", "scan_rays", [](MapParams& p) { p.scan_rays = static_cast<ScanRays>(0); });
  // 3 and 4 are kRayQuery and kRayTracingPipeline (either enum): 5 is none.
  add("cast_ray_backend_five", "cast_ray_backend",
      [](MapParams& p) { p.cast_ray_backend = static_cast<CastRayBackend>(5); });
  add("scan_rays_five", "scan_rays", [](MapParams& p) { p.scan_rays = static_cast<ScanRays>(5); });
  return out;
}

void PrintTo(const BadParams& b, std::ostream* os) { *os << b.name; }

class InvalidParams : public ::testing::TestWithParam<BadParams> {};

TEST_P(InvalidParams, ConstructorThrowsNamingTheField) {
  const BadParams& bad = GetParam();
  const std::string why = bad.params.validate();
  EXPECT_NE(why.find(bad.field), std::string::npos) << why;
  OCTOVK_REQUIRE_CONTEXT(ctx);
  try {
    OccupancyMap map(ctx, bad.params);
    FAIL() << "no exception for " << bad.name;
  } catch (const Error& e) {
    EXPECT_EQ(e.code(), ErrorCode::kInvalidArgument);
    EXPECT_NE(std::string(e.what()).find(bad.field), std::string::npos) << e.what();
  }
}

INSTANTIATE_TEST_SUITE_P(Cases, InvalidParams, ::testing::ValuesIn(badParams()),
                         [](const ::testing::TestParamInfo<BadParams>& info) {
                           return std::string(info.param.name);
                         });

// ---- bad scan input
// ------------------------------------------------------------------------------

TEST(BadInput, NonFinitePointsAreSkippedAndCounted) {
  OCTOVK_REQUIRE_CONTEXT(ctx);
  const float nan = std::numeric_limits<float>::quiet_NaN();
  const float inf = std::numeric_limits<float>::infinity();
  for (bool discretize : {false, true})
    for (double max_range : {-1.0, 0.8}) {
      SCOPED_TRACE(std::string(discretize ? "discretize" : "no discretize") +
                   (max_range < 0 ? ", unlimited" : ", max range"));
      const MapParams params = withResolution(0.05);
      OccupancyMap map(ctx, params);
      octomap::OcTree oracle = makeOracle(params);
      std::mt19937 rng(31);
      const Eigen::Vector3f origin(0.01f, 0.02f, 0.03f);
      for (int scan = 0; scan < 3; ++scan) {
        const auto finite = randomScan(rng, origin, 300, 1.2f);
        std::vector<Eigen::Vector3f> mixed;
        std::size_t bad = 0;
        for (std::size_t i = 0; i < finite.size(); ++i) {
          mixed.push_back(finite[i]);
          if (i % 10 == 0) {
            Eigen::Vector3f p = finite[i];
            p[static_cast<int>(i % 3)] = (i % 20 == 0) ? nan : ((i % 30 == 0) ? -inf : inf);
            mixed.push_back(p);
            ++bad;
          }
        }
        mixed.emplace_back(nan, nan, nan);
        mixed.emplace_back(inf, -inf, inf);
        bad += 2;
        oracle.insertPointCloud(toPointcloud(finite), toPoint(origin), max_range, false,
                                discretize);
        const ScanStats stats = map.insertPointCloud(
            mixed, origin, {.max_range_m = max_range, .discretize = discretize});
        EXPECT_EQ(stats.points, mixed.size());
        EXPECT_EQ(stats.skipped_nonfinite, bad);
        EXPECT_EQ(stats.nodes, oracle.size());
        auto ours = toOcTree(map);
        ASSERT_TRUE(sameTree(oracle, *ours)) << "scan " << scan;
      }
    }
}

TEST(BadInput, PointsOutsideTheMapAreSkippedAndCounted) {
  OCTOVK_REQUIRE_CONTEXT(ctx);
  const double res = 0.1;
  const float edge = static_cast<float>(32768 * res);  // the map spans [-edge, edge)
  const MapParams params = withResolution(res);
  std::mt19937 rng(41);
  const Eigen::Vector3f origin(0.3f, -0.2f, 0.1f);
  const std::vector<Eigen::Vector3f> outside = {
      {edge + 10.0f, 0.0f, 0.0f}, {0.0f, -edge - 1.0f, 0.0f}, {0.0f, 0.0f, 2.0f * edge},
      {-5000.0f, 5000.0f, 1.0f},  {1.0e9f, 1.0f, 1.0f},       {edge, 0.5f, 0.5f}};
  {
    SCOPED_TRACE("unlimited range: rays to outside points are skipped");
    OccupancyMap map(ctx, params);
    octomap::OcTree oracle = makeOracle(params);
    for (int scan = 0; scan < 3; ++scan) {
      auto pts = randomScan(rng, origin, 300, 3.0f);
      pts.insert(pts.begin() + 50, outside.begin(), outside.end());
      ScanStats stats;
      ASSERT_TRUE(insertBoth(map, oracle, pts, origin, -1.0, false, &stats)) << "scan " << scan;
      EXPECT_EQ(stats.skipped_outside, outside.size());
      EXPECT_EQ(stats.skipped_nonfinite, 0u);
    }
  }
  {
    SCOPED_TRACE("max range: outside points give free rays clipped to the range");
    OccupancyMap map(ctx, params);
    octomap::OcTree oracle = makeOracle(params);
    for (int scan = 0; scan < 3; ++scan) {
      auto pts = randomScan(rng, origin, 300, 3.0f);
      pts.insert(pts.end(), outside.begin(), outside.end());
      ScanStats stats;
      ASSERT_TRUE(insertBoth(map, oracle, pts, origin, 2.0, false, &stats)) << "scan " << scan;
      EXPECT_EQ(stats.skipped_outside, 0u);
    }
  }
  {
    SCOPED_TRACE("an origin outside the map: no free cells, end points inside still count");
    OccupancyMap map(ctx, params);
    octomap::OcTree oracle = makeOracle(params);
    const Eigen::Vector3f far_origin(edge + 1.0f, 0.0f, 0.0f);
    const auto pts = randomScan(rng, Eigen::Vector3f(1.0f, 1.0f, 1.0f), 60, 1.0f);
    ScanStats stats;
    ASSERT_TRUE(insertBoth(map, oracle, pts, far_origin, -1.0, false, &stats));
    EXPECT_EQ(stats.free_cells, 0u);
    EXPECT_GT(oracle.size(), 1u);
  }
  {
    SCOPED_TRACE("points near the map's edge, inside");
    OccupancyMap map(ctx, params);
    octomap::OcTree oracle = makeOracle(params);
    const Eigen::Vector3f o(edge - 2.0f, -edge + 2.0f, edge - 1.0f);
    auto pts = randomScan(rng, o, 300, 2.5f);
    ScanStats stats;
    ASSERT_TRUE(insertBoth(map, oracle, pts, o, -1.0, false, &stats));
    EXPECT_GT(stats.skipped_outside, 0u);
    EXPECT_LT(stats.skipped_outside, pts.size());
  }
}

TEST(BadInput, EmptyScanLeavesTheMapUnchanged) {
  OCTOVK_REQUIRE_CONTEXT(ctx);
  const MapParams params = withResolution(0.1);
  OccupancyMap map(ctx, params);
  const std::vector<Eigen::Vector3f> none;
  ScanStats stats = map.insertPointCloud(none, Eigen::Vector3f::Zero());
  EXPECT_EQ(stats.points, 0u);
  EXPECT_EQ(stats.nodes, 0u);
  EXPECT_EQ(map.nodeCount(), 0u);
  EXPECT_EQ(toOcTree(map)->size(), 0u);

  octomap::OcTree oracle = makeOracle(params);
  std::mt19937 rng(3);
  const auto pts = randomScan(rng, Eigen::Vector3f::Zero(), 200, 2.0f);
  ASSERT_TRUE(insertBoth(map, oracle, pts, Eigen::Vector3f::Zero(), -1.0, false));
  const std::string before = test::otBytes(*toOcTree(map));
  stats = map.insertPointCloud(none, Eigen::Vector3f(1.0f, 2.0f, 3.0f),
                               {.max_range_m = 5.0, .discretize = true});
  EXPECT_EQ(stats.points, 0u);
  EXPECT_EQ(stats.nodes, oracle.size());
  Pose pose;
  pose.translation = Eigen::Vector3f(1.0f, 0.0f, 0.0f);
  stats = map.insertPointCloud(none, Eigen::Vector3f::Zero(), pose);
  EXPECT_EQ(stats.nodes, oracle.size());
  EXPECT_EQ(test::otBytes(*toOcTree(map)), before);
  EXPECT_TRUE(test::sameLeaves(oracle, map));
}

// Runs `call`, which must throw octovk::Error with `code`, and checks that the map still holds
// the tree it had: the same .ot bytes (`before`) and OctoMap's node count (`nodes`).
template <typename Call>
void expectRefusedMapKept(Call&& call, ErrorCode code, const char* what, OccupancyMap& map,
                          const std::string& before, std::size_t nodes) {
  try {
    call();
    ADD_FAILURE() << "no exception for " << what;
  } catch (const Error& e) {
    EXPECT_EQ(e.code(), code) << what << ": " << e.what();
  }
  EXPECT_EQ(test::otBytes(*toOcTree(map)), before) << "map changed by " << what;
  EXPECT_EQ(map.nodeCount(), nodes) << what;
}

// upload() takes a host tree from the caller: one whose child blocks lie outside it, are shared
// by two nodes, or that claims a root it does not have is refused, and the map keeps its tree.
TEST(BadInput, MalformedHostTreeUploadThrowsAndLeavesTheMap) {
  OCTOVK_REQUIRE_CONTEXT(ctx);
  const MapParams params = withResolution(0.1);
  OccupancyMap map(ctx, params);
  octomap::OcTree oracle = makeOracle(params);
  std::mt19937 rng(8);
  const auto pts = randomScan(rng, Eigen::Vector3f::Zero(), 200, 2.0f);
  ASSERT_TRUE(insertBoth(map, oracle, pts, Eigen::Vector3f::Zero(), -1.0, false));
  const std::string before = test::otBytes(*toOcTree(map));
  const HostTree good = map.download();
  constexpr std::uint32_t kRoot = 0, kChildBits = 0xFFu;  // HostTree: root at 0, mask bits 0-7
  ASSERT_TRUE(good.root_exists);
  ASSERT_NE(good.nodes[kRoot].mask & kChildBits, 0u);
  const std::uint32_t root_block = good.nodes[kRoot].children;

  auto expectFormatError = [&](const HostTree& tree, const char* what) {
    expectRefusedMapKept([&] { map.upload(tree); }, ErrorCode::kFormat, what, map, before,
                         oracle.size());
  };
  HostTree outside = good;
  outside.nodes[kRoot].children = static_cast<std::uint32_t>(good.nodes.size() / 8 + 5);
  expectFormatError(outside, "a child block outside the tree");
  HostTree shared = good;
  // A child of the root that has children of its own gets the root's block as well: a cycle.
  for (std::uint32_t s = 0; s < 8; ++s) {
    HostTree::Node& child = shared.nodes[root_block * 8 + s];
    if ((good.nodes[kRoot].mask & (1u << s)) && (child.mask & kChildBits)) {
      child.children = root_block;
      break;
    }
  }
  expectFormatError(shared, "a block shared by two nodes");
  HostTree rootless;
  rootless.root_exists = true;
  expectFormatError(rootless, "a root without nodes");
  // The tree it had still takes scans like OctoMap's.
  ASSERT_TRUE(insertBoth(map, oracle, pts, Eigen::Vector3f(0.3f, 0.1f, 0.0f), -1.0, false));
}

TEST(BadInput, NonFiniteOriginOrMaxRangeThrowsAndLeavesTheMap) {
  OCTOVK_REQUIRE_CONTEXT(ctx);
  const MapParams params = withResolution(0.1);
  OccupancyMap map(ctx, params);
  octomap::OcTree oracle = makeOracle(params);
  std::mt19937 rng(4);
  const auto pts = randomScan(rng, Eigen::Vector3f::Zero(), 200, 2.0f);
  ASSERT_TRUE(insertBoth(map, oracle, pts, Eigen::Vector3f::Zero(), -1.0, false));
  const std::string before = test::otBytes(*toOcTree(map));
  const float nan = std::numeric_limits<float>::quiet_NaN();
  const float inf = std::numeric_limits<float>::infinity();

  auto expectInvalid = [&](auto&& call, const char* what) {
    expectRefusedMapKept(call, ErrorCode::kInvalidArgument, what, map, before, oracle.size());
  };
  expectInvalid([&] { map.insertPointCloud(pts, Eigen::Vector3f(nan, 0.0f, 0.0f)); }, "NaN origin");
  expectInvalid([&] { map.insertPointCloud(pts, Eigen::Vector3f(0.0f, inf, 0.0f)); },
                "infinite origin");
  expectInvalid(
      [&] {
        map.insertPointCloud(pts, Eigen::Vector3f(0.0f, 0.0f, -inf),
                             {.max_range_m = 2.0, .discretize = true});
      },
      "-inf origin, discretize");
  expectInvalid(
      [&] {
        map.insertPointCloud(pts, Eigen::Vector3f::Zero(),
                             {.max_range_m = std::numeric_limits<double>::quiet_NaN()});
      },
      "NaN max range");
  Pose bad_translation;
  bad_translation.translation = Eigen::Vector3f(nan, 0.0f, 0.0f);
  expectInvalid([&] { map.insertPointCloud(pts, Eigen::Vector3f::Zero(), bad_translation); },
                "NaN pose translation");
  Pose bad_rotation;
  bad_rotation.rotation = Eigen::Quaternionf(inf, 0.0f, 0.0f, 0.0f);
  expectInvalid([&] { map.insertPointCloud(pts, Eigen::Vector3f::Zero(), bad_rotation); },
                "infinite pose rotation");
  expectInvalid(
      [&] {
        map.insertPointCloud(pts, Eigen::Vector3f(nan, nan, nan), Pose{}, {.max_range_m = 1.0});
      },
      "NaN sensor origin with a pose");

  // The map still works afterwards.
  const auto more = randomScan(rng, Eigen::Vector3f(0.5f, 0.0f, 0.0f), 200, 2.0f);
  ASSERT_TRUE(insertBoth(map, oracle, more, Eigen::Vector3f(0.5f, 0.0f, 0.0f), -1.0, false));
}

// The node pool and the hash set start small: one big first scan must grow both several times.
TEST(Growth, HugeFirstScanEqualsOctoMap) {
  OCTOVK_REQUIRE_CONTEXT(ctx);
  const MapParams params = withResolution(0.02);
  OccupancyMap map(ctx, params);
  const std::size_t bytes_before = map.deviceBytes();
  octomap::OcTree oracle = makeOracle(params);
  std::mt19937 rng(8);
  std::uniform_real_distribution<float> u(-1.0f, 1.0f);
  std::vector<Eigen::Vector3f> pts;
  const Eigen::Vector3f origin(0.011f, -0.007f, 0.003f);
  // End points fill a 2 m cube, so that the scan has hundreds of thousands of distinct cells.
  while (pts.size() < 200000) pts.push_back(origin + Eigen::Vector3f(u(rng), u(rng), u(rng)));
  ScanStats stats;
  ASSERT_TRUE(insertBoth(map, oracle, pts, origin, -1.0, false, &stats));
  EXPECT_GT(stats.free_cells + stats.occupied_cells, 800000u);
  EXPECT_GT(oracle.size(), 800000u);
  // 1024 blocks and 2^16 hash slots at first: grown by far more than one step.
  EXPECT_GT(map.deviceBytes(), bytes_before * 8);
  EXPECT_TRUE(test::sameLeaves(oracle, map));
  // And a second, smaller scan into the grown map.
  const auto second = randomScan(rng, Eigen::Vector3f(0.3f, 0.2f, 0.1f), 20000, 1.5f);
  ASSERT_TRUE(insertBoth(map, oracle, second, Eigen::Vector3f(0.3f, 0.2f, 0.1f), -1.0, true));
}

// ---- device selection -------------------------------------------------------------------------

TEST(Context, UnknownSelectorListsTheDevices) {
  OCTOVK_REQUIRE_CONTEXT(ctx);
  ContextOptions options;
  options.selector = "no-such-gpu";
  auto result = Context::create(options);
  ASSERT_FALSE(result);
  EXPECT_EQ(result.error().code(), ErrorCode::kNoDevice);
  const std::string message = result.error().what();
  EXPECT_NE(message.find("no-such-gpu"), std::string::npos) << message;
  const auto devices = Context::listDevices();
  ASSERT_FALSE(devices.empty());
  for (const DeviceInfo& d : devices)
    EXPECT_NE(message.find(d.name), std::string::npos) << "'" << d.name << "' not in: " << message;
  EXPECT_NE(message.find(ctx.device().name), std::string::npos) << message;
  // value() of a failed result throws the error.
  try {
    result.value();
    ADD_FAILURE() << "Result::value() did not throw";
  } catch (const Error& e) {
    EXPECT_EQ(e.code(), ErrorCode::kNoDevice);
  }
  // An index past the end is as unknown as a name.
  options.selector = std::to_string(devices.size() + 5);
  auto by_index = Context::create(options);
  ASSERT_FALSE(by_index);
  EXPECT_EQ(by_index.error().code(), ErrorCode::kNoDevice);
}

// OCTOVK_DEVICE applies when the options name no device.
TEST(Context, EnvironmentVariableSelectsTheDevice) {
  OCTOVK_REQUIRE_CONTEXT(ctx);
  const char* old = std::getenv("OCTOVK_DEVICE");
  const std::string saved = old ? old : "";
  ::setenv("OCTOVK_DEVICE", "no-such-gpu-from-env", 1);
  auto missing = Context::create();
  ::setenv("OCTOVK_DEVICE", ctx.device().name.c_str(), 1);
  auto found = Context::create();
  if (old)
    ::setenv("OCTOVK_DEVICE", saved.c_str(), 1);
  else
    ::unsetenv("OCTOVK_DEVICE");
  ASSERT_FALSE(missing);
  EXPECT_EQ(missing.error().code(), ErrorCode::kNoDevice);
  EXPECT_NE(std::string(missing.error().what()).find("no-such-gpu-from-env"), std::string::npos)
      << missing.error().what();
  EXPECT_NE(std::string(missing.error().what()).find(ctx.device().name), std::string::npos)
      << missing.error().what();
  ASSERT_TRUE(found) << found.error().what();
  EXPECT_EQ(found.value()->device().name, ctx.device().name);
}

TEST(Context, SelectorByNameAndIndexFindsTheDevice) {
  OCTOVK_REQUIRE_CONTEXT(ctx);
  ContextOptions options;
  options.selector = ctx.device().name;
  auto by_name = Context::create(options);
  ASSERT_TRUE(by_name) << by_name.error().what();
  EXPECT_EQ(by_name.value()->device().name, ctx.device().name);
  options.selector = std::to_string(ctx.device().index);
  auto by_index = Context::create(options);
  ASSERT_TRUE(by_index) << by_index.error().what();
  EXPECT_EQ(by_index.value()->device().index, ctx.device().index);
  EXPECT_FALSE(ctx.device().type.empty());
}

// scripts/test.sh runs the suite on more than one driver and names the one each run must get
// (OCTOVK_EXPECT_DRIVER): a run that silently fell back to another driver would prove nothing.
TEST(Context, RunsOnTheDriverTheRunAskedFor) {
  OCTOVK_REQUIRE_CONTEXT(ctx);
  std::printf("device: %s (%s), driver: %s, loop limit: %u (0: none seen)\n",
              ctx.device().name.c_str(), ctx.device().type.c_str(), ctx.device().driver.c_str(),
              ContextAccess::device(ctx).loopLimit());
  EXPECT_FALSE(ctx.device().driver.empty());
  const char* expected = std::getenv("OCTOVK_EXPECT_DRIVER");
  if (expected && *expected) {
    EXPECT_NE(ctx.device().driver.find(expected), std::string::npos)
        << "OCTOVK_EXPECT_DRIVER='" << expected << "' but the device's driver is '"
        << ctx.device().driver << "'";
  }
}

// A validation message reaches the callback of the Context that caused it and is counted (the
// layer comes from vulkan-validationlayers, which scripts/setup.sh installs).
TEST(Context, ValidationMessagesReachTheCallback) {
  OCTOVK_REQUIRE_CONTEXT(ctx);
  std::vector<std::string> messages;
  ContextOptions options;
  options.selector = std::to_string(ctx.device().index);
  options.enable_validation = true;
  options.on_validation_message = [&](const std::string& m) { messages.push_back(m); };
  auto context = Context::create(options);
  ASSERT_TRUE(context) << context.error().what();
  const std::size_t before = validationMessageCount();
  // A deliberate misuse: a buffer of size 0 (VUID-VkBufferCreateInfo-size-00912).
  vk::Device& device = ContextAccess::device(*context.value());
  VkBufferCreateInfo info{VK_STRUCTURE_TYPE_BUFFER_CREATE_INFO};
  info.size = 0;
  info.usage = VK_BUFFER_USAGE_STORAGE_BUFFER_BIT;
  VkBuffer buffer = VK_NULL_HANDLE;
  if (vkCreateBuffer(device.handle(), &info, nullptr, &buffer) == VK_SUCCESS && buffer)
    vkDestroyBuffer(device.handle(), buffer, nullptr);
  ASSERT_FALSE(messages.empty());
  EXPECT_NE(messages.front().find("size"), std::string::npos) << messages.front();
  EXPECT_GT(validationMessageCount(), before);
}

// A map far larger than one descriptor binding may reach: with the binding range forced down to
// 1 MiB, the node pool, cell set and cell list (several MiB each) still work, because they are
// reached by device address; a descriptor range beyond the limit is refused, not bound.
TEST(BindingRange, MapsLargerThanOneBindingWithTheLimitForcedLow) {
  OCTOVK_REQUIRE_CONTEXT(ctx);
  auto small = test::contextWithBindingLimit(ctx, 1u << 20);
  ASSERT_TRUE(small) << small.error().what();
  EXPECT_EQ(ContextAccess::device(*small.value()).maxBindingBytes(), 1u << 20);
  const MapParams params = withResolution(0.01);
  OccupancyMap map(*small.value(), params);
  octomap::OcTree oracle = makeOracle(params);
  std::mt19937 rng(77);
  const Eigen::Vector3f origin(0.1f, -0.2f, 0.3f);
  for (int scan = 0; scan < 2; ++scan) {
    const auto pts = randomScan(rng, origin, 12000, 1.5f);
    ASSERT_TRUE(insertBoth(map, oracle, pts, origin, -1.0, scan == 1)) << "scan " << scan;
  }
  // Beyond 1 MiB of 8-byte nodes.
  EXPECT_GT(map.nodeCount() * sizeof(gpu::Node), std::size_t{2} << 20);
  vk::Buffer big(ContextAccess::device(*small.value()), (1u << 20) + 16, /*host_visible=*/false);
  vk::BindingSet set(ContextAccess::device(*small.value()));
  try {
    set.updateRange(gpu::kBindQueryIn, big.handle(), 0, big.size());
    ADD_FAILURE() << "a range beyond the binding limit was bound";
  } catch (const Error& e) {
    EXPECT_EQ(e.code(), ErrorCode::kInvalidArgument);
    EXPECT_NE(std::string(e.what()).find("maxStorageBufferRange"), std::string::npos) << e.what();
  }
}

// The device probe's verdict: the host's own answers pass; one ULP off in one operation is named
// with its operands. (On the devices the suite runs on, the probe passes at Context creation.)
TEST(DeviceProbe, NamesTheFirstOperationThatDiffers) {
  const std::vector<gpu::ProbeCase> cases = deviceProbeCases();
  ASSERT_EQ(cases.size(), gpu::kProbeCases);
  std::vector<gpu::ProbeResult> results;
  std::vector<std::int32_t> floors;
  for (const gpu::ProbeCase& c : cases) {
    results.push_back(hostProbeResult(c));
    floors.push_back(hostProbeFloor(c));
  }
  EXPECT_EQ(firstProbeMismatch(cases, results, floors), std::nullopt);
  // Ties of the float rounding are among the cases: the host rounds them to even.
  EXPECT_EQ(results[2].rounded, 1.0);
  EXPECT_EQ(results[3].rounded, 1.0 + std::ldexp(1.0, -22));
  auto wrong = results;
  wrong[100].quotient = std::nextafter(wrong[100].quotient, 0.0);
  const auto division = firstProbeMismatch(cases, wrong, floors);
  ASSERT_TRUE(division.has_value());
  EXPECT_EQ(division->rfind("double division of a = ", 0), 0u) << *division;
  wrong = results;
  wrong[7].rounded = std::nextafter(wrong[7].rounded, 1.0);
  const auto rounding = firstProbeMismatch(cases, wrong, floors);
  ASSERT_TRUE(rounding.has_value());
  EXPECT_NE(rounding->find("rounding double to float"), std::string::npos) << *rounding;
  auto bad_floors = floors;
  bad_floors[50] += 1;
  const auto conversion = firstProbeMismatch(cases, results, bad_floors);
  ASSERT_TRUE(conversion.has_value());
  EXPECT_NE(conversion->find("double to int conversion"), std::string::npos) << *conversion;
}

// ---- node count and leaf boxes ------------------------------------------------------------------

// Both ways of keeping the leaf boxes: on demand (the default: the next request after a scan
// rebuilds them) and after every scan.
TEST(Queries, NodeCountAndLeafBoxesMatchOctoMap) {
  OCTOVK_REQUIRE_CONTEXT(ctx);
  for (const auto& [res, every_scan] : std::vector<std::pair<double, bool>>{
           {0.01, false}, {0.05, true}, {0.1, false}, {0.2, true}}) {
    SCOPED_TRACE("resolution " + std::to_string(res) +
                 (every_scan ? ", leaf boxes every scan" : ", leaf boxes on demand"));
    const MapParams params = withResolution(res);
    OccupancyMap map(ctx, params);
    if (every_scan) map.setLeafBoxesEveryScan(true);
    octomap::OcTree oracle = makeOracle(params);
    EXPECT_EQ(map.nodeCount(), 0u);
    EXPECT_TRUE(map.downloadLeafBoxes().empty());
    std::mt19937 rng(static_cast<unsigned>(res * 1000));
    const float radius = static_cast<float>(res * 25);
    for (int scan = 0; scan < 12; ++scan) {
      // Alternate sides of the origin, so leaves have negative and positive coordinates, and
      // repeat scans so that pruned leaves (depth < 16) appear.
      const float s = (scan % 2) ? -1.0f : 1.0f;
      const Eigen::Vector3f origin(s * 0.3f * radius, 0.1f * radius, -0.2f * radius);
      std::mt19937 scan_rng(scan % 4);
      const auto pts = randomScan(scan % 3 == 0 ? rng : scan_rng, origin, 300, radius);
      ScanStats stats;
      ASSERT_TRUE(insertBoth(map, oracle, pts, origin, -1.0, false, &stats)) << "scan " << scan;
      // The rebuild is timed only when it runs as part of the scan.
      if (every_scan)
        EXPECT_GT(stats.device.leaf_boxes_ms, 0.0);
      else
        EXPECT_EQ(stats.device.leaf_boxes_ms, 0.0);
      EXPECT_EQ(map.nodeCount(), oracle.size());
      EXPECT_EQ(map.leafCount(), oracle.getNumLeafNodes());
      ASSERT_TRUE(test::sameLeaves(oracle, map)) << "scan " << scan;
    }
    std::size_t coarse = 0;
    for (const auto& b : map.downloadLeafBoxes())
      if (b.size > static_cast<float>(res) * 1.5f) ++coarse;
    EXPECT_GT(coarse, 0u) << "no pruned leaf was exercised";
  }
}

TEST(Queries, SingleCellTreeHasOneLeafBox) {
  OCTOVK_REQUIRE_CONTEXT(ctx);
  const MapParams params = withResolution(0.1);
  OccupancyMap map(ctx, params);
  octomap::OcTree oracle = makeOracle(params);
  // Origin and end point in the same cell: no free cells, one occupied cell (17 nodes).
  const std::vector<Eigen::Vector3f> pts = {{-0.01f, -0.02f, -0.03f}};
  ASSERT_TRUE(insertBoth(map, oracle, pts, Eigen::Vector3f(-0.05f, -0.05f, -0.05f), -1.0, false));
  EXPECT_EQ(map.nodeCount(), 17u);
  const auto boxes = map.downloadLeafBoxes();
  ASSERT_EQ(boxes.size(), 1u);
  EXPECT_FLOAT_EQ(boxes[0].size, 0.1f);
  EXPECT_EQ(boxes[0].center[0], -0.05f);
  EXPECT_EQ(boxes[0].log_odds, octomap::logodds(0.7));
  EXPECT_TRUE(test::sameLeaves(oracle, map));
}

}  // namespace
}  // namespace octovk::test

namespace octovk::test {
namespace {

// The public key helpers are OctoMap's coordToKeyChecked and keyToCoord at the finest depth, bit
// for bit, at the map's edges, on cell borders, and for NaN and out-of-range coordinates.
TEST(KeyHelpers, AreOctoMapsCoordToKeyCheckedAndKeyToCoord) {
  for (const double resolution : {0.05, 0.1, 0.08, 1.0 / 3.0}) {
    octomap::OcTree tree(resolution);
    std::mt19937 rng(static_cast<unsigned>(resolution * 1000));
    const float edge = static_cast<float>(32768 * resolution);
    std::uniform_real_distribution<float> u(-1.01f * edge, 1.01f * edge);
    std::vector<Eigen::Vector3f> points = {
        {0, 0, 0},
        {-0.0f, 1e-30f, -1e-30f},
        {static_cast<float>(resolution), static_cast<float>(-resolution), 0.5f},
        {edge, -edge, std::nextafter(edge, 0.0f)},
        {std::numeric_limits<float>::quiet_NaN(), 0, 0},
        {0, std::numeric_limits<float>::infinity(), 0}};
    for (int i = 0; i < 20000; ++i) points.push_back({u(rng), u(rng), u(rng)});
    for (const Eigen::Vector3f& p : points) {
      octomap::OcTreeKey expected;
      const bool inside = tree.coordToKeyChecked(octomap::point3d(p.x(), p.y(), p.z()), expected);
      const std::optional<Key> key = coordToKey(resolution, p);
      ASSERT_EQ(key.has_value(), inside) << p.transpose() << " at " << resolution;
      if (!inside) continue;
      for (int a = 0; a < 3; ++a) ASSERT_EQ((*key)[a], expected[a]) << p.transpose();
      const octomap::point3d centre = tree.keyToCoord(expected);
      const Eigen::Vector3f ours = keyToCoord(resolution, *key);
      for (int a = 0; a < 3; ++a)
        ASSERT_EQ(test::floatBits(ours[a]), test::floatBits(centre(a))) << p.transpose();
    }
  }
}

}  // namespace
}  // namespace octovk::test
