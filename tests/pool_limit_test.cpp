// A full node pool: a scan that needs more nodes than MapParams::max_nodes allows throws
// kOutOfDeviceMemory and leaves the map exactly as it was; later scans that fit still work.
#include <octomap/octomap.h>

#include "test_support.hpp"

namespace octovk {
namespace {

using test::sphere;

TEST(PoolLimit, FullPoolThrowsAndKeepsTheMap) {
  OCTOVK_REQUIRE_CONTEXT(ctx);
  MapParams params;
  params.resolution = 0.1;
  params.max_nodes = 20000;
  OccupancyMap map(ctx, params);
  octomap::OcTree oracle = test::makeOracle(params);

  const auto small = sphere(0.5f, 200, Eigen::Vector3f::Zero());
  map.insertPointCloud(small, Eigen::Vector3f::Zero());
  oracle.insertPointCloud(test::toPointcloud(small), octomap::point3d(0, 0, 0));
  ASSERT_TRUE(test::sameTree(oracle, *toOcTree(map)));
  const std::size_t before = map.nodeCount();
  ASSERT_GT(before, 100u);

  const auto big = sphere(6.0f, 20000, Eigen::Vector3f::Zero());
  try {
    map.insertPointCloud(big, Eigen::Vector3f::Zero());
    FAIL() << "a scan beyond max_nodes did not throw";
  } catch (const Error& e) {
    EXPECT_EQ(e.code(), ErrorCode::kOutOfDeviceMemory);
    EXPECT_NE(std::string(e.what()).find("unchanged"), std::string::npos) << e.what();
  }
  EXPECT_EQ(map.nodeCount(), before);
  EXPECT_TRUE(test::sameTree(oracle, *toOcTree(map)));

  // The map still takes scans that fit.
  const auto again = sphere(0.6f, 300, Eigen::Vector3f(0.05f, 0, 0));
  map.insertPointCloud(again, Eigen::Vector3f(0.05f, 0, 0));
  oracle.insertPointCloud(test::toPointcloud(again), octomap::point3d(0.05f, 0, 0));
  EXPECT_TRUE(test::sameTree(oracle, *toOcTree(map)));
}

TEST(PoolLimit, ImportOverTheLimitThrows) {
  OCTOVK_REQUIRE_CONTEXT(ctx);
  MapParams params;
  params.resolution = 0.1;
  octomap::OcTree tree = test::makeOracle(params);
  const auto big = sphere(4.0f, 5000, Eigen::Vector3f::Zero());
  tree.insertPointCloud(test::toPointcloud(big), octomap::point3d(0, 0, 0));
  params.max_nodes = 1000;
  OccupancyMap map(ctx, params);
  try {
    fromOcTree(map, tree);
    FAIL() << "an import beyond max_nodes did not throw";
  } catch (const Error& e) {
    EXPECT_EQ(e.code(), ErrorCode::kOutOfDeviceMemory);
  }
  EXPECT_EQ(map.nodeCount(), 0u);
}

}  // namespace
}  // namespace octovk
