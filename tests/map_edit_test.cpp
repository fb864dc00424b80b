// Map surgery against OctoMap: clearing a box as octomap_server's clear_bbx does it (every leaf
// leaf_bbx_iterator visits set to getClampingThresMinLog(), then updateInnerOccupancy), node for
// node with log-odds bits, and further scans after it equal OctoMap's on the cleared tree.
#include <octomap/octomap.h>

#include <filesystem>
#include <limits>
#include <memory>
#include <random>
#include <sstream>
#include <string>
#include <utility>

#include "test_support.hpp"

namespace octovk::test {
namespace {

void clearOracle(octomap::OcTree& tree, const Eigen::Vector3f& min, const Eigen::Vector3f& max) {
  for (auto it = tree.begin_leafs_bbx(toPoint(min), toPoint(max)), end = tree.end_leafs_bbx();
       it != end; ++it)
    it->setLogOdds(tree.getClampingThresMinLog());
  tree.updateInnerOccupancy();
}

struct Scene {
  OccupancyMap map;
  octomap::OcTree oracle;
};

// Scans that leave occupied and free leaves, pruned regions (free space near the sensor at a
// coarse resolution) and unknown space.
Scene scanned(Context& ctx, double resolution, unsigned seed) {
  const MapParams params = test::withResolution(resolution);
  Scene s{OccupancyMap(ctx, params), makeOracle(params)};
  std::mt19937 rng(seed);
  for (int i = 0; i < 4; ++i) {
    const Eigen::Vector3f origin(0.3f * static_cast<float>(i), 0.0f, 0.1f);
    const auto pts = test::randomScan(rng, origin, 1500, 2.5f);
    s.oracle.insertPointCloud(toPointcloud(pts), toPoint(origin));
    (void)s.map.insertPointCloud(pts, origin);
  }
  return s;
}

TEST(ClearBox, EqualsClearBbxNodeForNodeAndLaterScansToo) {
  OCTOVK_REQUIRE_CONTEXT(ctx);
  for (const double res : {0.05, 0.1, 0.2}) {
    SCOPED_TRACE("resolution " + std::to_string(res));
    Scene s = scanned(ctx, res, 3);
    ASSERT_TRUE(sameTree(s.oracle, *toOcTree(s.map)));
    const struct {
      Eigen::Vector3f min, max;
    } boxes[] = {{{0.2f, -0.5f, -0.4f}, {1.1f, 0.7f, 0.6f}},     // around the sensors
                 {{-3.0f, -3.0f, -0.05f}, {3.0f, 3.0f, 0.05f}},  // a thin slab through all
                 {{1.0f, 1.0f, 1.0f}, {1.0f, 1.0f, 1.0f}},       // one cell
                 {{5.0f, 5.0f, 5.0f}, {6.0f, 6.0f, 6.0f}}};      // nothing there
    std::size_t changed_leaves = 0;
    for (const auto& b : boxes) {
      std::size_t visited = 0;
      for (auto it = s.oracle.begin_leafs_bbx(toPoint(b.min), toPoint(b.max));
           it != s.oracle.end_leafs_bbx(); ++it)
        visited += it->getLogOdds() != s.oracle.getClampingThresMinLog();
      changed_leaves += visited;
      clearOracle(s.oracle, b.min, b.max);
      s.map.clearBox(b.min, b.max);
      ASSERT_TRUE(sameTree(s.oracle, *toOcTree(s.map)));
    }
    EXPECT_GT(changed_leaves, 100u) << "the boxes must clear something";
    // Scans after the cut: OctoMap prunes the cleared regions as they are updated again.
    std::mt19937 rng(11);
    for (int i = 0; i < 2; ++i) {
      const Eigen::Vector3f origin(0.5f, 0.1f * static_cast<float>(i), 0.0f);
      const auto pts = test::randomScan(rng, origin, 1200, 2.0f);
      s.oracle.insertPointCloud(toPointcloud(pts), toPoint(origin));
      (void)s.map.submitPointCloud(pts, origin);
    }
    s.map.flush();
    EXPECT_TRUE(sameTree(s.oracle, *toOcTree(s.map)));
    EXPECT_EQ(s.map.nodeCount(), s.oracle.size());
    EXPECT_EQ(s.map.leafCount(), s.oracle.getNumLeafNodes());
  }
}

// A pruned leaf reaching into the box is cleared whole, as the iterator visits it.
TEST(ClearBox, APrunedLeafReachingIntoTheBoxIsClearedWhole) {
  OCTOVK_REQUIRE_CONTEXT(ctx);
  const MapParams params = test::withResolution(0.1);
  OccupancyMap map(ctx, params);
  octomap::OcTree oracle = makeOracle(params);
  // Free space swept by many rays from one sensor: large pruned free leaves near it.
  std::mt19937 rng(5);
  for (int i = 0; i < 6; ++i) {
    const auto pts = test::sphere(3.0f, 4000, Eigen::Vector3f::Zero());
    oracle.insertPointCloud(toPointcloud(pts), octomap::point3d(0, 0, 0));
    (void)map.insertPointCloud(pts, Eigen::Vector3f::Zero());
  }
  std::size_t coarse = 0;
  for (auto it = oracle.begin_leafs_bbx(octomap::point3d(0.3f, 0.3f, 0.3f),
                                        octomap::point3d(0.35f, 0.35f, 0.35f));
       it != oracle.end_leafs_bbx(); ++it)
    coarse += it.getDepth() < 16;
  ASSERT_GT(coarse, 0u) << "the scenario needs a pruned leaf in the box";
  clearOracle(oracle, {0.3f, 0.3f, 0.3f}, {0.35f, 0.35f, 0.35f});
  map.clearBox({0.3f, 0.3f, 0.3f}, {0.35f, 0.35f, 0.35f});
  EXPECT_TRUE(sameTree(oracle, *toOcTree(map)));
}

TEST(ClearBox, BadBoxesAreRefusedAndTheMapKept) {
  OCTOVK_REQUIRE_CONTEXT(ctx);
  Scene s = scanned(ctx, 0.1, 9);
  const std::string before = test::otBytes(*toOcTree(s.map));
  const float nan = std::numeric_limits<float>::quiet_NaN();
  for (const auto& [min, max] : {std::pair<Eigen::Vector3f, Eigen::Vector3f>{{1, 0, 0}, {0, 1, 1}},
                                 {{0, 0, 0}, {nan, 1, 1}},
                                 {{-std::numeric_limits<float>::infinity(), 0, 0}, {1, 1, 1}}}) {
    try {
      s.map.clearBox(min, max);
      ADD_FAILURE() << "accepted a bad box";
    } catch (const Error& e) {
      EXPECT_EQ(e.code(), ErrorCode::kInvalidArgument) << e.what();
      EXPECT_NE(std::string(e.what()).find("clearBox"), std::string::npos) << e.what();
    }
  }
  EXPECT_EQ(test::otBytes(*toOcTree(s.map)), before);
}

}  // namespace
}  // namespace octovk::test

