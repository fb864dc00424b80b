// Oracle tests: the same scans into OctoMap and into octovk; after every scan the trees must be
// equal node by node with bit-identical log-odds.
#include <octomap/octomap.h>

#include <cmath>
#include <fstream>

#include "map/context_access.hpp"
#include "test_support.hpp"

namespace octovk::test {
namespace {

std::vector<Eigen::Vector3f> randomScan(std::mt19937& rng, const Eigen::Vector3f& origin,
                                        std::size_t n, float radius) {
  std::uniform_real_distribution<float> u(-1.0f, 1.0f);
  std::uniform_real_distribution<float> r(0.2f * radius, radius);
  std::vector<Eigen::Vector3f> pts;
  for (std::size_t i = 0; i < n; ++i) {
    Eigen::Vector3f d(u(rng), u(rng), u(rng));
    if (d.norm() < 1e-3f) continue;
    d.normalize();
    pts.push_back(origin + d * r(rng));
  }
  return pts;
}

// ---- random scans over seeds, resolutions, max range and discretize --------------------------

struct ScanCase {
  unsigned seed;
  double resolution;
  double max_range;  // in cells; < 0: unlimited
  bool discretize;
};

void PrintTo(const ScanCase& c, std::ostream* os) {
  *os << "seed " << c.seed << ", resolution " << c.resolution << ", max range " << c.max_range
      << " cells, discretize " << c.discretize;
}

std::string caseName(const ::testing::TestParamInfo<ScanCase>& info) {
  const ScanCase& c = info.param;
  return "seed" + std::to_string(c.seed) + "_res" +
         std::to_string(static_cast<int>(std::lround(c.resolution * 1000))) + "mm_" +
         (c.max_range < 0 ? "unlimited" : "maxrange") + (c.discretize ? "_discretize" : "");
}

std::vector<ScanCase> randomCases() {
  std::vector<ScanCase> cases;
  unsigned seed = 1;
  for (double res : {0.01, 0.02, 0.05, 0.1, 0.2})
    for (double max_range : {-1.0, 25.0})
      for (bool discretize : {false, true})
        for (int rep = 0; rep < 2; ++rep) cases.push_back({seed++, res, max_range, discretize});
  return cases;
}

class RandomScans : public ::testing::TestWithParam<ScanCase> {};

TEST_P(RandomScans, EqualsOctoMapAfterEveryScan) {
  OCTOVK_REQUIRE_CONTEXT(ctx);
  const ScanCase c = GetParam();
  const MapParams params = withResolution(c.resolution);
  OccupancyMap map(ctx, params);
  octomap::OcTree oracle = makeOracle(params);
  std::mt19937 rng(c.seed);
  // Points reach 40 cells: with a max range of 25 cells a good part lies beyond it.
  const float radius = static_cast<float>(c.resolution * 40);
  const double max_range = c.max_range < 0 ? -1.0 : c.max_range * c.resolution;
  std::size_t beyond = 0;
  for (int scan = 0; scan < 6; ++scan) {
    // A few origins repeat so that cells reach the clamping bounds (early abort, pruning).
    const Eigen::Vector3f origin(static_cast<float>(c.resolution * (scan % 2)),
                                 static_cast<float>(-c.resolution * 0.5 * (scan % 3)), 0.25f);
    const auto pts = randomScan(rng, origin, 400, radius);
    for (const auto& p : pts)
      if (max_range >= 0 && (p - origin).norm() > max_range) ++beyond;
    ASSERT_TRUE(insertBoth(map, oracle, pts, origin, max_range, c.discretize))
        << "after scan " << scan;
    ASSERT_EQ(map.nodeCount(), oracle.size());
  }
  if (max_range >= 0) {
    EXPECT_GT(beyond, 100u);
  }
  EXPECT_GT(oracle.size(), 100u);
}

INSTANTIATE_TEST_SUITE_P(Seeds, RandomScans, ::testing::ValuesIn(randomCases()), caseName);

// ---- origins on voxel borders and at cell centres; rays along axes and diagonals -------------

std::vector<Eigen::Vector3f> axisAndDiagonalRays(const Eigen::Vector3f& origin, float res) {
  std::vector<Eigen::Vector3f> pts;
  for (int len : {3, 7, 12}) {
    const float d = static_cast<float>(len) * res;
    for (int sx = -1; sx <= 1; ++sx)
      for (int sy = -1; sy <= 1; ++sy)
        for (int sz = -1; sz <= 1; ++sz) {
          if (sx == 0 && sy == 0 && sz == 0) continue;
          // Axes (one non-zero), face diagonals (two) and space diagonals (three).
          pts.push_back(origin + Eigen::Vector3f(static_cast<float>(sx) * d,
                                                 static_cast<float>(sy) * d,
                                                 static_cast<float>(sz) * d));
        }
  }
  // End points exactly on voxel borders and at cell centres, in absolute terms.
  for (int k = -6; k <= 6; k += 3) {
    pts.emplace_back(static_cast<float>(k) * res, 0.0f, static_cast<float>(-k) * res);
    pts.emplace_back((static_cast<float>(k) + 0.5f) * res, (static_cast<float>(k) + 0.5f) * res,
                     0.5f * res);
  }
  return pts;
}

class GridAlignedRays : public ::testing::TestWithParam<double> {};

TEST_P(GridAlignedRays, OriginsOnBordersAndCentres) {
  OCTOVK_REQUIRE_CONTEXT(ctx);
  const double res = GetParam();
  const MapParams params = withResolution(res);
  for (bool discretize : {false, true}) {
    SCOPED_TRACE(discretize ? "discretize" : "no discretize");
    OccupancyMap map(ctx, params);
    octomap::OcTree oracle = makeOracle(params);
    std::vector<Eigen::Vector3f> origins;
    for (int k : {0, 1, -1, 7, -13, 256}) {
      // Exactly k * resolution (a border in exact arithmetic), and the cell centre next to it.
      const float b = static_cast<float>(k * res);
      const float c = static_cast<float>((k + 0.5) * res);
      origins.emplace_back(b, b, b);
      origins.emplace_back(c, c, c);
      origins.emplace_back(b, c, -b);
    }
    const float fres = static_cast<float>(res);
    for (std::size_t i = 0; i < origins.size(); ++i) {
      const Eigen::Vector3f& o = origins[i];
      const double max_range = (i % 3 == 2) ? 8.0 * res : -1.0;
      ASSERT_TRUE(insertBoth(map, oracle, axisAndDiagonalRays(o, fres), o, max_range, discretize))
          << "origin " << i << " (" << o.transpose() << ")";
    }
  }
}

INSTANTIATE_TEST_SUITE_P(Resolutions, GridAlignedRays,
                         ::testing::Values(0.01, 0.02, 0.05, 0.1, 0.2),
                         [](const ::testing::TestParamInfo<double>& info) {
                           return "res" + std::to_string(std::lround(info.param * 1000)) + "mm";
                         });

// ---- clamping, early abort, expansion of pruned nodes, pruning -------------------------------

// A dense wall in front of the sensor: the free cone fills whole octants, which prune once clamped.
std::vector<Eigen::Vector3f> wallScan(const Eigen::Vector3f& origin, float res, float distance,
                                      float half_width) {
  std::vector<Eigen::Vector3f> pts;
  const float step = res * 0.5f;
  for (float y = -half_width; y <= half_width; y += step)
    for (float z = -half_width; z <= half_width; z += step)
      pts.push_back(origin + Eigen::Vector3f(distance, y, z));
  return pts;
}

struct RepeatCase {
  double resolution;
  bool discretize;
  double max_range;  // in metres
};

void PrintTo(const RepeatCase& c, std::ostream* os) {
  *os << "resolution " << c.resolution << ", max range " << c.max_range << ", discretize "
      << c.discretize;
}

class RepeatedScans : public ::testing::TestWithParam<RepeatCase> {};

TEST_P(RepeatedScans, ClampEarlyAbortPruneAndExpand) {
  OCTOVK_REQUIRE_CONTEXT(ctx);
  const RepeatCase c = GetParam();
  const MapParams params = withResolution(c.resolution);
  OccupancyMap map(ctx, params);
  octomap::OcTree oracle = makeOracle(params);
  const float res = static_cast<float>(c.resolution);
  const Eigen::Vector3f origin(0.5f * res, 0.5f * res, 0.5f * res);
  const auto wall = wallScan(origin, res, 16 * res, 8 * res);
  std::size_t aborted = 0, listed = 0;
  for (int rep = 0; rep < 16; ++rep) {
    ScanStats stats;
    ASSERT_TRUE(insertBoth(map, oracle, wall, origin, c.max_range, c.discretize, &stats))
        << "repetition " << rep;
    aborted = stats.aborted_cells;
    listed = stats.free_cells + stats.occupied_cells;
  }
  // After 16 identical scans every touched cell sits at a clamping bound: all are aborted.
  EXPECT_GT(aborted, 0u);
  EXPECT_EQ(aborted, listed);
  std::size_t pruned_free = 0, clamped_occupied = 0;
  for (auto it = oracle.begin_leafs(), end = oracle.end_leafs(); it != end; ++it) {
    if (it.getDepth() < 16 && it->getLogOdds() == oracle.getClampingThresMinLog()) ++pruned_free;
    if (it->getLogOdds() == oracle.getClampingThresMaxLog()) ++clamped_occupied;
  }
  // Clamped free space is pruned into inner-depth leaves; the wall is clamped occupied.
  EXPECT_GT(pruned_free, 0u);
  EXPECT_GT(clamped_occupied, 0u);

  // Another origin whose rays cross the pruned region: free updates there abort early, the end
  // points inside it expand pruned nodes.
  const Eigen::Vector3f other(8 * res, -6 * res, 3 * res);
  std::vector<Eigen::Vector3f> cross;
  for (int i = 0; i < 40; ++i) {
    const float t = static_cast<float>(i) / 40.0f;
    cross.push_back(origin + Eigen::Vector3f((4 + 10 * t) * res, (-4 + 8 * t) * res, 2 * res));
    cross.push_back(other + Eigen::Vector3f(-20 * res, (12 - 24 * t) * res, (3 - 6 * t) * res));
  }
  std::size_t in_pruned = 0;
  for (const auto& p : cross) {
    const octomap::OcTreeNode* n = oracle.search(toPoint(p));
    if (n && n == oracle.search(toPoint(p), 15)) ++in_pruned;
  }
  EXPECT_GT(in_pruned, 0u) << "no end point of the crossing scan falls in a pruned node";
  for (int rep = 0; rep < 3; ++rep)
    ASSERT_TRUE(insertBoth(map, oracle, cross, other, c.max_range, c.discretize))
        << "crossing scan " << rep;
  // And back to the first origin: the expanded nodes get cleared and pruned again.
  for (int rep = 0; rep < 6; ++rep)
    ASSERT_TRUE(insertBoth(map, oracle, wall, origin, c.max_range, c.discretize))
        << "wall again, repetition " << rep;
}

INSTANTIATE_TEST_SUITE_P(Cases, RepeatedScans,
                         ::testing::Values(RepeatCase{0.1, false, -1.0},
                                           RepeatCase{0.05, true, -1.0},
                                           RepeatCase{0.02, false, 0.5},
                                           RepeatCase{0.2, false, -1.0},
                                           RepeatCase{0.01, true, -1.0}),
                         [](const ::testing::TestParamInfo<RepeatCase>& info) {
                           const RepeatCase& c = info.param;
                           return "res" + std::to_string(std::lround(c.resolution * 1000)) + "mm" +
                                  (c.max_range < 0 ? "" : "_maxrange") +
                                  (c.discretize ? "_discretize" : "");
                         });

// ---- degenerate geometry ------------------------------------------------------------------------

TEST(EdgeCases, ZeroRangePointsAtOriginSignedZeroAndTinyOffsets) {
  OCTOVK_REQUIRE_CONTEXT(ctx);
  for (double res : {0.2, 0.05, 0.01}) {
    SCOPED_TRACE("resolution " + std::to_string(res));
    const MapParams params = withResolution(res);
    OccupancyMap map(ctx, params);
    octomap::OcTree oracle = makeOracle(params);
    const float r = static_cast<float>(res);
    const Eigen::Vector3f origin(0.0f, -0.0f, 0.0f);
    const std::vector<Eigen::Vector3f> pts = {
        origin,                 // the origin itself: occupied, no ray
        {-0.0f, -0.0f, -0.0f},  // signed zeros
        {0.0f, 0.0f, -0.0f},
        {0.5f * r, 0.5f * r, 0.5f * r},     // same cell as the origin
        {-0.5f * r, -0.5f * r, -0.5f * r},  // the neighbouring cell across all borders
        {1e-7f, -1e-7f, 1e-7f},             // tiny offsets across the borders at 0
        {r, 0.0f, 0.0f},
        {-r, 0.0f, 0.0f},
        {40 * r, -3 * r, 0.0f},
    };
    // Max range 0 clips every ray to nothing; half a cell and three cells clip most.
    for (double max_range : {-1.0, 0.0, 0.5 * res, 3.0 * res})
      for (bool discretize : {false, true})
        ASSERT_TRUE(insertBoth(map, oracle, pts, origin, max_range, discretize))
            << "max range " << max_range << (discretize ? ", discretize" : "");
  }
}

// Lavapipe stops a shader's loops after 65535 iterations; octovk refuses a scan whose rays that
// limit would cut (kMissingFeature naming the device, map unchanged) rather than insert part of
// it. That refusal is accepted on llvmpipe only; everywhere else the scan must match OctoMap.
::testing::AssertionResult insertBothUnlessRefused(Context& ctx, OccupancyMap& map,
                                                   octomap::OcTree& oracle,
                                                   const std::vector<Eigen::Vector3f>& points,
                                                   const Eigen::Vector3f& origin, double max_range,
                                                   bool discretize, std::size_t* refusals) {
  const std::string before = test::otBytes(*toOcTree(map));
  try {
    map.insertPointCloud(points, origin, {.max_range_m = max_range, .discretize = discretize});
  } catch (const Error& e) {
    if (e.code() != ErrorCode::kMissingFeature ||
        ctx.device().name.find("llvmpipe") == std::string::npos)
      return ::testing::AssertionFailure() << "insertPointCloud threw: " << e.what();
    if (std::string(e.what()).find(ctx.device().name) == std::string::npos)
      return ::testing::AssertionFailure() << "refusal does not name the device: " << e.what();
    if (test::otBytes(*toOcTree(map)) != before)
      return ::testing::AssertionFailure() << "the refused scan changed the map";
    ++*refusals;
    return ::testing::AssertionSuccess();
  }
  oracle.insertPointCloud(toPointcloud(points), toPoint(origin), max_range, false, discretize);
  return sameTree(oracle, *toOcTree(map));
}

// Rays thousands of cells long, across half the map: along an axis, a face diagonal and a general
// direction, in both senses, and from a far corner back to the centre.
TEST(EdgeCases, LongRaysAcrossHalfTheMap) {
  OCTOVK_REQUIRE_CONTEXT(ctx);
  std::size_t refusals = 0;
  for (double res : {0.2, 0.05}) {
    SCOPED_TRACE("resolution " + std::to_string(res));
    const MapParams params = withResolution(res);
    OccupancyMap map(ctx, params);
    octomap::OcTree oracle = makeOracle(params);
    const float r = static_cast<float>(res);
    const Eigen::Vector3f origin(0.0f, -0.0f, 0.0f);
    const float far = static_cast<float>(32768 * res) - 3.0f * r;
    std::vector<Eigen::Vector3f> pts;
    for (float f : {far, -far}) {
      pts.emplace_back(f, 0.0f, 0.0f);
      pts.emplace_back(f * 0.5f, f * 0.5f, 0.0f);
      pts.emplace_back(f * 0.31f, -f * 0.17f, f * 0.05f);
    }
    // Each ray alone (up to 32,766 cells), then all six in one scan.
    for (const auto& p : pts)
      ASSERT_TRUE(insertBothUnlessRefused(ctx, map, oracle, {p}, origin, -1.0, false, &refusals))
          << "ray to " << p.transpose();
    for (double max_range : {-1.0, 1000.0 * res})
      for (bool discretize : {false, true})
        ASSERT_TRUE(insertBothUnlessRefused(ctx, map, oracle, pts, origin, max_range, discretize,
                                            &refusals))
            << "max range " << max_range << (discretize ? ", discretize" : "");
    // From a far corner of the map back to the centre: 3 * 32765 cells (OctoMap's KeyRay holds at
    // most 100,000, so no ray may cross the whole map).
    const Eigen::Vector3f corner(far, far, -far);
    const std::vector<Eigen::Vector3f> centre = {{0.0f, 0.0f, 0.0f}, {-r, r, -r}};
    ASSERT_TRUE(insertBothUnlessRefused(ctx, map, oracle, centre, corner, -1.0, false, &refusals));
  }
  RecordProperty("refused_scans", static_cast<int>(refusals));
}

// The smallest inputs with rays longer than 32768 cells (valid for OctoMap, whose rays may have
// up to 100,000 cells), and two rays of 32,766 cells in one scan.
TEST(EdgeCases, RaysOfMoreThan32768Cells) {
  OCTOVK_REQUIRE_CONTEXT(ctx);
  const MapParams params = withResolution(0.2);
  std::size_t refusals = 0;
  {
    SCOPED_TRACE("one ray of 64,999 cells along x");
    OccupancyMap map(ctx, params);
    octomap::OcTree oracle = makeOracle(params);
    EXPECT_TRUE(insertBothUnlessRefused(ctx, map, oracle, {{6500.0f, 0.1f, 0.1f}},
                                        Eigen::Vector3f(-6500.0f, 0.1f, 0.1f), -1.0, false,
                                        &refusals));
  }
  {
    SCOPED_TRACE("two rays of 32,766 cells along the xy diagonals");
    OccupancyMap map(ctx, params);
    octomap::OcTree oracle = makeOracle(params);
    EXPECT_TRUE(insertBothUnlessRefused(ctx, map, oracle,
                                        {{-3276.5f, -3276.5f, 0.0f}, {3276.5f, 3276.5f, 0.0f}},
                                        Eigen::Vector3f::Zero(), -1.0, false, &refusals));
  }
  RecordProperty("refused_scans", static_cast<int>(refusals));
}

// Bigger scans: many rays share cells, deep trees at several origins.
class LargeRandomScans : public ::testing::TestWithParam<unsigned> {};

TEST_P(LargeRandomScans, EqualsOctoMapAfterEveryScan) {
  OCTOVK_REQUIRE_CONTEXT(ctx);
  const unsigned seed = GetParam();
  const double res = seed % 2 ? 0.05 : 0.02;
  const MapParams params = withResolution(res);
  OccupancyMap map(ctx, params);
  octomap::OcTree oracle = makeOracle(params);
  std::mt19937 rng(seed);
  std::uniform_real_distribution<float> u(-1.0f, 1.0f);
  const float radius = static_cast<float>(res * 60);
  Eigen::Vector3f origin(0.0f, 0.0f, 0.0f);
  for (int scan = 0; scan < 10; ++scan) {
    if (scan % 3 == 0) origin = Eigen::Vector3f(u(rng), u(rng), u(rng)) * (radius * 0.5f);
    const auto pts = randomScan(rng, origin, 4000, radius);
    const double max_range = scan % 4 == 1 ? 0.7 * radius : -1.0;
    ASSERT_TRUE(insertBoth(map, oracle, pts, origin, max_range, scan % 5 == 4))
        << "after scan " << scan;
  }
  EXPECT_TRUE(test::sameLeaves(oracle, map));
}

INSTANTIATE_TEST_SUITE_P(Seeds, LargeRandomScans, ::testing::Values(101u, 102u, 103u, 104u));

// ---- growth of the scan's sets -----------------------------------------------------------------

// Where the driver ends shader loops early (Mesa 22.3's llvmpipe), a walk is saved between rounds
// in lists that start at 256 walks (most scans leave none unfinished). 300 rays each longer than
// a round (about 43,000 steps along a diagonal, a round takes 30,000 iterations) leave more: the
// scan is refused, the lists grow and it runs again, once; the map is OctoMap's. Elsewhere every
// walk ends in one go and the scan runs once.
TEST(SetGrowth, MoreUnfinishedWalksThanTheListsHoldGrowThem) {
  OCTOVK_REQUIRE_CONTEXT(ctx);
  const double res = 0.2;
  const MapParams params = withResolution(res);
  OccupancyMap map(ctx, params);
  octomap::OcTree oracle = makeOracle(params);
  // Two ends 5 km away, 150 rays to each: few distinct cells, many long walks.
  const Eigen::Vector3f origin(0.1f, 0.1f, 0.1f);
  std::vector<Eigen::Vector3f> pts;
  for (int i = 0; i < 300; ++i)
    pts.push_back(i % 2 ? Eigen::Vector3f(2880.3f, 2870.1f, 2860.7f)
                        : Eigen::Vector3f(-2850.9f, 2890.2f, -2875.4f));
  // First 200 of them, which the lists hold (the sets grow for their cells), then all 300.
  const std::vector<Eigen::Vector3f> fewer(pts.begin(), pts.begin() + 200);
  ScanStats few, first, second;
  ASSERT_TRUE(insertBoth(map, oracle, fewer, origin, -1.0, false, &few));
  ASSERT_TRUE(insertBoth(map, oracle, pts, origin, -1.0, false, &first));
  ASSERT_TRUE(insertBoth(map, oracle, pts, origin, -1.0, false, &second));
  EXPECT_TRUE(sameTree(oracle, *toOcTree(map)));
  const bool limited = ContextAccess::device(ctx).loopLimit() != 0;
  EXPECT_EQ(first.cell_set_attempts, limited ? 2u : 1u) << "300 walks: refused for its walks";
  EXPECT_EQ(second.cell_set_attempts, 1u) << "the lists grown for 300 walks hold them";
}

// Few points with long rays touch far more cells than the first guess of the cell set (16 slots
// per point): the set grows, the ray pass is redone, and the map is the same as OctoMap's.
TEST(SetGrowth, LongRaysFromFewPointsGrowTheCellSet) {
  OCTOVK_REQUIRE_CONTEXT(ctx);
  const MapParams params = withResolution(0.05);
  OccupancyMap map(ctx, params);
  octomap::OcTree oracle = makeOracle(params);
  std::mt19937 rng(5);
  std::uniform_real_distribution<float> u(-1.0f, 1.0f);
  const Eigen::Vector3f origin(0.01f, 0.02f, -0.03f);
  for (int scan = 0; scan < 3; ++scan) {
    std::vector<Eigen::Vector3f> pts;
    for (int i = 0; i < 40 * (scan + 1); ++i) {
      Eigen::Vector3f d(u(rng), u(rng), u(rng));
      pts.push_back(origin + d.normalized() * (20.0f + 10.0f * u(rng)));
    }
    ScanStats stats;
    ASSERT_TRUE(insertBoth(map, oracle, pts, origin, -1.0, false, &stats)) << "scan " << scan;
    // About 400-900 cells per ray against 16 slots per point.
    if (scan == 0) {
      EXPECT_GT(stats.cell_set_attempts, 1u);
    }
    EXPECT_GT(stats.free_cells, pts.size() * 300);
  }
}

// A bundle of rays one cell apart at its far end fills its bricks densely: the scan has many
// more cells than the first guess of the cell list (16 per point) while its bricks fit the set.
// The list outgrows its buffer, the sets grow, the ray pass is redone.
TEST(SetGrowth, DenseBundleOfRaysOutgrowsTheCellList) {
  OCTOVK_REQUIRE_CONTEXT(ctx);
  const MapParams params = withResolution(0.05);
  OccupancyMap map(ctx, params);
  octomap::OcTree oracle = makeOracle(params);
  const Eigen::Vector3f origin(0.01f, 0.02f, 0.03f);
  std::vector<Eigen::Vector3f> pts;
  for (int j = 0; j < 32; ++j)
    for (int k = 0; k < 32; ++k)
      pts.emplace_back(3.2f, -0.8f + 0.05f * static_cast<float>(j) + 0.013f,
                       -0.8f + 0.05f * static_cast<float>(k) + 0.021f);
  ScanStats stats;
  ASSERT_TRUE(insertBoth(map, oracle, pts, origin, -1.0, false, &stats));
  EXPECT_GT(stats.free_cells, pts.size() * 16);
  EXPECT_GT(stats.cell_set_attempts, 1u);
}

// More distinct cells than one row of 65535 workgroups of 64 covers (4,194,240, lavapipe's
// limit in x): the lists of the scan are walked by indirect dispatches folded into y.
TEST(SetGrowth, MoreCellsThanOneRowOfWorkgroups) {
  OCTOVK_REQUIRE_CONTEXT(ctx);
  const MapParams params = withResolution(0.05);
  OccupancyMap map(ctx, params);
  octomap::OcTree oracle = makeOracle(params);
  std::mt19937 rng(11);
  std::normal_distribution<float> n(0.0f, 1.0f);
  const Eigen::Vector3f origin(0.01f, 0.02f, 0.03f);
  std::vector<Eigen::Vector3f> pts;
  for (int i = 0; i < 12000; ++i) {
    const Eigen::Vector3f d(n(rng), n(rng), n(rng));
    pts.push_back(origin + d.normalized() * 20.0f);
  }
  ScanStats stats;
  ASSERT_TRUE(insertBoth(map, oracle, pts, origin, -1.0, false, &stats));
  EXPECT_GT(stats.free_cells, 4194240u);
}

// ---- conflicts within one scan ---------------------------------------------------------------

TEST(Conflicts, OccupiedWinsOverFreeInOneScan) {
  OCTOVK_REQUIRE_CONTEXT(ctx);
  for (bool discretize : {false, true}) {
    SCOPED_TRACE(discretize ? "discretize" : "no discretize");
    const MapParams params = withResolution(0.05);
    OccupancyMap map(ctx, params);
    octomap::OcTree oracle = makeOracle(params);
    std::mt19937 rng(77);
    std::uniform_real_distribution<float> u(-1.0f, 1.0f);
    const Eigen::Vector3f origin(0.013f, -0.021f, 0.4f);
    for (int scan = 0; scan < 5; ++scan) {
      std::vector<Eigen::Vector3f> pts;
      for (int i = 0; i < 150; ++i) {
        Eigen::Vector3f d(u(rng), u(rng), u(rng));
        d.normalize();
        // Several points on one ray: the near ones' end cells are crossed by the far ones' rays.
        for (float r : {0.3f, 0.55f, 0.8f, 1.2f}) pts.push_back(origin + d * r);
      }
      ScanStats stats;
      ASSERT_TRUE(insertBoth(map, oracle, pts, origin, -1.0, discretize, &stats))
          << "scan " << scan;
      EXPECT_GT(stats.occupied_cells, 0u);
    }
    auto ours = toOcTree(map);
    std::size_t occupied = 0;
    for (auto it = ours->begin_leafs(), end = ours->end_leafs(); it != end; ++it)
      if (ours->isNodeOccupied(*it)) ++occupied;
    EXPECT_GT(occupied, 100u);
  }
}

TEST(Conflicts, FarPointBehindNearPointOnOneLine) {
  OCTOVK_REQUIRE_CONTEXT(ctx);
  const MapParams params = withResolution(0.1);
  OccupancyMap map(ctx, params);
  octomap::OcTree oracle = makeOracle(params);
  const Eigen::Vector3f origin(0.05f, 0.05f, 0.05f);
  const std::vector<Eigen::Vector3f> pts = {{1.05f, 0.05f, 0.05f}, {0.55f, 0.05f, 0.05f},
                                            {0.05f, 1.05f, 0.05f}, {0.05f, 0.35f, 0.05f},
                                            {0.75f, 0.75f, 0.75f}, {0.35f, 0.35f, 0.35f}};
  ASSERT_TRUE(insertBoth(map, oracle, pts, origin, -1.0, false));
  auto ours = toOcTree(map);
  for (const Eigen::Vector3f& p : {pts[1], pts[3], pts[5]}) {
    const octomap::OcTreeNode* n = ours->search(toPoint(p));
    ASSERT_NE(n, nullptr);
    EXPECT_EQ(n->getLogOdds(), octomap::logodds(0.7)) << "at " << p.transpose();
  }
}

TEST(Conflicts, ManyPointsInOneCell) {
  OCTOVK_REQUIRE_CONTEXT(ctx);
  for (bool discretize : {false, true}) {
    SCOPED_TRACE(discretize ? "discretize" : "no discretize");
    const MapParams params = withResolution(0.05);
    OccupancyMap map(ctx, params);
    octomap::OcTree oracle = makeOracle(params);
    std::mt19937 rng(5);
    std::uniform_real_distribution<float> jitter(0.0005f, 0.0495f);
    const Eigen::Vector3f origin(-0.31f, 0.12f, 0.07f);
    for (int scan = 0; scan < 4; ++scan) {
      std::vector<Eigen::Vector3f> pts;
      // 2000 points inside the cell [1.0, 1.05) x [0.5, 0.55) x [0.2, 0.25), plus a few others.
      for (int i = 0; i < 2000; ++i)
        pts.emplace_back(1.0f + jitter(rng), 0.5f + jitter(rng), 0.2f + jitter(rng));
      for (int i = 0; i < 20; ++i)
        pts.emplace_back(-1.0f + 0.1f * static_cast<float>(i), -0.7f, 0.3f);
      ScanStats stats;
      ASSERT_TRUE(insertBoth(map, oracle, pts, origin, -1.0, discretize, &stats))
          << "scan " << scan;
      EXPECT_EQ(stats.occupied_cells, 21u);
    }
  }
}

// ---- the pose overload -----------------------------------------------------------------------

Eigen::Quaternionf randomRotation(std::mt19937& rng) {
  std::normal_distribution<float> n(0.0f, 1.0f);
  Eigen::Quaternionf q(n(rng), n(rng), n(rng), n(rng));
  q.normalize();
  return q;
}

struct PoseCase {
  unsigned seed;
  double resolution;
  double max_range;
  bool discretize;
};

void PrintTo(const PoseCase& c, std::ostream* os) {
  *os << "seed " << c.seed << ", resolution " << c.resolution << ", max range " << c.max_range
      << ", discretize " << c.discretize;
}

class PoseOverload : public ::testing::TestWithParam<PoseCase> {};

TEST_P(PoseOverload, EqualsOctoMapFrameOriginInsert) {
  OCTOVK_REQUIRE_CONTEXT(ctx);
  const PoseCase c = GetParam();
  const MapParams params = withResolution(c.resolution);
  OccupancyMap map(ctx, params);
  octomap::OcTree oracle = makeOracle(params);
  std::mt19937 rng(c.seed);
  std::uniform_real_distribution<float> t(-1.0f, 1.0f);
  const float radius = static_cast<float>(c.resolution * 30);
  for (int scan = 0; scan < 6; ++scan) {
    Pose pose;
    pose.rotation = randomRotation(rng);
    pose.translation = Eigen::Vector3f(t(rng), t(rng), t(rng)) * (radius * 0.3f);
    const Eigen::Vector3f origin_sensor(t(rng) * 0.1f, t(rng) * 0.1f, t(rng) * 0.1f);
    const auto pts = randomScan(rng, origin_sensor, 400, radius);
    oracle.insertPointCloud(toPointcloud(pts), toPoint(origin_sensor), test::toPose6D(pose),
                            c.max_range, false, c.discretize);
    const ScanStats stats = map.insertPointCloud(
        pts, origin_sensor, pose, {.max_range_m = c.max_range, .discretize = c.discretize});
    EXPECT_EQ(stats.points, pts.size());
    EXPECT_EQ(stats.nodes, oracle.size());
    auto ours = toOcTree(map);
    ASSERT_TRUE(sameTree(oracle, *ours)) << "after scan " << scan;
  }
}

INSTANTIATE_TEST_SUITE_P(Seeds, PoseOverload,
                         ::testing::Values(PoseCase{11, 0.1, -1.0, false},
                                           PoseCase{12, 0.05, 1.0, false},
                                           PoseCase{13, 0.02, -1.0, true},
                                           PoseCase{14, 0.2, 4.0, true},
                                           PoseCase{15, 0.01, -1.0, false}),
                         [](const ::testing::TestParamInfo<PoseCase>& info) {
                           const PoseCase& c = info.param;
                           return "seed" + std::to_string(c.seed) + "_res" +
                                  std::to_string(std::lround(c.resolution * 1000)) + "mm" +
                                  (c.max_range < 0 ? "" : "_maxrange") +
                                  (c.discretize ? "_discretize" : "");
                         });

// ---- non-default sensor models ---------------------------------------------------------------

struct ModelCase {
  double prob_hit, prob_miss, clamping_min, clamping_max;
};

void PrintTo(const ModelCase& m, std::ostream* os) {
  *os << "prob_hit " << m.prob_hit << ", prob_miss " << m.prob_miss << ", clamping "
      << m.clamping_min << " .. " << m.clamping_max;
}

std::string modelName(const ::testing::TestParamInfo<ModelCase>& info) {
  auto pct = [](double p) { return std::to_string(std::lround(p * 1000)); };
  const ModelCase& m = info.param;
  return "hit" + pct(m.prob_hit) + "_miss" + pct(m.prob_miss) + "_clamp" + pct(m.clamping_min) +
         "_" + pct(m.clamping_max);
}

class SensorModels : public ::testing::TestWithParam<ModelCase> {};

TEST_P(SensorModels, RandomAndRepeatedScans) {
  OCTOVK_REQUIRE_CONTEXT(ctx);
  const ModelCase m = GetParam();
  MapParams params = withResolution(0.05);
  params.prob_hit = m.prob_hit;
  params.prob_miss = m.prob_miss;
  params.clamping_min = m.clamping_min;
  params.clamping_max = m.clamping_max;
  ASSERT_EQ(params.validate(), "");
  OccupancyMap map(ctx, params);
  octomap::OcTree oracle = makeOracle(params);
  std::mt19937 rng(99);
  const Eigen::Vector3f origin(0.025f, 0.0f, -0.05f);
  const auto fixed = randomScan(rng, origin, 500, 1.5f);
  for (int scan = 0; scan < 10; ++scan) {
    const auto pts = (scan % 3 == 2) ? randomScan(rng, origin, 300, 1.5f) : fixed;
    ASSERT_TRUE(insertBoth(map, oracle, pts, origin, scan % 2 ? 1.0 : -1.0, false))
        << "scan " << scan;
  }
  const auto wall = wallScan(origin, 0.05f, 0.8f, 0.4f);
  for (int rep = 0; rep < 8; ++rep)
    ASSERT_TRUE(insertBoth(map, oracle, wall, origin, -1.0, rep % 2 == 1)) << "wall " << rep;
}

INSTANTIATE_TEST_SUITE_P(Models, SensorModels,
                         ::testing::Values(ModelCase{0.9, 0.2, 0.2, 0.8},
                                           ModelCase{0.6, 0.45, 0.05, 0.99},
                                           ModelCase{0.5, 0.5, 0.1192, 0.971}),
                         modelName);

}  // namespace
}  // namespace octovk::test
