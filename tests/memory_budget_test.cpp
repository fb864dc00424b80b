// The device-memory budget (MapParams::max_device_bytes) and the release of per-scan scratch
// (OccupancyMap::trim and the automatic release after an outsized scan). A growth the cap does
// not allow — the cell sets, the node pool, the query buffers — throws kOutOfDeviceMemory, the map
// keeps its nodes and takes the next scan that fits, except the scan's cell sets and lists: a scan
// whose cells do not fit is applied in groups of tiles, each within the cap, with the same
// result; trim and the automatic release change only sizes, never results. Caps are derived
// from what an uncapped map measures, not written in.
#include <octomap/octomap.h>

#include <cstdio>
#include <fstream>
#include <functional>
#include <memory>
#include <sstream>

#include "map/buffer_sizes.hpp"
#include "map/change_set.hpp"
#include "map/context_access.hpp"
#include "map/growth_policy.hpp"
#include "map/map_core.hpp"
#include "test_support.hpp"

namespace octovk {
namespace {

using test::sphere;

MapParams capped(double resolution, std::size_t cap) {
  MapParams p = test::withResolution(resolution);
  p.max_device_bytes = cap;
  return p;
}

// Expects `scan` to throw kOutOfDeviceMemory naming the cap and `what`.
template <class F>
void expectCapRefusal(F&& scan, const std::string& what) {
  try {
    scan();
    ADD_FAILURE() << "a growth beyond max_device_bytes did not throw (" << what << ")";
  } catch (const Error& e) {
    EXPECT_EQ(e.code(), ErrorCode::kOutOfDeviceMemory) << e.what();
    const std::string msg = e.what();
    EXPECT_NE(msg.find("max_device_bytes"), std::string::npos) << msg;
    EXPECT_NE(msg.find(what), std::string::npos) << msg;
    EXPECT_NE(msg.find("unchanged"), std::string::npos) << msg;
  }
}

void expectBreakdownAddsUp(const OccupancyMap& map) {
  const OccupancyMap::DeviceBytes b = map.deviceBytesByUse();
  EXPECT_EQ(b.total(), map.deviceBytes());
  EXPECT_EQ(b.pool, map.poolBytes());
  EXPECT_EQ(b.scratch, map.scratchBytes());
  EXPECT_GT(b.leaf_boxes, 0u);
  EXPECT_GT(b.queries, 0u);
}

TEST(MemoryBudget, MinimumIsAnEmptyMapAndLessIsRefused) {
  OCTOVK_REQUIRE_CONTEXT(ctx);
  for (const std::size_t max_nodes : {std::size_t{0}, std::size_t{800}}) {
    MapParams params;
    params.max_nodes = max_nodes;
    const std::size_t min = params.minDeviceBytes();
    {
      const OccupancyMap empty(ctx, params);
      EXPECT_EQ(empty.deviceBytes(), min) << "max_nodes " << max_nodes;
      expectBreakdownAddsUp(empty);
    }
    params.max_device_bytes = min;  // exactly the minimum: accepted
    EXPECT_EQ(params.validate(), "");
    OccupancyMap at_min(ctx, params);
    EXPECT_EQ(at_min.deviceBytes(), min);

    params.max_device_bytes = min - 1;
    const std::string why = params.validate();
    EXPECT_NE(why.find("max_device_bytes"), std::string::npos) << why;
    EXPECT_NE(why.find(std::to_string(min)), std::string::npos) << why;
    try {
      OccupancyMap too_small(ctx, params);
      ADD_FAILURE() << "a cap below an empty map was accepted";
    } catch (const Error& e) {
      EXPECT_EQ(e.code(), ErrorCode::kInvalidArgument);
      EXPECT_NE(std::string(e.what()).find(std::to_string(min)), std::string::npos) << e.what();
    }
  }
  // A smaller pool limit makes a smaller empty map.
  MapParams small;
  small.max_nodes = 800;
  EXPECT_LT(small.minDeviceBytes(), MapParams{}.minDeviceBytes());
}

// Long rays from few points: the cell set must grow in the ray pass beyond what the cap allows.
// The scan is applied in groups of tiles instead (ScanStats::tile_groups), each part within the
// cap: the map equals OctoMap's and its counts an uncapped map's, blocking, submitted back to back
// (the next scans start with the groups the last one showed they need) and with discretize.
TEST(MemoryBudget, CellSetOverCapAppliesTheScanInGroupsOfTiles) {
  OCTOVK_REQUIRE_CONTEXT(ctx);
  const double res = 0.05;
  struct Scan {
    std::vector<Eigen::Vector3f> points;
    Eigen::Vector3f origin;
    bool discretize = false;
  };
  std::vector<Scan> scans = {{sphere(0.5f, 200, Eigen::Vector3f::Zero()), {0, 0, 0}},
                             {sphere(30.0f, 64, Eigen::Vector3f::Zero()), {0, 0, 0}}};
  for (int i = 1; i <= 3; ++i) {  // submitted back to back
    const Eigen::Vector3f o(0.07f * static_cast<float>(i), 0.03f, 0.0f);
    scans.push_back({sphere(25.0f + static_cast<float>(i), 48, o), o});
  }
  const Eigen::Vector3f o(-0.11f, 0.02f, 0.01f);
  scans.push_back({sphere(28.0f, 80, o), o, true});  // discretize: the distinct end cells' rays

  OccupancyMap uncapped(ctx, test::withResolution(res));
  std::vector<ScanStats> whole;
  std::size_t pool = 0, total = 0;
  for (const Scan& s : scans) {
    whole.push_back(uncapped.insertPointCloud(s.points, s.origin, {.discretize = s.discretize}));
    pool = std::max(pool, uncapped.poolBytes());
    total = std::max(total, uncapped.deviceBytes());
  }
  // The pool as uncapped (the map fits), and a 32nd of the rest (the scans' sets do not).
  const std::size_t cap = pool + (total - pool) / 32;
  OccupancyMap map(ctx, capped(res, cap));
  octomap::OcTree oracle = test::makeOracle(map.params());
  const auto expectSameCounts = [&](const ScanStats& parts, std::size_t i) {
    EXPECT_EQ(whole[i].tile_groups, 1u) << "scan " << i;
    EXPECT_EQ(parts.free_cells, whole[i].free_cells) << "scan " << i;
    EXPECT_EQ(parts.occupied_cells, whole[i].occupied_cells) << "scan " << i;
    EXPECT_EQ(parts.aborted_cells, whole[i].aborted_cells) << "scan " << i;
    EXPECT_EQ(parts.nodes, whole[i].nodes) << "scan " << i;
  };
  ASSERT_TRUE(test::insertBoth(map, oracle, scans[0].points, scans[0].origin, -1.0, false));
  ScanStats parts;
  ASSERT_TRUE(test::insertBoth(map, oracle, scans[1].points, scans[1].origin, -1.0, false, &parts));
  expectSameCounts(parts, 1);
  std::size_t in_parts = parts.tile_groups > 1;
  EXPECT_LE(map.deviceBytes(), cap);

  // Submitted back to back: each in parts from its start, one statistics entry per scan.
  for (std::size_t i = 2; i < 5; ++i) {
    map.submitPointCloud(scans[i].points, scans[i].origin);
    oracle.insertPointCloud(test::toPointcloud(scans[i].points), test::toPoint(scans[i].origin));
  }
  map.flush();
  const std::vector<ScanStats> stats = map.takeScanStats();
  ASSERT_EQ(stats.size(), 3u);
  for (std::size_t i = 0; i < stats.size(); ++i) {
    expectSameCounts(stats[i], i + 2);
    in_parts += stats[i].tile_groups > 1;
  }
  EXPECT_TRUE(test::sameTree(oracle, *toOcTree(map)));
  EXPECT_LE(map.deviceBytes(), cap);

  ASSERT_TRUE(test::insertBoth(map, oracle, scans[5].points, scans[5].origin, -1.0, true, &parts));
  expectSameCounts(parts, 5);
  in_parts += parts.tile_groups > 1;
  EXPECT_GE(in_parts, 3u) << "of the 5 long scans, applied in groups of tiles";
  EXPECT_LE(map.deviceBytes(), cap);
}

// A scan with more points than the cap leaves room for (points, their staging, ray walks), from
// a point cloud and from a depth image: refused before anything runs; smaller scans still work.
TEST(MemoryBudget, PointsOverCapKeepTheMap) {
  OCTOVK_REQUIRE_CONTEXT(ctx);
  const double res = 0.1;
  const auto scan = sphere(1.0f, 500, Eigen::Vector3f::Zero());
  const auto more = sphere(1.1f, 800, Eigen::Vector3f(0.1f, 0, 0));
  std::size_t after_scans = 0;
  {
    OccupancyMap probe(ctx, test::withResolution(res));
    probe.insertPointCloud(scan, Eigen::Vector3f::Zero());
    probe.insertPointCloud(more, Eigen::Vector3f(0.1f, 0, 0));
    after_scans = probe.deviceBytes();
  }
  const std::size_t cap = after_scans + (256 << 10);
  OccupancyMap map(ctx, capped(res, cap));
  octomap::OcTree oracle = test::makeOracle(map.params());
  ASSERT_TRUE(test::insertBoth(map, oracle, scan, Eigen::Vector3f::Zero(), -1.0, false));
  const std::size_t nodes = map.nodeCount();

  const auto many = sphere(1.5f, 20000, Eigen::Vector3f::Zero());  // 120 B per point
  expectCapRefusal([&] { map.insertPointCloud(many, Eigen::Vector3f::Zero()); }, "points");
  std::vector<std::uint16_t> pixels(640 * 480, 5000);  // a wall 1 m away
  DepthImage image;
  image.width = 640;
  image.height = 480;
  image.depths = std::span<const std::uint16_t>(pixels);
  expectCapRefusal([&] { map.insertDepthImage(image, Pose{}); }, "points");
  EXPECT_EQ(map.nodeCount(), nodes);
  EXPECT_TRUE(test::sameTree(oracle, *toOcTree(map)));
  EXPECT_LE(map.deviceBytes(), cap);

  ASSERT_TRUE(test::insertBoth(map, oracle, more, Eigen::Vector3f(0.1f, 0, 0), -1.0, false));
  EXPECT_LE(map.deviceBytes(), cap);
}

// The same small scan again and again, 20 m apart (a whole number of bricks): each needs the
// first one's scratch and as many new blocks again, so within a cap a little above what the first
// scan left, the pool soon may not grow. That scan is refused, the map keeps its nodes (or, for a
// scan applied in groups of tiles, the parts before, as the message says), and a smaller scan
// still fits.
TEST(MemoryBudget, NodePoolOverCapKeepsTheMap) {
  OCTOVK_REQUIRE_CONTEXT(ctx);
  const double res = 0.1;
  const Eigen::Vector3f a(0, 0, 0);
  const auto first = sphere(0.6f, 200, a);
  std::size_t after_first = 0, pool_after_first = 0;
  {
    OccupancyMap probe(ctx, test::withResolution(res));
    probe.insertPointCloud(first, a);
    after_first = probe.deviceBytes();
    pool_after_first = probe.poolBytes();
  }
  const std::size_t cap = after_first + pool_after_first / 8;
  OccupancyMap map(ctx, capped(res, cap));
  octomap::OcTree oracle = test::makeOracle(map.params());
  ASSERT_TRUE(test::insertBoth(map, oracle, first, a, -1.0, false));
  EXPECT_EQ(map.deviceBytes(), after_first);

  bool refused = false;
  Eigen::Vector3f last = a;
  std::unique_ptr<octomap::OcTree> synced;  // the map after a scan that failed in parts
  // (The scan sets and lists give way to the pool first, so it takes a few scans.)
  for (int k = 1; k <= 64 && !refused; ++k) {
    const Eigen::Vector3f at(20.0f * static_cast<float>(k), 0, 0);
    const auto scan = sphere(0.6f, 200, at);
    const std::size_t nodes = map.nodeCount();
    const std::size_t pool_bytes = map.poolBytes();
    try {
      map.insertPointCloud(scan, at);
    } catch (const Error& e) {
      refused = true;
      EXPECT_EQ(e.code(), ErrorCode::kOutOfDeviceMemory) << e.what();
      const std::string msg = e.what();
      for (const char* part : {"max_device_bytes", "node pool"})
        EXPECT_NE(msg.find(part), std::string::npos) << msg;
      EXPECT_LE(map.deviceBytes(), cap);
      if (msg.find("applied in groups of tiles") == std::string::npos) {
        EXPECT_NE(msg.find("unchanged"), std::string::npos) << msg;
        EXPECT_EQ(map.nodeCount(), nodes);
        EXPECT_EQ(map.poolBytes(), pool_bytes);
        EXPECT_TRUE(test::sameTree(oracle, *toOcTree(map)));
      } else {
        // A scan applied in parts (its cells did not fit the sets the pool left) that outgrew
        // the cap after its first parts: the message says the map holds them, and not that it
        // is unchanged; the map goes on from there.
        EXPECT_NE(msg.find("the map holds the first"), std::string::npos) << msg;
        EXPECT_EQ(msg.find("unchanged"), std::string::npos) << msg;
        EXPECT_GT(map.nodeCount(), nodes);
        synced = toOcTree(map);
      }
      break;
    }
    oracle.insertPointCloud(test::toPointcloud(scan), test::toPoint(at));
    EXPECT_LE(map.deviceBytes(), cap) << "scan " << k;
    last = at;
  }
  ASSERT_TRUE(refused) << "no scan outgrew the capped pool";

  // A smaller scan at the last place the map took fits the pool that is left.
  const auto small = sphere(0.3f, 50, last);
  ASSERT_TRUE(test::insertBoth(map, synced ? *synced : oracle, small, last, -1.0, false));
  EXPECT_LE(map.deviceBytes(), cap);
}

// A map that outgrows the cap with a spill (OccupancyMap::spillTilesTo): its coldest tiles leave
// the device instead of the scan failing, and scans that come back to them load them first. The
// map equals OctoMap's after every round, blocking and submitted back to back, node for node
// (download() includes the spilled tiles), within the cap; what reads the whole tree on the
// device is refused by name while tiles are off it, and an upload brings everything back.
TEST(MemoryBudget, MapOverCapSpillsColdTilesAndStaysOctoMaps) {
  OCTOVK_REQUIRE_CONTEXT(ctx);
  const double res = 0.1;
  const auto at = [](int k) { return Eigen::Vector3f(20.0f * static_cast<float>(k), 0, 0); };
  const auto scanAt = [&](int k, float radius) { return sphere(radius, 200, at(k)); };
  std::size_t after_first = 0, pool_after_first = 0;
  {
    OccupancyMap probe(ctx, test::withResolution(res));
    probe.insertPointCloud(scanAt(0, 0.6f), at(0));
    after_first = probe.deviceBytes();
    pool_after_first = probe.poolBytes();
  }
  // As NodePoolOverCapKeepsTheMap's cap, which a few places' scans outgrow.
  const std::size_t cap = after_first + pool_after_first / 8;
  OccupancyMap map(ctx, capped(res, cap));
  map.spillTilesTo(makeHostTileSpill());
  octomap::OcTree oracle = test::makeOracle(map.params());
  std::size_t most_spilled = 0;
  // Out to 12 places, blocking; then back over every other one, submitted back to back, with a
  // larger sphere (new cells in the tiles left behind).
  for (int k = 0; k < 12; ++k) {
    ASSERT_TRUE(test::insertBoth(map, oracle, scanAt(k, 0.6f), at(k), -1.0, false)) << k;
    EXPECT_LE(map.deviceBytes(), cap) << "scan " << k;
    most_spilled = std::max(most_spilled, map.spilledTiles());
  }
  EXPECT_GT(most_spilled, 0u) << "the map never outgrew the cap";
  EXPECT_GT(map.spillCounts().evicted, 0u);
  for (int k = 10; k >= 0; k -= 2) {
    map.submitPointCloud(scanAt(k, 0.8f), at(k));
    oracle.insertPointCloud(test::toPointcloud(scanAt(k, 0.8f)), test::toPoint(at(k)));
  }
  map.flush();
  EXPECT_GT(map.spillCounts().loaded, 0u) << "no place revisited was loaded back";
  EXPECT_LE(map.deviceBytes(), cap);
  EXPECT_TRUE(test::sameTree(oracle, *toOcTree(map)));
  EXPECT_EQ(map.nodeCount(), oracle.size());
  EXPECT_EQ(map.leafCount(), oracle.getNumLeafNodes());
  ASSERT_GT(map.spilledTiles(), 0u);

  for (const auto& [call, run] : std::vector<std::pair<std::string, std::function<void()>>>{
           {"queries", [&] { map.search(scanAt(0, 0.6f)); }},
           {"leavesInBox", [&] { map.leavesInBox(at(0), at(1)); }},
           {"clearBox", [&] { map.clearBox(at(0), at(1)); }},
           {"compact", [&] { map.compact(); }}}) {
    try {
      run();
      ADD_FAILURE() << call << " ran with tiles off the device";
    } catch (const Error& e) {
      EXPECT_EQ(e.code(), ErrorCode::kInvalidArgument) << e.what();
      const std::string msg = e.what();
      EXPECT_NE(msg.find(call), std::string::npos) << msg;
      EXPECT_NE(msg.find("spilled"), std::string::npos) << msg;
    }
  }
  EXPECT_TRUE(test::sameTree(oracle, *toOcTree(map)));  // the refusals changed nothing

  // An uncapped map given the whole tree holds every tile and answers queries again.
  OccupancyMap whole(ctx, test::withResolution(res));
  whole.upload(map.download());
  EXPECT_EQ(whole.spilledTiles(), 0u);
  EXPECT_TRUE(test::sameTree(oracle, *toOcTree(whole)));
  EXPECT_EQ(whole.search(scanAt(0, 0.6f)).size(), 200u);
}

// A scan whose spilled tiles do not all fit the pool at once (a long-range scan over a map the
// cap holds a part of): it is applied in groups of tiles, each part loading its own, and the map
// is still OctoMap's.
TEST(MemoryBudget, ScanWhoseTilesDoNotFitAtOnceLoadsThemInGroups) {
  OCTOVK_REQUIRE_CONTEXT(ctx);
  const double res = 0.1;
  const Eigen::Vector3f a(0, 0, 0), b(0.35f, -0.25f, 0.15f);
  const auto first = sphere(6.0f, 2000, a);
  const auto again = sphere(6.5f, 2000, b);
  std::size_t pool = 0, total = 0;
  {
    OccupancyMap probe(ctx, test::withResolution(res));
    probe.insertPointCloud(first, a);
    probe.insertPointCloud(again, b);
    pool = probe.poolBytes();
    total = probe.deviceBytes();
  }
  // A third of the pool: neither scan's tiles fit at once.
  const std::size_t cap = total - pool + pool / 3;
  OccupancyMap map(ctx, capped(res, cap));
  map.spillTilesTo(makeHostTileSpill());
  octomap::OcTree oracle = test::makeOracle(map.params());
  ScanStats stats;
  ASSERT_TRUE(test::insertBoth(map, oracle, first, a, -1.0, false, &stats));
  ASSERT_TRUE(test::insertBoth(map, oracle, again, b, -1.0, false, &stats));
  EXPECT_GT(stats.tile_groups, 1u) << "the second scan should have run in groups of tiles";
  EXPECT_GT(map.spillCounts().loaded, 0u);
  EXPECT_GT(map.spilledTiles(), 0u);
  EXPECT_LE(map.deviceBytes(), cap);
  EXPECT_EQ(map.nodeCount(), oracle.size());
}

// Query batches beyond the cap: alone, and after a scan in the same call (the scan is then not
// applied either).
TEST(MemoryBudget, QueryBuffersOverCapKeepTheMap) {
  OCTOVK_REQUIRE_CONTEXT(ctx);
  const double res = 0.1;
  const auto scan = sphere(1.0f, 500, Eigen::Vector3f::Zero());
  const auto more = sphere(1.2f, 500, Eigen::Vector3f(0.1f, 0, 0));
  std::size_t after_scans = 0;  // both scans, without queries beyond the first buffers
  {
    OccupancyMap probe(ctx, test::withResolution(res));
    probe.insertPointCloud(scan, Eigen::Vector3f::Zero());
    probe.insertPointCloud(more, Eigen::Vector3f(0.1f, 0, 0));
    after_scans = probe.deviceBytes();
  }
  const std::size_t cap = after_scans + (16 << 10);
  OccupancyMap map(ctx, capped(res, cap));
  octomap::OcTree oracle = test::makeOracle(map.params());
  ASSERT_TRUE(test::insertBoth(map, oracle, scan, Eigen::Vector3f::Zero(), -1.0, false));
  const std::size_t nodes = map.nodeCount();

  std::vector<Ray> rays(20000);
  for (std::size_t i = 0; i < rays.size(); ++i) {
    const float a = 0.001f * static_cast<float>(i);
    rays[i].direction = Eigen::Vector3f(std::cos(a), std::sin(a), 0.1f);
  }
  expectCapRefusal([&] { (void)map.castRays(rays); }, "query buffers");
  EXPECT_LE(map.deviceBytes(), cap);

  // A batch that fits still gets OctoMap's answers.
  const std::vector<Ray> few(rays.begin(), rays.begin() + 8);
  const std::vector<RayHit> hits = map.castRays(few);
  ASSERT_EQ(hits.size(), few.size());
  for (std::size_t i = 0; i < few.size(); ++i) {
    octomap::point3d end;
    const bool hit = oracle.castRay(test::toPoint(few[i].origin), test::toPoint(few[i].direction),
                                    end, false, -1.0);
    EXPECT_EQ(hits[i].hit, hit) << i;
    EXPECT_EQ(hits[i].end, Eigen::Vector3f(end.x(), end.y(), end.z())) << i;
  }

  // A scan with too many queries: neither happens.
  std::vector<Eigen::Vector3f> lookups(40000, Eigen::Vector3f(0.5f, 0, 0));
  QueryResults results;
  expectCapRefusal(
      [&] {
        map.insertPointCloud(more, Eigen::Vector3f(0.1f, 0, 0), ScanOptions{},
                             QueryRequest{lookups, {}}, results);
      },
      "query buffers");
  EXPECT_EQ(map.nodeCount(), nodes);
  EXPECT_TRUE(test::sameTree(oracle, *toOcTree(map)));
  EXPECT_LE(map.deviceBytes(), cap);

  // The same scan alone works.
  ASSERT_TRUE(test::insertBoth(map, oracle, more, Eigen::Vector3f(0.1f, 0, 0), -1.0, false));
  EXPECT_LE(map.deviceBytes(), cap);
}

// Scans of many short rays (few cells) into a cap far below what the first guess of the cell set
// (4 brick slots per point) would take: the guess is cut to the cap, the scans succeed, equal
// OctoMap, and the map stays within the cap after every scan.
TEST(MemoryBudget, ScansStayWithinTheCap) {
  OCTOVK_REQUIRE_CONTEXT(ctx);
  const double res = 0.05;
  std::mt19937 rng(11);
  std::vector<std::vector<Eigen::Vector3f>> scans;
  std::vector<Eigen::Vector3f> origins;
  for (int i = 0; i < 4; ++i) {
    origins.emplace_back(0.3f * static_cast<float>(i), 0.1f, 0.0f);
    scans.push_back(test::randomScan(rng, origins.back(), 60000, 0.5f));
  }
  std::size_t uncapped_max = 0, pool_max = 0;
  {
    OccupancyMap probe(ctx, test::withResolution(res));
    for (std::size_t i = 0; i < scans.size(); ++i) {
      probe.insertPointCloud(scans[i], origins[i]);
      uncapped_max = std::max(uncapped_max, probe.deviceBytes());
      pool_max = std::max(pool_max, probe.poolBytes() + probe.deviceBytesByUse().leaf_boxes);
    }
  }
  // The pool and leaf boxes as uncapped, and half of the scratch and queries.
  const std::size_t cap = pool_max + (uncapped_max - pool_max) / 2;
  OccupancyMap map(ctx, capped(res, cap));
  octomap::OcTree oracle = test::makeOracle(map.params());
  for (std::size_t i = 0; i < scans.size(); ++i) {
    ASSERT_TRUE(test::insertBoth(map, oracle, scans[i], origins[i], -1.0, false)) << "scan " << i;
    EXPECT_LE(map.deviceBytes(), cap) << "scan " << i;
    expectBreakdownAddsUp(map);
  }
  EXPECT_LT(map.deviceBytes(), uncapped_max);
}

TEST(MemoryBudget, TrimReleasesScratchAndQueries) {
  OCTOVK_REQUIRE_CONTEXT(ctx);
  const MapParams params = test::withResolution(0.05);
  OccupancyMap fresh(ctx, params);
  const OccupancyMap::DeviceBytes empty = fresh.deviceBytesByUse();

  OccupancyMap map(ctx, params);
  octomap::OcTree oracle = test::makeOracle(params);
  std::mt19937 rng(5);
  const Eigen::Vector3f origin(0.01f, 0.02f, 0.03f);
  const auto big = test::randomScan(rng, origin, 100000, 2.0f);
  ASSERT_TRUE(test::insertBoth(map, oracle, big, origin, -1.0, false));
  const std::vector<Eigen::Vector3f> probes = test::randomScan(rng, origin, 30000, 2.5f);
  const std::vector<Lookup> before = map.search(probes);
  const OccupancyMap::DeviceBytes grown = map.deviceBytesByUse();
  EXPECT_GT(grown.scratch, 8 * empty.scratch);
  EXPECT_GT(grown.queries, 8 * empty.queries);

  map.trim();
  const OccupancyMap::DeviceBytes trimmed = map.deviceBytesByUse();
  EXPECT_EQ(trimmed.scratch, empty.scratch);
  EXPECT_EQ(trimmed.queries, empty.queries);
  EXPECT_EQ(trimmed.pool, grown.pool);
  EXPECT_EQ(trimmed.leaf_boxes, grown.leaf_boxes);
  EXPECT_EQ(map.deviceBytes(),
            grown.pool + grown.leaf_boxes + empty.scratch + empty.queries + grown.changes);
  map.trim();  // twice: nothing more to release
  EXPECT_EQ(map.deviceBytes(), trimmed.total());

  // Same answers, and scans after the trim grow the scratch again and equal OctoMap.
  const std::vector<Lookup> after = map.search(probes);
  ASSERT_EQ(after.size(), before.size());
  for (std::size_t i = 0; i < after.size(); ++i) {
    EXPECT_EQ(after[i].state, before[i].state) << i;
    EXPECT_EQ(after[i].log_odds, before[i].log_odds) << i;
    EXPECT_EQ(after[i].depth, before[i].depth) << i;
  }
  const Eigen::Vector3f o2(0.4f, -0.2f, 0.1f);
  ASSERT_TRUE(
      test::insertBoth(map, oracle, test::randomScan(rng, o2, 50000, 2.0f), o2, -1.0, true));
  EXPECT_GT(map.scratchBytes(), empty.scratch);
  map.trim();
  const Eigen::Vector3f o3(-0.3f, 0.2f, 0.0f);
  ASSERT_TRUE(
      test::insertBoth(map, oracle, test::randomScan(rng, o3, 2000, 1.0f), o3, -1.0, false));
  EXPECT_TRUE(test::sameLeaves(oracle, map));
}

// Small scans keep their scratch (no release, no regrowth); one outsized scan among them grows
// it and it is released right after; the next small scan grows it back to the small scans' size.
TEST(MemoryBudget, OutsizedScanReleasesItsScratch) {
  OCTOVK_REQUIRE_CONTEXT(ctx);
  const MapParams params = test::withResolution(0.05);
  const std::size_t empty_scratch = OccupancyMap(ctx, params).scratchBytes();
  OccupancyMap map(ctx, params);
  octomap::OcTree oracle = test::makeOracle(params);
  std::mt19937 rng(9);
  auto scanAt = [&](float x, std::size_t n, float radius) {
    const Eigen::Vector3f o(x, 0.05f, -0.02f);
    return test::insertBoth(map, oracle, test::randomScan(rng, o, n, radius), o, -1.0, false);
  };
  ASSERT_TRUE(scanAt(0.0f, 3000, 1.0f));
  const std::size_t small_scratch = map.scratchBytes();
  for (int i = 1; i <= 3; ++i) {
    ASSERT_TRUE(scanAt(0.1f * static_cast<float>(i), 3000, 1.0f));
    EXPECT_EQ(map.scratchBytes(), small_scratch) << "small scan " << i;
  }
  // 40 times the points: its scratch (points, walks, a larger cell set) is over 4 MiB.
  ASSERT_TRUE(scanAt(0.5f, 120000, 2.0f));
  EXPECT_EQ(map.scratchBytes(), empty_scratch);
  ASSERT_TRUE(scanAt(0.6f, 3000, 1.0f));
  EXPECT_EQ(map.scratchBytes(), small_scratch);

  // Outsized scans that become the usual size keep their scratch.
  OccupancyMap steady(ctx, params);
  std::size_t steady_scratch = 0;
  for (int i = 0; i < 4; ++i) {
    const Eigen::Vector3f o(0.1f * static_cast<float>(i), 0, 0);
    steady.insertPointCloud(test::randomScan(rng, o, 120000, 2.0f), o);
    if (i == 0) steady_scratch = steady.scratchBytes();
    EXPECT_EQ(steady.scratchBytes(), steady_scratch) << "scan " << i;
  }
  EXPECT_GT(steady_scratch, std::size_t{4} << 20);  // the premise: over the release threshold
}

// `octovk info` reports the pool and the scratch apart.
TEST(MemoryBudget, InfoReportsPoolAndScratch) {
  OCTOVK_REQUIRE_CONTEXT(ctx);
  (void)ctx;  // the program makes its own
  MapParams params = test::withResolution(0.1);
  octomap::OcTree tree = test::makeOracle(params);
  const auto pts = sphere(1.0f, 500, Eigen::Vector3f::Zero());
  tree.insertPointCloud(test::toPointcloud(pts), octomap::point3d(0, 0, 0));
  const std::string bt = test::tmpPath("budget_info.bt");
  const std::string out = test::tmpPath("budget_info.txt");
  ASSERT_TRUE(tree.writeBinary(bt));
  ASSERT_EQ(test::shell(OCTOVK_PATH(OCTOVK_CLI) + " info " + bt + " > " + out + " 2>&1"), 0);
  const std::string text = test::fileBytes(out);
  const auto line_at = text.find("device memory:");
  ASSERT_NE(line_at, std::string::npos) << text;
  const std::string line = text.substr(line_at, text.find('\n', line_at) - line_at);
  for (const char* part : {"node pool", "leaf boxes", "scan scratch", "query buffers", "MiB"})
    EXPECT_NE(line.find(part), std::string::npos) << line;
}

// Under the cap, a scan whose bricks list more cells than the cell lists hold, beside a cell set
// with room (a dense view lists about 25 cells a brick, the set is made for 4 a slot), lengthens
// the lists alone to the cells counted and an eighth more where a set four times larger does not
// fit; without a cap the set grows 4x as before. Where not even the lists fit, the growth is
// refused with nothing changed (the scan is then split in groups of tiles). A full second set
// grows 2x under the cap where 4x does not fit.
TEST(MemoryBudget, ShortCellListsGrowAloneUnderTheCap) {
  OCTOVK_REQUIRE_CONTEXT(ctx);
  vk::Device& device = ContextAccess::device(ctx);
  const MapParams plain = test::withResolution(0.05);
  MapCore probe(device, plain);
  const std::uint32_t log2 = probe.buffers.hashLog2();
  const std::size_t lists = probe.buffers.cellEntries();
  ASSERT_EQ(lists, (std::size_t{1} << log2) * kCellsPerBrickSlot);
  gpu::ScanCounters counters{};
  counters.status = gpu::kStatusHashFull | gpu::kStatusCellsShort | gpu::kStatusNotApplied;
  counters.brick_entries = 8;  // a set with room
  counters.cell_entries = static_cast<std::uint32_t>(3 * lists);
  const std::size_t want = counters.cell_entries + counters.cell_entries / 8;
  const gpu::PoolState pool = probe.readPool();
  // Room for the lengthened lists, not for the set 4x larger (every size 4x).
  const std::size_t room = sizes::cellBytes(want) - sizes::cellBytes(lists);
  ASSERT_LT(room, sizes::hashBytes(log2 + 2) - sizes::hashBytes(log2));
  const auto grown = [&](std::size_t cap) {
    MapParams params = plain;
    params.max_device_bytes = cap;
    auto core = std::make_unique<MapCore>(device, params);
    ChangeSet changes(*core);
    GrowthPolicy(*core, changes).growForRetry(counters, pool);
    return core;
  };
  const std::size_t empty = probe.buffers.deviceBytes();
  const auto capped = grown(empty + room);
  EXPECT_EQ(capped->buffers.hashLog2(), log2);
  EXPECT_EQ(capped->buffers.cellEntries(), want);
  EXPECT_EQ(capped->buffers.deviceBytes(), empty + room);
  const auto uncapped = grown(0);
  EXPECT_EQ(uncapped->buffers.hashLog2(), log2 + 2);
  EXPECT_EQ(uncapped->buffers.cellEntries(), (std::size_t{4} << log2) * kCellsPerBrickSlot);
  try {
    grown(empty + room - 1);
    ADD_FAILURE() << "lists beyond the cap were made";
  } catch (const Error& e) {
    EXPECT_EQ(e.code(), ErrorCode::kOutOfDeviceMemory) << e.what();
    EXPECT_NE(std::string(e.what()).find("cell lists"), std::string::npos) << e.what();
  }
  // The second set likewise: 2x where 4x does not fit.
  counters.status = gpu::kStatusEndpointHashFull | gpu::kStatusNotApplied;
  const std::uint32_t ends = probe.buffers.endpointLog2();
  const std::size_t twice = sizes::endpointBytes(ends + 1) - sizes::endpointBytes(ends) +
                            sizes::slotBytes(log2, ends + 1) - sizes::slotBytes(log2, ends);
  const auto halved = grown(empty + twice);
  EXPECT_EQ(halved->buffers.endpointLog2(), ends + 1);
  EXPECT_EQ(grown(0)->buffers.endpointLog2(), ends + 2);
}

}  // namespace
}  // namespace octovk
