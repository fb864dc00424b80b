// Scans submitted back to back (OccupancyMap::submitPointCloud / submitDepthImage): the map after
// every synchronisation equals OctoMap's after the same scans, including when the device refuses
// a scan in the middle of a queued sequence (a set, the pool or the lists too small) and the
// library grows and runs it again with the scans queued behind it; errors found late drop the
// failing scan and the later ones and keep the earlier ones; queries see every submitted scan.
#include <octomap/octomap.h>

#include <random>

#include "test_support.hpp"

namespace octovk {
namespace {

using test::randomScan;
using test::sphere;

struct Scan {
  std::vector<Eigen::Vector3f> points;
  Eigen::Vector3f origin;
  double max_range = -1.0;
  bool discretize = false;
  ScanOptions options() const { return {.max_range_m = max_range, .discretize = discretize}; }
};

void insertOracle(octomap::OcTree& oracle, const Scan& s) {
  oracle.insertPointCloud(test::toPointcloud(s.points), test::toPoint(s.origin), s.max_range, false,
                          s.discretize);
}

// A varied sequence: sizes from a handful of points to thousands, some with a max range, some
// discretized, origins wandering, so that the sets, the pool and the lists grow along the way.
std::vector<Scan> sequence(std::mt19937& rng, int count) {
  std::vector<Scan> scans;
  std::uniform_int_distribution<int> size(1, 4000);
  std::uniform_real_distribution<float> radius(0.3f, 3.0f);
  for (int i = 0; i < count; ++i) {
    Scan s;
    s.origin =
        Eigen::Vector3f(0.13f * static_cast<float>(i % 7), -0.07f * static_cast<float>(i % 5),
                        0.02f * static_cast<float>(i % 3));
    const std::size_t n = i % 9 == 4 ? 3 : static_cast<std::size_t>(size(rng));
    s.points = randomScan(rng, s.origin, n, radius(rng));
    s.max_range = i % 4 == 1 ? 1.5 : -1.0;
    s.discretize = i % 6 == 5;
    scans.push_back(std::move(s));
  }
  return scans;
}

TEST(Streaming, BackToBackEqualsOctoMapAtEverySynchronisation) {
  OCTOVK_REQUIRE_CONTEXT(ctx);
  const MapParams params = test::withResolution(0.05);
  OccupancyMap map(ctx, params);
  octomap::OcTree oracle = test::makeOracle(params);
  std::mt19937 rng(21);
  const std::vector<Scan> scans = sequence(rng, 36);
  std::vector<ScanTicket> tickets;
  std::size_t next = 0;
  for (std::size_t chunk = 1; next < scans.size(); chunk = chunk % 6 + 1) {
    for (std::size_t i = 0; i < chunk && next < scans.size(); ++i, ++next) {
      const Scan& s = scans[next];
      tickets.push_back(map.submitPointCloud(s.points, s.origin, s.options()));
      insertOracle(oracle, s);
    }
    map.flush();
    EXPECT_EQ(map.scansInFlight(), 0u);
    ASSERT_TRUE(test::sameTree(oracle, *toOcTree(map))) << "after scan " << next;
  }
  // Tickets count up; every scan's statistics come back once, in order.
  for (std::size_t i = 1; i < tickets.size(); ++i) EXPECT_EQ(tickets[i], tickets[i - 1] + 1);
  const std::vector<ScanStats> stats = map.takeScanStats();
  ASSERT_EQ(stats.size(), scans.size());
  for (std::size_t i = 0; i < stats.size(); ++i) {
    EXPECT_EQ(stats[i].ticket, tickets[i]);
    EXPECT_EQ(stats[i].points, scans[i].points.size());
    EXPECT_GE(stats[i].cell_set_attempts, 1u);
    EXPECT_TRUE(map.finished(tickets[i]));
  }
  EXPECT_EQ(stats.back().nodes, oracle.size());
  EXPECT_TRUE(map.takeScanStats().empty());
}

// The same sequence through the blocking calls and through submit: the same pool, node by node.
TEST(Streaming, SubmittedEqualsBlockingNodeByNode) {
  OCTOVK_REQUIRE_CONTEXT(ctx);
  const MapParams params = test::withResolution(0.1);
  std::mt19937 rng(5);
  const std::vector<Scan> scans = sequence(rng, 20);
  OccupancyMap blocking(ctx, params), streamed(ctx, params);
  std::vector<std::size_t> nodes;
  for (const Scan& s : scans)
    nodes.push_back(blocking.insertPointCloud(s.points, s.origin, s.options()).nodes);
  for (const Scan& s : scans) streamed.submitPointCloud(s.points, s.origin, s.options());
  streamed.flush();
  const std::vector<ScanStats> stats = streamed.takeScanStats();
  ASSERT_EQ(stats.size(), scans.size());
  for (std::size_t i = 0; i < stats.size(); ++i) EXPECT_EQ(stats[i].nodes, nodes[i]) << i;
  EXPECT_TRUE(test::otBytes(*toOcTree(blocking)) == test::otBytes(*toOcTree(streamed)));
}

// A scan the device cannot apply (the pool, the sets and the lists all too small for it) in the
// middle of a queue: it and the scan submitted right behind it (refused on the device because the
// map was halted) run again after growth, in order; the map equals OctoMap's.
TEST(Streaming, RefusedScanRunsAgainWithTheScansQueuedBehindIt) {
  OCTOVK_REQUIRE_CONTEXT(ctx);
  for (const bool discretize : {false, true}) {
    SCOPED_TRACE(discretize ? "discretize" : "rays");
    const MapParams params = test::withResolution(0.05);
    OccupancyMap map(ctx, params);
    octomap::OcTree oracle = test::makeOracle(params);
    std::mt19937 rng(77);
    std::vector<Scan> scans;
    const Eigen::Vector3f o(0.1f, 0.2f, 0.0f);
    scans.push_back({randomScan(rng, o, 50, 0.5f), o, -1.0, discretize});
    scans.push_back({randomScan(rng, o, 60, 0.5f), o, -1.0, discretize});
    // Far more cells and blocks than the first scans grew anything for.
    scans.push_back({sphere(3.0f, 8000, o), o, -1.0, discretize});
    // A scan that fits by itself (inside what the first two made): only the halt keeps the
    // device from applying it out of order, and running it again would then insert it twice.
    scans.push_back({randomScan(rng, o, 5, 0.3f), o, -1.0, discretize});
    for (int i = 0; i < 4; ++i) {
      const Eigen::Vector3f p = o + Eigen::Vector3f(0.05f * static_cast<float>(i), 0.3f, 0.0f);
      scans.push_back({randomScan(rng, p, 400, 2.0f), p, 2.5, discretize});
    }
    for (const Scan& s : scans) {
      map.submitPointCloud(s.points, s.origin, s.options());
      insertOracle(oracle, s);
    }
    map.flush();
    ASSERT_TRUE(test::sameTree(oracle, *toOcTree(map)));
    const std::vector<ScanStats> stats = map.takeScanStats();
    ASSERT_EQ(stats.size(), scans.size());
    EXPECT_GE(stats[2].cell_set_attempts, 2u) << "the large scan was not refused first";
    // Submitted before the refusal was seen, so refused on the device (halted), and run again.
    EXPECT_GE(stats[3].cell_set_attempts, 2u) << "the scan behind the refused one was not rerun";
    EXPECT_EQ(stats.back().nodes, oracle.size());
  }
}

// An error found on the device (a pool over MapParams::max_nodes) surfaces at the flush: the
// map holds the scans before the failing one; it and the scans behind it are not inserted; the
// map goes on taking scans.
TEST(Streaming, LateErrorKeepsTheScansBeforeAndDropsTheRest) {
  OCTOVK_REQUIRE_CONTEXT(ctx);
  MapParams params = test::withResolution(0.1);
  params.max_nodes = 20000;
  OccupancyMap map(ctx, params);
  octomap::OcTree oracle = test::makeOracle(params);
  const Eigen::Vector3f o = Eigen::Vector3f::Zero();
  const auto a = sphere(0.5f, 200, o), b = sphere(0.7f, 300, Eigen::Vector3f(0.05f, 0, 0));
  const auto big = sphere(6.0f, 20000, o);
  const auto c = sphere(0.6f, 250, o);
  map.submitPointCloud(a, o);
  map.submitPointCloud(b, Eigen::Vector3f(0.05f, 0, 0));
  const ScanTicket failing = map.submitPointCloud(big, o);
  insertOracle(oracle, {a, o});
  insertOracle(oracle, {b, Eigen::Vector3f(0.05f, 0, 0)});
  // The refusal is thrown by the first call that finds it: flush() where the device is slow
  // (lavapipe), the next submit where the big scan has already come back (an H200).
  try {
    map.submitPointCloud(c, o);
    map.flush();
    FAIL() << "a scan beyond max_nodes did not throw";
  } catch (const Error& e) {
    EXPECT_EQ(e.code(), ErrorCode::kOutOfDeviceMemory);
    EXPECT_EQ(e.scan(), failing);
    const std::string what = e.what();
    EXPECT_NE(what.find("scan " + std::to_string(failing) + " was not inserted, nor the "),
              std::string::npos)
        << what;
  }
  EXPECT_EQ(map.scansInFlight(), 0u);
  EXPECT_TRUE(test::sameTree(oracle, *toOcTree(map)));
  const std::vector<ScanStats> stats = map.takeScanStats();
  ASSERT_EQ(stats.size(), 2u);  // the two scans in the map
  // The map takes scans again (the device's halt was cleared).
  map.submitPointCloud(c, o);
  insertOracle(oracle, {c, o});
  map.flush();
  EXPECT_TRUE(test::sameTree(oracle, *toOcTree(map)));
}

// Queries, lookups, exports and nodeCount see every scan submitted before them.
TEST(Streaming, QueriesSeeEverySubmittedScan) {
  OCTOVK_REQUIRE_CONTEXT(ctx);
  const MapParams params = test::withResolution(0.1);
  OccupancyMap map(ctx, params);
  octomap::OcTree oracle = test::makeOracle(params);
  std::mt19937 rng(3);
  const std::vector<Scan> scans = sequence(rng, 5);
  for (const Scan& s : scans) {
    map.submitPointCloud(s.points, s.origin, s.options());
    insertOracle(oracle, s);
  }
  EXPECT_EQ(map.nodeCount(), oracle.size());
  for (const Scan& s : scans) map.submitPointCloud(s.points, s.origin, s.options());
  for (const Scan& s : scans) insertOracle(oracle, s);
  std::vector<Eigen::Vector3f> probes = randomScan(rng, Eigen::Vector3f::Zero(), 2000, 3.0f);
  const std::vector<Lookup> found = map.search(probes);
  ASSERT_EQ(found.size(), probes.size());
  for (std::size_t i = 0; i < probes.size(); ++i) {
    const octomap::OcTreeNode* n = oracle.search(test::toPoint(probes[i]));
    const CellState want =
        !n ? CellState::kUnknown
           : (oracle.isNodeOccupied(n) ? CellState::kOccupied : CellState::kFree);
    ASSERT_EQ(found[i].state, want) << i;
    if (n) {
      ASSERT_EQ(test::floatBits(found[i].log_odds), test::floatBits(n->getLogOdds())) << i;
    }
  }
  EXPECT_EQ(map.scansInFlight(), 0u);
}

// Depth images submitted back to back equal the blocking insertDepthImage, image by image.
TEST(Streaming, DepthImagesSubmittedEqualBlocking) {
  OCTOVK_REQUIRE_CONTEXT(ctx);
  const MapParams params = test::withResolution(0.05);
  OccupancyMap blocking(ctx, params), streamed(ctx, params);
  std::mt19937 rng(11);
  std::uniform_int_distribution<int> depth(0, 12000);
  const std::uint32_t w = 64, h = 48;
  for (int i = 0; i < 8; ++i) {
    std::vector<std::uint16_t> pixels(w * h);
    for (auto& p : pixels) p = static_cast<std::uint16_t>(depth(rng) < 600 ? 0 : depth(rng));
    DepthImage image;
    image.width = w;
    image.height = h;
    image.depths = std::span<const std::uint16_t>(pixels);
    image.fx = image.fy = 60.0f;
    image.cx = 31.5f;
    image.cy = 23.5f;
    Pose pose;
    pose.translation = Eigen::Vector3f(0.1f * static_cast<float>(i), 0.0f, 0.3f);
    pose.rotation = Eigen::Quaternionf(
        Eigen::AngleAxisf(0.2f * static_cast<float>(i), Eigen::Vector3f::UnitZ()));
    blocking.insertDepthImage(image, pose, {.max_range_m = i % 2 ? 1.8 : -1.0});
    streamed.submitDepthImage(image, pose, {.max_range_m = i % 2 ? 1.8 : -1.0});
    // The pixels were copied: overwriting them now changes nothing submitted.
    std::fill(pixels.begin(), pixels.end(), std::uint16_t{1});
  }
  streamed.flush();
  EXPECT_TRUE(test::otBytes(*toOcTree(blocking)) == test::otBytes(*toOcTree(streamed)));
}

// Empty scans take a ticket and finish in order; a bad input is refused by submit itself, with
// nothing submitted.
TEST(Streaming, EmptyAndInvalidScans) {
  OCTOVK_REQUIRE_CONTEXT(ctx);
  const MapParams params = test::withResolution(0.1);
  OccupancyMap map(ctx, params);
  const auto pts = sphere(1.0f, 100, Eigen::Vector3f::Zero());
  const ScanTicket t1 = map.submitPointCloud(pts, Eigen::Vector3f::Zero());
  const ScanTicket t2 = map.submitPointCloud({}, Eigen::Vector3f::Zero());
  EXPECT_THROW(map.submitPointCloud(pts, Eigen::Vector3f(NAN, 0, 0)), Error);
  map.flush();
  EXPECT_TRUE(map.finished(t1));
  EXPECT_TRUE(map.finished(t2));
  const std::vector<ScanStats> stats = map.takeScanStats();
  ASSERT_EQ(stats.size(), 2u);
  EXPECT_EQ(stats[1].ticket, t2);
  EXPECT_EQ(stats[1].points, 0u);
  EXPECT_EQ(stats[1].nodes, stats[0].nodes);
  EXPECT_EQ(map.nodeCount(), stats[0].nodes);
}

}  // namespace
}  // namespace octovk

