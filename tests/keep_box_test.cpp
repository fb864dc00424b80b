// Keeping only a box (OccupancyMap::keepBox) against OctoMap. The expected tree is written from
// OctoMap's leaf iterator (octomap_keep_box.hpp says why deleteNode cannot be the oracle) and
// compared node for node, log-odds bits included; scans after the cut against OctoMap inserting
// the same scans into that tree.
#include <octomap/octomap.h>

#include <algorithm>
#include <filesystem>
#include <limits>
#include <memory>
#include <random>
#include <sstream>
#include <string>
#include <tuple>
#include <utility>
#include <vector>

#include "changed_keys.hpp"
#include "octomap_keep_box.hpp"
#include "test_support.hpp"

namespace octovk::test {
namespace {

std::unique_ptr<octomap::OcTree> keepOracle(const octomap::OcTree& tree, const Eigen::Vector3f& min,
                                            const Eigen::Vector3f& max) {
  return test::octomapKeepBox(tree, toPoint(min), toPoint(max));
}

struct Scene {
  OccupancyMap map;
  std::unique_ptr<octomap::OcTree> oracle;
};

// Scans that leave occupied and free leaves, pruned regions and unknown space.
Scene scanned(Context& ctx, const MapParams& params, unsigned seed, bool changes = false) {
  Scene s{OccupancyMap(ctx, params), std::make_unique<octomap::OcTree>(makeOracle(params))};
  s.map.enableChangeDetection(changes);
  s.oracle->enableChangeDetection(changes);
  std::mt19937 rng(seed);
  for (int i = 0; i < 4; ++i) {
    const Eigen::Vector3f origin(0.3f * static_cast<float>(i), 0.0f, 0.1f);
    const auto pts = test::randomScan(rng, origin, 1500, 2.5f);
    s.oracle->insertPointCloud(toPointcloud(pts), toPoint(origin));
    (void)s.map.insertPointCloud(pts, origin);
  }
  return s;
}

void keepBoth(Scene& s, const Eigen::Vector3f& min, const Eigen::Vector3f& max) {
  s.oracle = keepOracle(*s.oracle, min, max);
  s.map.keepBox(min, max);
}

TEST(KeepBox, EqualsTheLeafIteratorsTreeNodeForNodeAndLaterScansToo) {
  OCTOVK_REQUIRE_CONTEXT(ctx);
  for (const double res : {0.05, 0.1, 0.2}) {
    SCOPED_TRACE("resolution " + std::to_string(res));
    Scene s = scanned(ctx, test::withResolution(res), 3);
    ASSERT_TRUE(sameTree(*s.oracle, *toOcTree(s.map)));
    const struct {
      Eigen::Vector3f min, max;
    } boxes[] = {{{-1.5f, -2.0f, -1.0f}, {2.2f, 1.7f, 1.3f}},    // most of the map
                 {{-3.0f, -3.0f, -0.25f}, {3.0f, 3.0f, 0.05f}},  // a thin slab of that
                 {{0.2f, -0.5f, -0.2f}, {1.1f, 0.7f, 0.0f}}};    // around the sensors
    std::size_t nodes = s.map.nodeCount();
    for (const auto& b : boxes) {
      keepBoth(s, b.min, b.max);
      ASSERT_TRUE(sameTree(*s.oracle, *toOcTree(s.map)));
      EXPECT_EQ(s.map.nodeCount(), s.oracle->size());
      EXPECT_LT(s.map.nodeCount(), nodes) << "the box must cut something";
      EXPECT_GT(s.map.nodeCount(), 100u) << "the box must keep something";
      nodes = s.map.nodeCount();
      EXPECT_EQ(s.map.leafCount(), s.oracle->getNumLeafNodes());
    }
    // Scans after the cut, blocking and submitted: OctoMap inserting them into the cut tree.
    const std::size_t pool_bytes = s.map.deviceBytesByUse().pool;
    std::mt19937 rng(11);
    for (int i = 0; i < 3; ++i) {
      const Eigen::Vector3f origin(0.5f, 0.1f * static_cast<float>(i), 0.0f);
      const auto pts = test::randomScan(rng, origin, 1200, 2.0f);
      s.oracle->insertPointCloud(toPointcloud(pts), toPoint(origin));
      if (i == 0)
        (void)s.map.insertPointCloud(pts, origin);
      else
        (void)s.map.submitPointCloud(pts, origin);
    }
    s.map.flush();
    EXPECT_TRUE(sameTree(*s.oracle, *toOcTree(s.map)));
    EXPECT_EQ(s.map.nodeCount(), s.oracle->size());
    EXPECT_EQ(s.map.leafCount(), s.oracle->getNumLeafNodes());
    EXPECT_EQ(s.map.deviceBytesByUse().pool, pool_bytes)
        << "the scans after the cut fit in the blocks it freed";
    EXPECT_EQ(
        s.map.leavesInBox({-1.0f, -1.0f, -1.0f}, {1.0f, 1.0f, 1.0f}).size(),
        static_cast<std::size_t>(std::distance(
            s.oracle->begin_leafs_bbx(octomap::point3d(-1, -1, -1), octomap::point3d(1, 1, 1)),
            s.oracle->end_leafs_bbx())));
  }
}

// compact() after a cut gives the freed blocks back to the device: the pool's bytes fall, the
// tree, the change set and later scans stay OctoMap's; a pool with little free room is left.
TEST(KeepBox, CompactGivesTheFreedBlocksBack) {
  OCTOVK_REQUIRE_CONTEXT(ctx);
  Scene s = scanned(ctx, test::withResolution(0.05), 7, /*changes=*/true);
  const std::size_t grown = s.map.deviceBytesByUse().pool;
  keepBoth(s, {0.2f, -0.5f, -0.2f}, {1.1f, 0.7f, 0.0f});
  EXPECT_EQ(s.map.deviceBytesByUse().pool, grown) << "keepBox frees blocks, not bytes";
  const std::size_t nodes = s.map.nodeCount();
  s.map.compact();
  const OccupancyMap::DeviceBytes compacted = s.map.deviceBytesByUse();
  EXPECT_LT(compacted.pool * 2, grown) << "the cut kept a small box: most of the pool is free";
  EXPECT_LT(compacted.leaf_boxes, compacted.pool * 3) << "the leaf boxes follow the pool";
  EXPECT_EQ(s.map.nodeCount(), nodes);
  ASSERT_TRUE(sameTree(*s.oracle, *toOcTree(s.map)));
  EXPECT_EQ(ourChanges(s.map), oracleChanges(*s.oracle));
  s.map.compact();  // nothing more to give back
  EXPECT_EQ(s.map.deviceBytesByUse().pool, compacted.pool);
  std::mt19937 rng(13);
  for (int i = 0; i < 3; ++i) {
    const Eigen::Vector3f origin(0.6f, 0.1f * static_cast<float>(i), -0.1f);
    const auto pts = test::randomScan(rng, origin, 1500, 2.0f);
    s.oracle->insertPointCloud(toPointcloud(pts), toPoint(origin));
    (void)s.map.submitPointCloud(pts, origin);
  }
  s.map.flush();
  EXPECT_TRUE(sameTree(*s.oracle, *toOcTree(s.map)));
  EXPECT_EQ(ourChanges(s.map), oracleChanges(*s.oracle));
  EXPECT_EQ(s.map.nodeCount(), s.oracle->size());
}

// Emptied and scanned again, the map is what it was, in the blocks the cut freed.
TEST(KeepBox, ABoxOutsideTheMapKeepsNothingAndTheFreedBlocksAreReused) {
  OCTOVK_REQUIRE_CONTEXT(ctx);
  const MapParams params = test::withResolution(0.1);
  Scene s = scanned(ctx, params, 5);
  const std::string before = test::otBytes(*toOcTree(s.map));
  const std::size_t nodes = s.map.nodeCount();
  const std::size_t pool_bytes = s.map.deviceBytesByUse().pool;
  // 1e5 m is beyond the keys of a 0.1 m map (32768 cells from the origin): the iterator visits
  // nothing.
  s.map.keepBox({-1.0f, -1.0f, -1.0f}, {1e5f, 1.0f, 1.0f});
  EXPECT_EQ(s.map.nodeCount(), 0u);
  EXPECT_EQ(s.map.leafCount(), 0u);
  EXPECT_EQ(toOcTree(s.map)->size(), 0u);
  // OctoMap's iterator, meant to be at its end here, yields the root once (see
  // octomap_keep_box.hpp); that inner node is no leaf in the box.
  std::size_t visited = 0;
  for (auto it =
           s.oracle->begin_leafs_bbx(octomap::point3d(-1, -1, -1), octomap::point3d(1e5f, 1, 1));
       it != s.oracle->end_leafs_bbx(); ++it)
    visited += s.oracle->nodeHasChildren(&*it) ? 0 : 1;
  EXPECT_EQ(visited, 0u);
  EXPECT_EQ(keepOracle(*s.oracle, {-1.0f, -1.0f, -1.0f}, {1e5f, 1.0f, 1.0f})->size(), 0u);
  // The same scans again: the same tree, in the same pool.
  OccupancyMap& map = s.map;
  std::mt19937 rng(5);
  for (int i = 0; i < 4; ++i) {
    const Eigen::Vector3f origin(0.3f * static_cast<float>(i), 0.0f, 0.1f);
    (void)map.insertPointCloud(test::randomScan(rng, origin, 1500, 2.5f), origin);
  }
  EXPECT_EQ(test::otBytes(*toOcTree(map)), before);
  EXPECT_EQ(map.nodeCount(), nodes);
  EXPECT_EQ(map.deviceBytesByUse().pool, pool_bytes) << "the freed blocks were not reused";
}

// A pruned leaf reaching into the box stays whole, and a box inside one leaf keeps it alone.
TEST(KeepBox, APrunedLeafReachingIntoTheBoxStaysWhole) {
  OCTOVK_REQUIRE_CONTEXT(ctx);
  const MapParams params = test::withResolution(0.1);
  Scene s{OccupancyMap(ctx, params), std::make_unique<octomap::OcTree>(makeOracle(params))};
  for (int i = 0; i < 6; ++i) {
    const auto pts = test::sphere(3.0f, 4000, Eigen::Vector3f::Zero());
    s.oracle->insertPointCloud(toPointcloud(pts), octomap::point3d(0, 0, 0));
    (void)s.map.insertPointCloud(pts, Eigen::Vector3f::Zero());
  }
  const Eigen::Vector3f lo(0.3f, 0.3f, 0.3f), hi(0.35f, 0.35f, 0.35f);
  std::size_t coarse = 0;
  for (auto it = s.oracle->begin_leafs_bbx(toPoint(lo), toPoint(hi));
       it != s.oracle->end_leafs_bbx(); ++it)
    coarse += it.getDepth() < 16;
  ASSERT_GT(coarse, 0u) << "the scenario needs a pruned leaf in the box";
  keepBoth(s, lo, hi);
  EXPECT_TRUE(sameTree(*s.oracle, *toOcTree(s.map)));
  EXPECT_EQ(s.map.leafCount(), s.oracle->getNumLeafNodes());
  const auto pts = test::sphere(1.0f, 500, Eigen::Vector3f(0.2f, 0.2f, 0.2f));
  s.oracle->insertPointCloud(toPointcloud(pts), octomap::point3d(0.2f, 0.2f, 0.2f));
  (void)s.map.insertPointCloud(pts, Eigen::Vector3f(0.2f, 0.2f, 0.2f));
  EXPECT_TRUE(sameTree(*s.oracle, *toOcTree(s.map)));
}

// Change detection does not see the cut (OctoMap's deleteNode leaves the changed keys alone:
// deleted leaves' keys stay), and scans after it note what OctoMap's would.
TEST(KeepBox, ChangedKeysStayAsOctoMapsAndLaterScansNoteTheirs) {
  OCTOVK_REQUIRE_CONTEXT(ctx);
  Scene s = scanned(ctx, test::withResolution(0.1), 7, /*changes=*/true);
  ASSERT_EQ(ourChanges(s.map), oracleChanges(*s.oracle));
  const std::size_t changes = s.map.numChangesDetected();
  keepBoth(s, {-0.5f, -0.5f, -0.5f}, {1.0f, 0.5f, 0.5f});
  EXPECT_EQ(s.map.numChangesDetected(), changes);
  ASSERT_EQ(ourChanges(s.map), oracleChanges(*s.oracle));
  std::mt19937 rng(17);
  for (int i = 0; i < 2; ++i) {
    const Eigen::Vector3f origin(0.2f * static_cast<float>(i), 0.3f, 0.0f);
    const auto pts = test::randomScan(rng, origin, 1500, 2.5f);
    s.oracle->insertPointCloud(toPointcloud(pts), toPoint(origin));
    (void)s.map.insertPointCloud(pts, origin);
  }
  EXPECT_TRUE(sameTree(*s.oracle, *toOcTree(s.map)));
  EXPECT_EQ(ourChanges(s.map), oracleChanges(*s.oracle));
  s.map.resetChangeDetection();
  EXPECT_EQ(s.map.numChangesDetected(), 0u);
}

TEST(KeepBox, BadBoxesAreRefusedAndTheMapKept) {
  OCTOVK_REQUIRE_CONTEXT(ctx);
  Scene s = scanned(ctx, test::withResolution(0.1), 9);
  const std::string before = test::otBytes(*toOcTree(s.map));
  const std::size_t nodes = s.map.nodeCount();
  const float nan = std::numeric_limits<float>::quiet_NaN();
  for (const auto& [min, max] : {std::pair<Eigen::Vector3f, Eigen::Vector3f>{{1, 0, 0}, {0, 1, 1}},
                                 {{0, 0, 0}, {nan, 1, 1}},
                                 {{-std::numeric_limits<float>::infinity(), 0, 0}, {1, 1, 1}}}) {
    try {
      s.map.keepBox(min, max);
      ADD_FAILURE() << "accepted a bad box";
    } catch (const Error& e) {
      EXPECT_EQ(e.code(), ErrorCode::kInvalidArgument) << e.what();
      EXPECT_NE(std::string(e.what()).find("keepBox"), std::string::npos) << e.what();
    }
  }
  EXPECT_EQ(test::otBytes(*toOcTree(s.map)), before);
  EXPECT_EQ(s.map.nodeCount(), nodes);
}

// A scan of a corridor (floor, ceiling and two walls) seen from `origin`: points on its surfaces
// within `reach` metres along it.
std::vector<Eigen::Vector3f> corridorScan(std::mt19937& rng, const Eigen::Vector3f& origin,
                                          std::size_t n, float reach) {
  std::uniform_real_distribution<float> along(-reach, reach), across(-2.0f, 2.0f), up(-1.0f, 1.5f);
  std::uniform_int_distribution<int> face(0, 3);
  std::vector<Eigen::Vector3f> pts;
  while (pts.size() < n) {
    const float x = origin.x() + along(rng);
    switch (face(rng)) {
      case 0:
        pts.emplace_back(x, across(rng), -1.0f);
        break;
      case 1:
        pts.emplace_back(x, across(rng), 1.5f);
        break;
      case 2:
        pts.emplace_back(x, -2.0f, up(rng));
        break;
      default:
        pts.emplace_back(x, 2.0f, up(rng));
        break;
    }
  }
  return pts;
}

// A rolling window: 300 scans along 60 m of corridor, a window of 8 x 6 x 3.4 m kept around the
// sensor after every third scan, under a cap the whole map would exceed. No call fails, the map
// stays under the cap, and at checkpoints it is OctoMap's tree cut the same way.
TEST(KeepBox, ARollingWindowStaysUnderACapTheWholeMapWouldExceed) {
  OCTOVK_REQUIRE_CONTEXT(ctx);
  MapParams params = test::withResolution(0.1);
  params.max_device_bytes = std::size_t{6} << 20;
  OccupancyMap map(ctx, params);
  std::unique_ptr<octomap::OcTree> oracle = std::make_unique<octomap::OcTree>(makeOracle(params));
  octomap::OcTree uncut = makeOracle(params);
  std::mt19937 rng(23);
  const int scans = 300;
  std::size_t largest = 0;
  for (int i = 0; i < scans; ++i) {
    const Eigen::Vector3f origin(0.2f * static_cast<float>(i), 0.1f, 0.2f);
    const auto pts = corridorScan(rng, origin, 400, 4.0f);
    oracle->insertPointCloud(toPointcloud(pts), toPoint(origin));
    uncut.insertPointCloud(toPointcloud(pts), toPoint(origin));
    ASSERT_NO_THROW((void)map.submitPointCloud(pts, origin)) << "scan " << i;
    if (i % 3 == 2) {
      const Eigen::Vector3f half(4.0f, 3.0f, 1.7f);
      oracle = keepOracle(*oracle, origin - half, origin + half);
      ASSERT_NO_THROW(map.keepBox(origin - half, origin + half)) << "after scan " << i;
    }
    largest = std::max(largest, map.deviceBytes());
    ASSERT_LE(map.deviceBytes(), params.max_device_bytes) << "scan " << i;
    if (i % 60 == 59) {
      map.flush();
      ASSERT_TRUE(sameTree(*oracle, *toOcTree(map))) << "after scan " << i;
      ASSERT_EQ(map.nodeCount(), oracle->size());
    }
  }
  // The whole map needs a block (8 node slots: 72 B in the pool, 160 B of leaf boxes) per inner
  // node at least: more than the cap.
  const std::size_t inner = uncut.size() - uncut.getNumLeafNodes();
  EXPECT_GT(inner * (72 + 160), params.max_device_bytes)
      << "the whole map would fit under the cap: the test shows nothing";
  std::cout << "rolling window: largest " << largest << " B under a cap of "
            << params.max_device_bytes << " B; the whole map has " << uncut.size() << " nodes ("
            << inner << " inner), the window " << oracle->size() << "\n";
}

// `octovk edit --keep-box` writes the file OctoMap writes for the tree cut the same way.
TEST(KeepBoxCli, EditWritesTheFilesOctoMapWrites) {
  OCTOVK_REQUIRE_CONTEXT(ctx);
  Scene s = scanned(ctx, test::withResolution(0.1), 21);
  const std::string in = test::tmpPath("keep_in.ot");
  writeMapFile(s.map, in);
  std::unique_ptr<octomap::AbstractOcTree> read(octomap::AbstractOcTree::read(in));
  auto* from_file = dynamic_cast<octomap::OcTree*>(read.get());
  ASSERT_NE(from_file, nullptr);
  // The edits in order: keep, clear inside what was kept, keep a smaller box.
  std::unique_ptr<octomap::OcTree> expected =
      keepOracle(*from_file, {-1.5f, -2.0f, -1.0f}, {2.2f, 1.7f, 1.3f});
  for (auto it = expected->begin_leafs_bbx(octomap::point3d(0.2f, -0.5f, -0.4f),
                                           octomap::point3d(1.1f, 0.7f, 0.6f)),
            end = expected->end_leafs_bbx();
       it != end; ++it)
    it->setLogOdds(expected->getClampingThresMinLog());
  expected->updateInnerOccupancy();
  expected = keepOracle(*expected, {-1.0f, -1.0f, -0.5f}, {1.5f, 1.0f, 0.5f});
  for (const std::string ext : {".ot", ".bt"}) {
    const std::string out = test::tmpPath("keep_out" + ext);
    std::filesystem::remove(out);
    const std::string command = std::string(OCTOVK_PATH(OCTOVK_CLI)) + " edit " + in +
                                " --keep-box -1.5 -2 -1 2.2 1.7 1.3"
                                " --clear-box 0.2 -0.5 -0.4 1.1 0.7 0.6"
                                " --keep-box=-1,-1,-0.5,1.5,1,0.5 -o " +
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
      EXPECT_LT(test::fileBytes(out).size(), test::fileBytes(in).size());
    }
  }
}

}  // namespace
}  // namespace octovk::test
