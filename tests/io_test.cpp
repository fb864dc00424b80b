// I/O tests: OctoMap .bt / .ot round trips byte for byte, OcTree conversion both ways, scans into
// an imported map, and corrupt or missing files.
#include <octomap/ScanGraph.h>
#include <octomap/octomap.h>

#include <filesystem>
#include <fstream>
#include <functional>

#include "test_support.hpp"

namespace octovk {
namespace {

using test::randomScan;

namespace fs = std::filesystem;
using test::fileBytes;
using test::makeOracle;
using test::sameTree;
using test::tmpPath;
using test::toPoint;
using test::toPointcloud;

const std::string kGeb079 = std::string(OCTOVK_OCTOMAP_DATA_DIR) + "/geb079.bt";
const std::string kSpherical = std::string(OCTOVK_OCTOMAP_DATA_DIR) + "/spherical_scan.graph";

std::unique_ptr<octomap::OcTree> readOctoMapBt(const std::string& path) {
  auto tree = std::make_unique<octomap::OcTree>(0.1);
  EXPECT_TRUE(tree->readBinary(path)) << path;
  return tree;
}

// spherical_scan.graph inserted by OctoMap as graph2tree does, with the given resolution.
octomap::OcTree sphericalTree(double resolution) {
  MapParams params;
  params.resolution = resolution;
  octomap::OcTree tree = makeOracle(params);
  octomap::ScanGraph graph;
  {
    test::QuietCout quiet;
    EXPECT_TRUE(graph.readBinary(kSpherical));
  }
  for (octomap::ScanNode* node : graph) {
    const octomath::Pose6D pose = node->pose;
    const octomap::point3d origin = pose.transform(pose.inv().transform(pose.trans()));
    octomap::Pointcloud pc = *node->scan;
    pc.transform(pose);
    tree.insertPointCloud(pc, origin, -1.0, false, false);
  }
  return tree;
}

// Runs `call`, which must throw octovk::Error with `code`; returns its message.
std::string expectError(const std::function<void()>& call, ErrorCode code, const char* what) {
  try {
    call();
  } catch (const Error& e) {
    EXPECT_EQ(e.code(), code) << what << ": " << e.what();
    EXPECT_GT(std::string(e.what()).size(), 10u) << what;
    return e.what();
  } catch (const std::exception& e) {
    ADD_FAILURE() << what << ": threw something else than octovk::Error: " << e.what();
    return {};
  }
  ADD_FAILURE() << what << ": no exception";
  return {};
}

// ---- round trips ------------------------------------------------------------------------------

TEST(Io, Geb079BtRoundTripIsByteIdentical) {
  OCTOVK_REQUIRE_CONTEXT(ctx);
  OccupancyMap map = readMapFile(ctx, kGeb079);
  EXPECT_DOUBLE_EQ(map.params().resolution, 0.08);
  EXPECT_EQ(map.nodeCount(), 532566u);
  auto oracle = readOctoMapBt(kGeb079);
  EXPECT_EQ(map.nodeCount(), oracle->size());
  EXPECT_TRUE(sameTree(*oracle, *toOcTree(map)));
  EXPECT_EQ(map.leafCount(), oracle->getNumLeafNodes());
  EXPECT_TRUE(test::sameLeaves(*oracle, map));

  const std::string out = tmpPath("geb079_copy.bt");
  fs::remove(out);
  writeMapFile(map, out);
  const std::string original = fileBytes(kGeb079);
  ASSERT_FALSE(original.empty());
  EXPECT_TRUE(fileBytes(out) == original) << "written .bt differs from geb079.bt";
  // Writing does not change the map.
  EXPECT_TRUE(sameTree(*oracle, *toOcTree(map)));
  // And the copy reads back the same.
  OccupancyMap again = readMapFile(ctx, out);
  EXPECT_TRUE(sameTree(*oracle, *toOcTree(again)));
}

TEST(Io, OtRoundTripIsByteIdentical) {
  OCTOVK_REQUIRE_CONTEXT(ctx);
  for (double res : {0.1, 0.05}) {
    SCOPED_TRACE("resolution " + std::to_string(res));
    octomap::OcTree tree = sphericalTree(res);
    ASSERT_GT(tree.size(), 1000u);
    const std::string ot = tmpPath("spherical_octomap.ot");
    ASSERT_TRUE(tree.write(ot));
    OccupancyMap map = readMapFile(ctx, ot);
    EXPECT_EQ(map.params().resolution, res);
    EXPECT_EQ(map.nodeCount(), tree.size());
    EXPECT_TRUE(sameTree(tree, *toOcTree(map)));
    EXPECT_TRUE(test::sameLeaves(tree, map));

    const std::string out = tmpPath("spherical_octovk.ot");
    writeMapFile(map, out);
    EXPECT_TRUE(fileBytes(out) == fileBytes(ot)) << "written .ot differs from OctoMap's";

    // .bt from the same map: OctoMap's writeBinary (max-likelihood, pruned) of the same tree.
    const std::string bt = tmpPath("spherical_octovk.bt");
    writeMapFile(map, bt);
    octomap::OcTree copy(tree);
    std::stringstream expected;
    ASSERT_TRUE(copy.writeBinary(expected));
    EXPECT_TRUE(fileBytes(bt) == expected.str()) << "written .bt differs from OctoMap's";
    // The full log-odds survive writing a .bt (which prunes a copy, not the map).
    EXPECT_TRUE(sameTree(tree, *toOcTree(map)));
  }
}

TEST(Io, FromOcTreeThenToOcTreeGivesTheSameTree) {
  OCTOVK_REQUIRE_CONTEXT(ctx);
  // An empty tree, a single-node path, a pruned tree from scans, and geb079.
  std::vector<std::pair<std::string, std::unique_ptr<octomap::OcTree>>> trees;
  trees.emplace_back("empty", std::make_unique<octomap::OcTree>(0.1));
  auto single = std::make_unique<octomap::OcTree>(0.1);
  single->updateNode(octomap::point3d(1.0f, -2.0f, 3.0f), true);
  trees.emplace_back("single cell", std::move(single));
  auto pruned = std::make_unique<octomap::OcTree>(sphericalTree(0.1));
  trees.emplace_back("spherical 0.1", std::move(pruned));
  auto scanned = std::make_unique<octomap::OcTree>(0.05);
  {
    std::mt19937 rng(12);
    for (int i = 0; i < 8; ++i) {
      const auto pts = randomScan(rng, Eigen::Vector3f::Zero(), 300, 1.0f);
      scanned->insertPointCloud(toPointcloud(pts), octomap::point3d(0, 0, 0));
    }
  }
  trees.emplace_back("random scans 0.05", std::move(scanned));
  trees.emplace_back("geb079", readOctoMapBt(kGeb079));

  for (const auto& [name, tree] : trees) {
    SCOPED_TRACE(name);
    MapParams params;
    params.resolution = tree->getResolution();
    OccupancyMap map(ctx, params);
    fromOcTree(map, *tree);
    EXPECT_EQ(map.nodeCount(), tree->size());
    EXPECT_TRUE(sameTree(*tree, *toOcTree(map)));
    EXPECT_TRUE(test::sameLeaves(*tree, map));
    // Replacing the contents again (another tree, then this one) works.
    octomap::OcTree other(params.resolution);
    other.updateNode(octomap::point3d(-0.5f, 0.25f, 0.75f), false);
    fromOcTree(map, other);
    EXPECT_TRUE(sameTree(other, *toOcTree(map)));
    EXPECT_EQ(map.nodeCount(), 17u);
    fromOcTree(map, *tree);
    EXPECT_TRUE(sameTree(*tree, *toOcTree(map)));
  }
}

TEST(Io, FromOcTreeWithOtherResolutionThrows) {
  OCTOVK_REQUIRE_CONTEXT(ctx);
  MapParams params;
  params.resolution = 0.1;
  OccupancyMap map(ctx, params);
  octomap::OcTree other(0.05);
  other.updateNode(octomap::point3d(0.1f, 0.2f, 0.3f), true);
  expectError([&] { fromOcTree(map, other); }, ErrorCode::kInvalidArgument, "resolution mismatch");
  EXPECT_EQ(map.nodeCount(), 0u);
}

// Scans into an imported map behave exactly as OctoMap's scans into the same imported tree: the
// uploaded pool works like one built by scans (expansion of pruned nodes, early abort at the
// clamping bounds that a .bt holds everywhere).
struct ImportCase {
  const char* name;
  bool from_bt;
};

void PrintTo(const ImportCase& c, std::ostream* os) { *os << c.name; }

class InsertAfterImport : public ::testing::TestWithParam<ImportCase> {};

TEST_P(InsertAfterImport, EqualsOctoMapInsertingIntoTheSameTree) {
  OCTOVK_REQUIRE_CONTEXT(ctx);
  std::string path;
  std::unique_ptr<octomap::OcTree> oracle;
  if (GetParam().from_bt) {
    path = kGeb079;
    oracle = readOctoMapBt(kGeb079);
  } else {
    path = tmpPath("spherical_import.ot");
    ASSERT_TRUE(sphericalTree(0.1).write(path));
    std::unique_ptr<octomap::AbstractOcTree> read(octomap::AbstractOcTree::read(path));
    oracle.reset(dynamic_cast<octomap::OcTree*>(read.release()));
    ASSERT_NE(oracle, nullptr);
  }
  OccupancyMap map = readMapFile(ctx, path);
  ASSERT_TRUE(sameTree(*oracle, *toOcTree(map)));

  double x0, y0, z0, x1, y1, z1;
  oracle->getMetricMin(x0, y0, z0);
  oracle->getMetricMax(x1, y1, z1);
  std::mt19937 rng(17);
  std::uniform_real_distribution<double> ux(x0, x1), uy(y0, y1), uz(z0, z1);
  for (int scan = 0; scan < 8; ++scan) {
    // Origins inside the map's bounds; some scans repeat to reach the clamping bounds.
    std::mt19937 scan_rng(scan % 2 == 0 ? 100 + scan : 99);
    const Eigen::Vector3f origin =
        scan % 2 == 0
            ? Eigen::Vector3f(static_cast<float>(ux(rng)), static_cast<float>(uy(rng)),
                              static_cast<float>(uz(rng)))
            : Eigen::Vector3f(static_cast<float>((x0 + x1) / 2), static_cast<float>((y0 + y1) / 2),
                              static_cast<float>((z0 + z1) / 2));
    const auto pts = randomScan(scan_rng, origin, 2000, 4.0f);
    const double max_range = scan % 3 == 2 ? 2.5 : -1.0;
    ASSERT_TRUE(test::insertBoth(map, *oracle, pts, origin, max_range, scan % 4 == 3))
        << "scan " << scan;
  }
  EXPECT_TRUE(test::sameLeaves(*oracle, map));
}

INSTANTIATE_TEST_SUITE_P(Files, InsertAfterImport,
                         ::testing::Values(ImportCase{"geb079_bt", true},
                                           ImportCase{"spherical_ot", false}),
                         [](const ::testing::TestParamInfo<ImportCase>& info) {
                           return std::string(info.param.name);
                         });

// ---- corrupt and missing files -----------------------------------------------------------------

TEST(Io, CorruptFilesThrowFormatErrors) {
  OCTOVK_REQUIRE_CONTEXT(ctx);
  std::mt19937 rng(5);
  std::uniform_int_distribution<int> byte(0, 255);
  auto randomBytes = [&](std::size_t n) {
    std::string s(n, '\0');
    for (char& c : s) c = static_cast<char>(byte(rng));
    return s;
  };
  for (const char* ext : {".bt", ".ot"}) {
    const std::string path = tmpPath(std::string("random") + ext);
    test::writeBytes(path, randomBytes(4096));
    expectError([&] { readMapFile(ctx, path); }, ErrorCode::kFormat, path.c_str());
    const std::string empty = tmpPath(std::string("empty") + ext);
    test::writeBytes(empty, "");
    expectError([&] { readMapFile(ctx, empty); }, ErrorCode::kFormat, empty.c_str());
  }

  // A .bt header followed by garbage, and an .ot header followed by garbage.
  const std::string geb = fileBytes(kGeb079);
  ASSERT_GT(geb.size(), 1000u);
  const std::size_t data_at = geb.find("\ndata\n") + 6;
  ASSERT_GT(data_at, 6u);
  {
    // The node data of a real map with a flipped resolution line.
    const std::string path = tmpPath("bad_resolution.bt");
    std::string bytes = geb;
    const std::size_t res_at = bytes.find("\nres ");
    ASSERT_NE(res_at, std::string::npos);
    bytes.replace(res_at + 5, 4, "-1.0");
    test::writeBytes(path, bytes);
    expectError([&] { readMapFile(ctx, path); }, ErrorCode::kFormat, "negative resolution");
  }

  // Wrong headers: a .bt holding an .ot and an .ot holding a .bt.
  {
    octomap::OcTree tree = sphericalTree(0.1);
    const std::string ot_as_bt = tmpPath("ot_content.bt");
    {
      std::ofstream out(ot_as_bt, std::ios_base::binary);
      tree.write(out);
    }
    expectError([&] { readMapFile(ctx, ot_as_bt); }, ErrorCode::kFormat, "an .ot named .bt");
    const std::string bt_as_ot = tmpPath("bt_content.ot");
    test::writeBytes(bt_as_ot, geb);
    expectError([&] { readMapFile(ctx, bt_as_ot); }, ErrorCode::kFormat, "a .bt named .ot");
    const std::string text = tmpPath("text.bt");
    test::writeBytes(text, "# Not an octree\nhello\n");
    expectError([&] { readMapFile(ctx, text); }, ErrorCode::kFormat, "a text file named .bt");
  }
}

TEST(Io, TruncatedBtThrowsFormatError) {
  OCTOVK_REQUIRE_CONTEXT(ctx);
  const std::string geb = fileBytes(kGeb079);
  ASSERT_GT(geb.size(), 1000u);
  const std::size_t data_at = geb.find("\ndata\n") + 6;
  for (std::size_t keep :
       {geb.size() - 1, geb.size() / 2, data_at + 10, data_at, data_at - 3, std::size_t{20}}) {
    const std::string path = tmpPath("truncated.bt");
    test::writeBytes(path, geb.substr(0, keep));
    expectError([&] { readMapFile(ctx, path); }, ErrorCode::kFormat,
                ("geb079.bt cut to " + std::to_string(keep) + " bytes").c_str());
  }
}

TEST(Io, TruncatedOtThrowsFormatError) {
  OCTOVK_REQUIRE_CONTEXT(ctx);
  octomap::OcTree tree = sphericalTree(0.1);
  std::stringstream s;
  ASSERT_TRUE(tree.write(s));
  const std::string ot = s.str();
  const std::size_t data_at = ot.find("\ndata\n") + 6;
  ASSERT_GT(data_at, 6u);
  for (std::size_t keep : {ot.size() - 1, ot.size() / 2, data_at + 7, data_at}) {
    const std::string path = tmpPath("truncated.ot");
    test::writeBytes(path, ot.substr(0, keep));
    expectError([&] { readMapFile(ctx, path); }, ErrorCode::kFormat,
                ("spherical .ot cut to " + std::to_string(keep) + " bytes").c_str());
  }
}

// Files whose node records nest deeper than a tree's 16 levels: OctoMap's recursive readers would
// follow them until the stack overflows (a .bt header then 200 KB of 0xff, ~87,000 frames).
// They are refused as format errors before OctoMap reads them, quickly.
TEST(Io, NodeRecordsNestedDeeperThanSixteenLevelsAreRefused) {
  OCTOVK_REQUIRE_CONTEXT(ctx);
  octomap::OcTree tree = sphericalTree(0.1);
  std::stringstream ot_stream, bt_stream;
  ASSERT_TRUE(tree.write(ot_stream));
  ASSERT_TRUE(tree.writeBinary(bt_stream));
  const std::string ot = ot_stream.str(), bt = bt_stream.str();
  const std::size_t ot_data = ot.find("\ndata\n") + 6, bt_data = bt.find("\ndata\n") + 6;
  ASSERT_GT(ot_data, 6u);
  ASSERT_GT(bt_data, 6u);
  // .ot: every record a float log-odds and a child byte announcing one child.
  for (std::size_t levels : {17u, 300000u}) {
    std::string data;
    for (std::size_t i = 0; i < levels; ++i) data += std::string(4, '\0') + std::string(1, '\x01');
    const std::string path = tmpPath("deep.ot");
    test::writeBytes(path, ot.substr(0, ot_data) + data);
    expectError([&] { readMapFile(ctx, path); }, ErrorCode::kFormat,
                (".ot nested " + std::to_string(levels) + " levels").c_str());
  }
  // .bt: all child pairs 11 (inner child follows), the fuzzing case of issue 11.
  const std::string path = tmpPath("deep.bt");
  test::writeBytes(path, bt.substr(0, bt_data) + std::string(200000, '\xff'));
  expectError([&] { readMapFile(ctx, path); }, ErrorCode::kFormat, ".bt header + 200 KB of 0xff");
}

TEST(Io, MissingFileAndUnknownExtension) {
  OCTOVK_REQUIRE_CONTEXT(ctx);
  const std::string missing = tmpPath("does_not_exist.bt");
  fs::remove(missing);
  expectError([&] { readMapFile(ctx, missing); }, ErrorCode::kIo, "nonexistent .bt");
  expectError([&] { readMapFile(ctx, tmpPath("does_not_exist.ot")); }, ErrorCode::kIo,
              "nonexistent .ot");
  expectError([&] { readMapFile(ctx, "/nonexistent-dir-octovk/x.bt"); }, ErrorCode::kIo,
              "nonexistent directory");
  // A directory named like a map.
  const std::string dir_bt = tmpPath("a_directory.bt");
  fs::create_directories(dir_bt);
  try {
    readMapFile(ctx, dir_bt);
    ADD_FAILURE() << "reading a directory did not throw";
  } catch (const Error& e) {
    EXPECT_TRUE(e.code() == ErrorCode::kIo || e.code() == ErrorCode::kFormat) << e.what();
  }
  // A valid map with an unknown extension is refused by its name.
  const std::string txt = tmpPath("geb079.txt");
  fs::copy_file(kGeb079, txt, fs::copy_options::overwrite_existing);
  const std::string why =
      expectError([&] { readMapFile(ctx, txt); }, ErrorCode::kInvalidArgument, ".txt");
  EXPECT_NE(why.find(".txt"), std::string::npos) << why;
  expectError([&] { readMapFile(ctx, tmpPath("no_extension")); }, ErrorCode::kInvalidArgument,
              "no extension");
}

TEST(Io, WriteErrorsLeaveNoFile) {
  OCTOVK_REQUIRE_CONTEXT(ctx);
  MapParams params;
  params.resolution = 0.1;
  OccupancyMap map(ctx, params);
  std::mt19937 rng(1);
  const auto pts = randomScan(rng, Eigen::Vector3f::Zero(), 200, 1.0f);
  map.insertPointCloud(pts, Eigen::Vector3f::Zero());

  const std::string dir = tmpPath("write_errors");
  fs::remove_all(dir);
  fs::create_directories(dir);
  for (const char* name : {"map.txt", "map.bt.bak", "map"}) {
    const std::string path = dir + "/" + name;
    expectError([&] { writeMapFile(map, path); }, ErrorCode::kInvalidArgument, name);
    EXPECT_FALSE(fs::exists(path)) << path;
  }
  const std::string missing_dir = dir + "/no/such/dir/map.bt";
  expectError([&] { writeMapFile(map, missing_dir); }, ErrorCode::kIo, "nonexistent directory");
  EXPECT_FALSE(fs::exists(dir + "/no"));
  expectError([&] { writeMapFile(map, dir + "/no/map.ot"); }, ErrorCode::kIo,
              "nonexistent directory (.ot)");
  // A path whose target is a directory cannot be replaced by the file.
  fs::create_directories(dir + "/taken.bt");
  expectError([&] { writeMapFile(map, dir + "/taken.bt"); }, ErrorCode::kIo, "target is a dir");
  EXPECT_TRUE(fs::is_directory(dir + "/taken.bt"));
  // No temporary files left behind by the failed writes.
  std::size_t entries = 0;
  for (const auto& e : fs::directory_iterator(dir)) {
    ++entries;
    EXPECT_EQ(e.path().filename(), "taken.bt") << "left behind: " << e.path();
  }
  EXPECT_EQ(entries, 1u);
  // A good write after the failures works.
  writeMapFile(map, dir + "/good.ot");
  OccupancyMap back = readMapFile(ctx, dir + "/good.ot");
  EXPECT_TRUE(sameTree(*toOcTree(map), *toOcTree(back)));
}

}  // namespace
}  // namespace octovk
