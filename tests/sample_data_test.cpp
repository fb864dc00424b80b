// Oracle tests on real and shipped data: OctoMap's example scans and a slice of the FR-079 log,
// inserted the way graph2tree does, compared with OctoMap after every few scans.
#include <octomap/ScanGraph.h>
#include <octomap/octomap.h>
#include <unistd.h>

#include <cmath>
#include <cstdio>
#include <fstream>
#include <mutex>

#include "test_support.hpp"

namespace octovk {
namespace {

using test::makeOracle;
using test::sameTree;
using test::toPoint;

const std::string kOctomapData = OCTOVK_PATH(OCTOVK_OCTOMAP_DATA_DIR);
const std::string kSharedData = OCTOVK_PATH(OCTOVK_SHARED_DATA_DIR);

/// graph2tree's preparation of one scan: the cloud moved to the world by the pose, and the origin
/// pose.transform(pose.inv().transform(pose.trans())).
struct OracleScan {
  octomap::Pointcloud points_world;
  octomap::point3d origin_world;
};

std::vector<OracleScan> graph2treeScans(const std::string& path) {
  octomap::ScanGraph graph;
  {
    test::QuietCout quiet;
    EXPECT_TRUE(graph.readBinary(path)) << path;
  }
  std::vector<OracleScan> out;
  for (octomap::ScanNode* node : graph) {
    const octomath::Pose6D pose = node->pose;
    const octomap::point3d sensor_origin = pose.inv().transform(pose.trans());
    OracleScan scan;
    scan.points_world = *node->scan;
    scan.points_world.transform(pose);
    scan.origin_world = pose.transform(sensor_origin);
    out.push_back(std::move(scan));
  }
  return out;
}

struct InsertCase {
  double resolution;
  double max_range;
  bool discretize;
};

void PrintTo(const InsertCase& c, std::ostream* os) {
  *os << "resolution " << c.resolution << ", max range " << c.max_range << ", discretize "
      << c.discretize;
}

std::string insertCaseName(const ::testing::TestParamInfo<InsertCase>& info) {
  const InsertCase& c = info.param;
  return "res" + std::to_string(std::lround(c.resolution * 1000)) + "mm" +
         (c.max_range < 0 ? "" : "_maxrange" + std::to_string(std::lround(c.max_range)) + "m") +
         (c.discretize ? "_discretize" : "");
}

// Inserts every scan of `graph_path` into octovk (pose overload) and OctoMap (graph2tree's way),
// comparing after every `every`-th scan and after the last.
void compareGraph(Context& ctx, const std::string& graph_path, const InsertCase& c,
                  std::size_t every, std::size_t expected_scans) {
  std::vector<GraphScan> scans;
  {
    test::QuietCout quiet;
    scans = readScanGraph(graph_path);
  }
  const std::vector<OracleScan> oracle_scans = graph2treeScans(graph_path);
  ASSERT_EQ(scans.size(), expected_scans);
  ASSERT_EQ(oracle_scans.size(), scans.size());
  MapParams params;
  params.resolution = c.resolution;
  OccupancyMap map(ctx, params);
  octomap::OcTree oracle = makeOracle(params);
  for (std::size_t i = 0; i < scans.size(); ++i) {
    ASSERT_EQ(scans[i].points_sensor.size(), oracle_scans[i].points_world.size());
    const ScanStats stats = map.insertPointCloud(
        scans[i].points_sensor, graph2treeSensorOrigin(scans[i].T_world_sensor),
        scans[i].T_world_sensor, {.max_range_m = c.max_range, .discretize = c.discretize});
    oracle.insertPointCloud(oracle_scans[i].points_world, oracle_scans[i].origin_world, c.max_range,
                            false, c.discretize);
    ASSERT_EQ(stats.skipped_nonfinite, 0u);
    ASSERT_EQ(stats.nodes, oracle.size()) << "after scan " << i;
    if ((i + 1) % every == 0 || i + 1 == scans.size()) {
      auto ours = toOcTree(map);
      ASSERT_TRUE(sameTree(oracle, *ours)) << "after scan " << i << " of " << graph_path;
    }
  }
  EXPECT_EQ(map.nodeCount(), oracle.size());
  EXPECT_TRUE(test::sameLeaves(oracle, map));
}

// ---- spherical_scan.graph --------------------------------------------------------------------

class SphericalScan : public ::testing::TestWithParam<InsertCase> {};

TEST_P(SphericalScan, EqualsGraph2treeProcedure) {
  OCTOVK_REQUIRE_CONTEXT(ctx);
  compareGraph(ctx, kOctomapData + "/spherical_scan.graph", GetParam(), 1, 1);
}

INSTANTIATE_TEST_SUITE_P(Cases, SphericalScan,
                         ::testing::Values(InsertCase{0.1, -1.0, false},
                                           InsertCase{0.05, -1.0, false},
                                           InsertCase{0.02, -1.0, false},
                                           InsertCase{0.1, 2.0, true}, InsertCase{0.2, 3.0, false}),
                         insertCaseName);

TEST(SphericalScan, ReadScanGraphMatchesOctoMap) {
  const std::string path = kOctomapData + "/spherical_scan.graph";
  test::QuietCout quiet;
  const std::vector<GraphScan> scans = readScanGraph(path);
  octomap::ScanGraph graph;
  ASSERT_TRUE(graph.readBinary(path));
  ASSERT_EQ(scans.size(), 1u);
  ASSERT_EQ(graph.size(), 1u);
  const octomap::ScanNode& node = *graph.getNodeByID(0);
  ASSERT_EQ(scans[0].points_sensor.size(), 10201u);
  ASSERT_EQ(scans[0].points_sensor.size(), node.scan->size());
  for (std::size_t i = 0; i < node.scan->size(); ++i) {
    const octomap::point3d& p = (*node.scan)[i];
    ASSERT_EQ(scans[0].points_sensor[i], Eigen::Vector3f(p.x(), p.y(), p.z())) << "point " << i;
  }
  const Pose& pose = scans[0].T_world_sensor;
  EXPECT_EQ(pose.translation, Eigen::Vector3f(node.pose.x(), node.pose.y(), node.pose.z()));
  EXPECT_EQ(pose.rotation.w(), node.pose.rot().u());
  EXPECT_EQ(pose.rotation.x(), node.pose.rot().x());
  EXPECT_EQ(pose.rotation.y(), node.pose.rot().y());
  EXPECT_EQ(pose.rotation.z(), node.pose.rot().z());
}

// The real graph2tree program, run on the same file, writes the same .ot as octovk.
TEST(SphericalScan, SameOtAsGraph2treeProgram) {
  OCTOVK_REQUIRE_CONTEXT(ctx);
  const std::string graph2tree = OCTOVK_PATH(OCTOVK_GRAPH2TREE);
  ASSERT_FALSE(graph2tree.empty() || graph2tree.find("NOTFOUND") != std::string::npos)
      << "graph2tree (octomap-tools) not found";
  const std::string bt = test::tmpPath("spherical_graph2tree.bt");
  std::remove(bt.c_str());
  std::remove((bt + ".ot").c_str());
  ASSERT_EQ(test::shell(graph2tree + " -i " + kOctomapData + "/spherical_scan.graph -o " + bt +
                        " -res 0.1 > /dev/null 2>&1"),
            0);
  const std::string expected = test::fileBytes(bt + ".ot");
  ASSERT_FALSE(expected.empty());

  std::vector<GraphScan> scans;
  {
    test::QuietCout quiet;
    scans = readScanGraph(kOctomapData + "/spherical_scan.graph");
  }
  MapParams params;
  params.resolution = 0.1;
  OccupancyMap map(ctx, params);
  for (const GraphScan& s : scans)
    map.insertPointCloud(s.points_sensor, graph2treeSensorOrigin(s.T_world_sensor),
                         s.T_world_sensor);
  const std::string ours = test::tmpPath("spherical_octovk.ot");
  writeMapFile(map, ours);
  EXPECT_TRUE(test::fileBytes(ours) == expected) << "octovk's .ot differs from graph2tree's";
  const std::string ours_bt = test::tmpPath("spherical_octovk.bt");
  writeMapFile(map, ours_bt);
  EXPECT_TRUE(test::fileBytes(ours_bt) == test::fileBytes(bt))
      << "octovk's .bt differs from graph2tree's";
}

// ---- scan.dat.bz2: one real 3D scan, sensor at the origin ------------------------------------

const std::vector<Eigen::Vector3f>& scanDat() {
  static std::vector<Eigen::Vector3f> points;
  static std::once_flag once;
  std::call_once(once, [] {
    const std::string src = kOctomapData + "/scan.dat.bz2";
    // Per process: ctest -j runs the cases as separate processes, which would race on one file.
    const std::string dst = test::tmpPath("scan.dat." + std::to_string(::getpid()));
    if (test::shell("bzip2 -dc '" + src + "' > '" + dst + "' 2>/dev/null") != 0 &&
        test::shell("python3 -c \"import bz2,sys; open(sys.argv[2],'wb').write(bz2.open("
                    "sys.argv[1]).read())\" '" +
                    src + "' '" + dst + "'") != 0)
      return;
    std::ifstream in(dst);
    float x, y, z;
    while (in >> x >> y >> z) points.emplace_back(x, y, z);
    std::remove(dst.c_str());
  });
  return points;
}

class ScanDat : public ::testing::TestWithParam<InsertCase> {};

TEST_P(ScanDat, EqualsOctoMap) {
  OCTOVK_REQUIRE_CONTEXT(ctx);
  const InsertCase c = GetParam();
  const auto& points = scanDat();
  ASSERT_EQ(points.size(), 88206u) << "could not decompress scan.dat.bz2";
  MapParams params;
  params.resolution = c.resolution;
  OccupancyMap map(ctx, params);
  octomap::OcTree oracle = makeOracle(params);
  const Eigen::Vector3f origin = Eigen::Vector3f::Zero();
  // The same scan twice: the second time many cells are updated in an existing tree.
  for (int rep = 0; rep < 2; ++rep) {
    ScanStats stats;
    ASSERT_TRUE(test::insertBoth(map, oracle, points, origin, c.max_range, c.discretize, &stats))
        << "repetition " << rep;
    EXPECT_EQ(stats.points, points.size());
    EXPECT_GT(stats.occupied_cells, 1000u);
  }
  EXPECT_TRUE(test::sameLeaves(oracle, map));
}

INSTANTIATE_TEST_SUITE_P(Cases, ScanDat,
                         ::testing::Values(InsertCase{0.1, -1.0, false},
                                           InsertCase{0.05, -1.0, false},
                                           InsertCase{0.05, 3.0, true}),
                         insertCaseName);

// ---- a slice of the FR-079 corridor log ------------------------------------------------------

constexpr std::size_t kFr079Scans = 300;

// fr079.clf.bz2 -> OctoMap text log (clf2log.py) -> scan graph (log2graph), made once.
const std::string& fr079Graph(std::string* why) {
  static std::string graph;
  static std::string error;
  static std::once_flag once;
  std::call_once(once, [] {
    const std::string log2graph = OCTOVK_PATH(OCTOVK_LOG2GRAPH);
    if (log2graph.empty() || log2graph.find("NOTFOUND") != std::string::npos) {
      error = "log2graph (octomap-tools) not found";
      return;
    }
    const std::string dir = kSharedData + "/fr079-2d";
    const std::string log = test::tmpPath("fr079_300.log");
    const std::string out = test::tmpPath("fr079_300.graph");
    if (test::shell("python3 '" + dir + "/clf2log.py' '" + dir + "/fr079.clf.bz2' '" + log + "' " +
                    std::to_string(kFr079Scans) + " > /dev/null") != 0) {
      error = "clf2log.py failed";
      return;
    }
    if (test::shell("'" + log2graph + "' '" + log + "' '" + out + "' > /dev/null 2>&1") != 0) {
      error = "log2graph failed";
      return;
    }
    graph = out;
  });
  if (why) *why = error;
  return graph;
}

class Fr079 : public ::testing::TestWithParam<InsertCase> {};

TEST_P(Fr079, EqualsGraph2treeEvery25Scans) {
  OCTOVK_REQUIRE_CONTEXT(ctx);
  std::string why;
  const std::string& graph = fr079Graph(&why);
  ASSERT_FALSE(graph.empty()) << why;
  compareGraph(ctx, graph, GetParam(), 25, kFr079Scans);
}

INSTANTIATE_TEST_SUITE_P(Slice, Fr079,
                         ::testing::Values(InsertCase{0.1, -1.0, false},
                                           InsertCase{0.1, 10.0, false},
                                           InsertCase{0.05, -1.0, false},
                                           InsertCase{0.05, 10.0, false}),
                         insertCaseName);

}  // namespace
}  // namespace octovk