namespace octovk::test {
namespace {

// `octovk edit --clear-box` writes the file OctoMap writes after clear_bbx on the same map.
TEST(ClearBoxCli, EditWritesTheFilesOctoMapWrites) {
  OCTOVK_REQUIRE_CONTEXT(ctx);
  Scene s = scanned(ctx, 0.1, 21);
  const std::string in = test::tmpPath("edit_in.ot");
  writeMapFile(s.map, in);
  std::unique_ptr<octomap::AbstractOcTree> read(octomap::AbstractOcTree::read(in));
  auto* expected = dynamic_cast<octomap::OcTree*>(read.get());
  ASSERT_NE(expected, nullptr);
  clearOracle(*expected, {0.2f, -0.5f, -0.4f}, {1.1f, 0.7f, 0.6f});
  clearOracle(*expected, {-3.0f, -3.0f, -0.05f}, {3.0f, 3.0f, 0.05f});
  for (const std::string ext : {".ot", ".bt"}) {
    const std::string out = test::tmpPath("edit_out" + ext);
    std::filesystem::remove(out);
    const std::string command = std::string(OCTOVK_PATH(OCTOVK_CLI)) + " edit " + in +
                                " --clear-box 0.2 -0.5 -0.4 1.1 0.7 0.6"
                                " --clear-box=-3,-3,-0.05,3,3,0.05 -o " +
                                out + " >/dev/null 2>&1";
    ASSERT_EQ(test::shell(command), 0) << command;
    octomap::OcTree copy(*expected);  // writeBinary prunes what it writes
    std::stringstream bytes;
    if (ext == ".bt")
      copy.writeBinary(bytes);
    else
      copy.write(bytes);
    EXPECT_EQ(test::fileBytes(out), bytes.str()) << ext << " differs from OctoMap's";
    if (ext == ".ot") {
      EXPECT_NE(test::fileBytes(out), test::fileBytes(in)) << "nothing cleared";
    }
  }
}

}  // namespace
}  // namespace octovk::test