namespace octovk {
namespace {

// ScanOptions (params.hpp) carries OctoMap's insertPointCloud arguments after the origin (max
// range, discretize): blocking, submitted and depth-image scans given their options in it build
// OctoMap's map with the same arguments, byte for byte.
TEST(ScanOptionsApi, EqualsOctoMapWithTheSameArguments) {
  OCTOVK_REQUIRE_CONTEXT(ctx);
  const MapParams params = test::withResolution(0.1);
  std::mt19937 rng(17);
  const std::vector<Scan> scans = sequence(rng, 8);
  Pose pose;
  pose.translation = Eigen::Vector3f(0.2f, -0.1f, 0.05f);
  pose.rotation = Eigen::Quaternionf(Eigen::AngleAxisf(0.3f, Eigen::Vector3f::UnitZ()));
  std::vector<float> depth(32 * 24);
  for (std::size_t i = 0; i < depth.size(); ++i)
    depth[i] = 0.5f + 0.01f * static_cast<float>(i % 37);
  DepthImage image;
  image.width = 32;
  image.height = 24;
  image.encoding = DepthImage::Encoding::kFloat32;
  image.depths = std::span<const float>(depth);
  image.fx = image.fy = 20.0f;
  image.cx = 15.5f;
  image.cy = 11.5f;
  image.depth_scale = 1.0f;

  OccupancyMap map(ctx, params);
  octomap::OcTree oracle = test::makeOracle(params);
  // OctoMap's sensor-frame insertPointCloud(pc, sensor_origin, frame_origin, max_range, lazy_eval,
  // discretize).
  const auto insertOracleInSensorFrame = [&](const std::vector<Eigen::Vector3f>& points,
                                             const Eigen::Vector3f& origin, double max_range,
                                             bool discretize) {
    oracle.insertPointCloud(test::toPointcloud(points), test::toPoint(origin), test::toPose6D(pose),
                            max_range, false, discretize);
  };
  for (std::size_t i = 0; i < scans.size(); ++i) {
    const Scan& s = scans[i];
    const ScanOptions o{.max_range_m = s.max_range, .discretize = s.discretize};
    if (i % 2 == 0) {
      map.insertPointCloud(s.points, s.origin, o);
      insertOracle(oracle, s);
    } else {
      map.submitPointCloud(s.points, s.origin, pose, o);
      insertOracleInSensorFrame(s.points, s.origin, s.max_range, s.discretize);
    }
  }
  const std::vector<Eigen::Vector3f> image_points = unprojectDepthImage(image);
  map.insertDepthImage(image, pose, {.max_range_m = 0.9, .discretize = true});
  insertOracleInSensorFrame(image_points, Eigen::Vector3f::Zero(), 0.9, true);
  map.submitDepthImage(image, pose, {.max_range_m = 0.7});
  insertOracleInSensorFrame(image_points, Eigen::Vector3f::Zero(), 0.7, false);
  map.flush();
  EXPECT_GT(map.nodeCount(), 1u);
  EXPECT_TRUE(test::otBytes(*toOcTree(map)) == test::otBytes(oracle));
}

}  // namespace
}  // namespace octovk
