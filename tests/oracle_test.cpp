// Oracle tests: the same scans into OctoMap and into octovk; after every scan the trees must be
// equal node by node with bit-identical log-odds.
#include <octomap/octomap.h>

#include <cmath>
#include <fstream>

#include "test_support.hpp"

namespace octovk {
namespace {

using test::makeOracle;
using test::sameTree;
using test::toPointcloud;

struct ScanCase {
  unsigned seed;
  double resolution;
  double max_range;
  bool discretize;
};

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

class RandomScans : public ::testing::TestWithParam<ScanCase> {};

TEST_P(RandomScans, EqualsOctoMapAfterEveryScan) {
  OCTOVK_REQUIRE_CONTEXT(ctx);
  const ScanCase c = GetParam();
  MapParams params;
  params.resolution = c.resolution;
  OccupancyMap map(ctx, params);
  octomap::OcTree oracle = makeOracle(params);
  std::mt19937 rng(c.seed);
  const float radius = static_cast<float>(c.resolution * 40);
  for (int scan = 0; scan < 6; ++scan) {
    // A few origins repeat so that cells reach the clamping bounds (early abort, pruning).
    const Eigen::Vector3f origin(static_cast<float>(c.resolution * (scan % 2)),
                                 static_cast<float>(-c.resolution * 0.5 * (scan % 3)), 0.25f);
    const auto pts = randomScan(rng, origin, 400, radius);
    oracle.insertPointCloud(toPointcloud(pts), octomap::point3d(origin.x(), origin.y(), origin.z()),
                            c.max_range, false, c.discretize);
    map.insertPointCloud(pts, origin, c.max_range, c.discretize);
    auto ours = toOcTree(map);
    ASSERT_TRUE(sameTree(oracle, *ours)) << "after scan " << scan;
  }
}

INSTANTIATE_TEST_SUITE_P(Seeds, RandomScans,
                         ::testing::Values(ScanCase{1, 0.1, -1.0, false},
                                           ScanCase{2, 0.05, -1.0, false},
                                           ScanCase{3, 0.2, 2.0, false},
                                           ScanCase{4, 0.01, 0.3, false},
                                           ScanCase{5, 0.1, -1.0, true},
                                           ScanCase{6, 0.05, 1.5, true}));

}  // namespace
}  // namespace octovk
