// I/O tests: OctoMap .bt / .ot round trips byte for byte, OcTree conversion both ways, scans into
// an imported map, and corrupt or missing files.
#include <octomap/ScanGraph.h>
#include <octomap/octomap.h>
#include <sys/resource.h>

#include <chrono>
#include <filesystem>
#include <fstream>
#include <functional>
#include <limits>

#include "io/parse.hpp"
#include "test_support.hpp"

namespace octovk {
namespace {

using test::randomScan;

namespace fs = std::filesystem;

// A plain OcTree file's bytes read by parseTreeFile, which reads each tree type as its own.
std::unique_ptr<octomap::OcTree> parsePlain(std::string_view bytes, bool binary,
                                            const std::string& name) {
  io::AnyTree tree = io::parseTreeFile(bytes, binary, name);
  EXPECT_EQ(tree.index(), 0u) << name << " read as another tree type than OcTree";
  auto* plain = std::get_if<std::unique_ptr<octomap::OcTree>>(&tree);
  return plain ? std::move(*plain) : std::make_unique<octomap::OcTree>(0.1);
}

using test::fileBytes;
using test::makeOracle;
using test::sameTree;
using test::tmpPath;
using test::toPoint;
using test::toPointcloud;

const std::string kGeb079 = OCTOVK_PATH(OCTOVK_OCTOMAP_DATA_DIR) + "/geb079.bt";
const std::string kSpherical = OCTOVK_PATH(OCTOVK_OCTOMAP_DATA_DIR) + "/spherical_scan.graph";

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

// ---- hostile files (issue 11): refused by octovk's check before OctoMap's reader sees them ----
// Each case is generated from a valid file as the fuzzing of issue 11 found it (one inserted byte,
// a truncated data section, header edits, NaN log-odds); the check runs on bytes, without Vulkan.

struct TreeFiles {
  std::string bt, ot;
  std::size_t bt_data, ot_data;  // where the node data starts
};

const TreeFiles& sphericalFiles() {
  static const TreeFiles files = [] {
    octomap::OcTree tree = sphericalTree(0.1);
    std::stringstream ot, bt;
    EXPECT_TRUE(tree.write(ot));
    EXPECT_TRUE(tree.writeBinary(bt));
    TreeFiles f{bt.str(), ot.str(), 0, 0};
    f.bt_data = f.bt.find("\ndata\n") + 6;
    f.ot_data = f.ot.find("\ndata\n") + 6;
    return f;
  }();
  return files;
}

// The file with the header line that starts with `key` replaced by `line` (removed if empty).
std::string withHeaderLine(const std::string& file, const std::string& key,
                           const std::string& line) {
  const std::size_t at = file.find("\n" + key);
  EXPECT_NE(at, std::string::npos) << key;
  const std::size_t end = file.find('\n', at + 1);
  return file.substr(0, at + 1) + (line.empty() ? "" : line + "\n") + file.substr(end + 1);
}

// parseTreeFile must refuse `bytes` with kFormat, naming the file and mentioning `why`.
void expectRefused(const std::string& bytes, bool binary, const std::string& why,
                   const std::string& what) {
  const std::string name = binary ? "hostile.bt" : "hostile.ot";
  const std::string message = expectError([&] { (void)io::parseTreeFile(bytes, binary, name); },
                                          ErrorCode::kFormat, what.c_str());
  EXPECT_NE(message.find("'" + name + "'"), std::string::npos) << what << ": " << message;
  EXPECT_NE(message.find(why), std::string::npos)
      << what << ": expected '" << why << "' in: " << message;
}

TEST(IoHostile, ValidFilesReadAsOctoMapReadsThem) {
  const TreeFiles& f = sphericalFiles();
  for (const bool binary : {true, false}) {
    const std::string& bytes = binary ? f.bt : f.ot;
    const std::unique_ptr<octomap::OcTree> ours = parsePlain(bytes, binary, "valid");
    std::stringstream in(bytes);
    std::unique_ptr<octomap::OcTree> theirs;
    if (binary) {
      theirs = std::make_unique<octomap::OcTree>(0.1);
      ASSERT_TRUE(theirs->readBinary(in));
    } else {
      std::unique_ptr<octomap::AbstractOcTree> read(octomap::AbstractOcTree::read(in));
      ASSERT_TRUE(dynamic_cast<octomap::OcTree*>(read.get()));
      theirs.reset(static_cast<octomap::OcTree*>(read.release()));
    }
    EXPECT_GT(ours->size(), 1000u);
    EXPECT_TRUE(sameTree(*theirs, *ours)) << (binary ? ".bt" : ".ot");
    // More comment and blank lines, CR LF line ends and spaces are a header OctoMap reads alike.
    std::string edited = withHeaderLine(bytes, "res", "\n# a comment\r\n  res   0.1 \r");
    edited = withHeaderLine(edited, "id", "id OcTree\r");
    EXPECT_TRUE(sameTree(*theirs, *parsePlain(edited, binary, "edited")));
  }
}

TEST(IoHostile, EmptyTreesAsOctoMapWritesThemLoad) {
  OCTOVK_REQUIRE_CONTEXT(ctx);
  octomap::OcTree empty(0.05);
  std::stringstream ot, bt;
  ASSERT_TRUE(empty.write(ot));
  ASSERT_TRUE(empty.writeBinary(bt));
  ASSERT_NE(ot.str().find("\nsize 0\n"), std::string::npos);  // and no byte after "data\n"
  const std::string bt_path = tmpPath("empty_octomap.bt"), ot_path = tmpPath("empty_octomap.ot");
  test::writeBytes(bt_path, bt.str());
  test::writeBytes(ot_path, ot.str());
  for (const std::string& path : {bt_path, ot_path}) {
    OccupancyMap map = readMapFile(ctx, path);
    EXPECT_EQ(map.nodeCount(), 0u) << path;
    EXPECT_EQ(map.params().resolution, 0.05) << path;
  }
}

TEST(IoHostile, OneInsertedByteAnywhereIsRefused) {
  // The issue's .ot that grew memory without bound: the record sizes (5 bytes .ot, 2 bytes .bt)
  // can no longer add up to the data section, whatever the byte and wherever it goes.
  const TreeFiles& f = sphericalFiles();
  for (const bool binary : {true, false}) {
    const std::string& bytes = binary ? f.bt : f.ot;
    const std::size_t data = binary ? f.bt_data : f.ot_data;
    for (std::size_t i = 0; i < 40; ++i) {
      const std::size_t at = data + (bytes.size() - data) * i / 39;
      for (const char c : {'\0', '\x01', '\xff'}) {
        std::string damaged = bytes;
        damaged.insert(at, 1, c);
        SCOPED_TRACE(std::string(binary ? ".bt" : ".ot") + " with a byte inserted at " +
                     std::to_string(at));
        expectError([&] { (void)io::parseTreeFile(damaged, binary, "x"); }, ErrorCode::kFormat,
                    "inserted byte");
      }
    }
  }
}

TEST(IoHostile, EveryTruncationOfTheDataSectionIsRefused) {
  const TreeFiles& f = sphericalFiles();
  for (const bool binary : {true, false}) {
    const std::string& bytes = binary ? f.bt : f.ot;
    const std::size_t data = binary ? f.bt_data : f.ot_data;
    for (std::size_t keep = data; keep < bytes.size(); keep += 1 + (bytes.size() - data) / 500) {
      SCOPED_TRACE(std::string(binary ? ".bt" : ".ot") + " cut to " + std::to_string(keep));
      expectError([&] { (void)io::parseTreeFile(bytes.substr(0, keep), binary, "x"); },
                  ErrorCode::kFormat, "truncated");
    }
    expectRefused(bytes.substr(0, data), binary, "data section is empty", "no data");
    expectRefused(bytes.substr(0, bytes.size() - 1), binary, "past the end", "last byte cut");
  }
}

TEST(IoHostile, DeepNestingAndChildlessInnerNodesAreRefused) {
  const TreeFiles& f = sphericalFiles();
  const std::string bt_header = f.bt.substr(0, f.bt_data), ot_header = f.ot.substr(0, f.ot_data);
  // A .bt header and 200 KB of 0xff: OctoMap's readBinaryNode overflowed the stack (~87,000
  // frames).
  expectRefused(bt_header + std::string(200000, '\xff'), true, "deeper than a tree's 16 levels",
                ".bt + 200 KB of 0xff");
  // .ot records with one child each, 17 deep (a node below the leaves) and 300,000 deep.
  for (std::size_t levels : {17u, 300000u}) {
    std::string data;
    for (std::size_t i = 0; i < levels; ++i) data += std::string(4, '\0') + '\x01';
    expectRefused(ot_header + data, false, "deeper than a tree's 16 levels",
                  ".ot " + std::to_string(levels) + " deep");
  }
  // .bt: the root's child 0 is an inner node (11) whose record lists no child: OctoMap would give
  // it the log-odds of no child, -FLT_MAX.
  expectRefused(withHeaderLine(bt_header, "size", "size 2") + std::string("\x03\x00\x00\x00", 4),
                true, "inner node without children", "childless inner node");
}

TEST(IoHostile, HeaderSizeMustMatchTheData) {
  const TreeFiles& f = sphericalFiles();
  for (const bool binary : {true, false}) {
    const std::string& bytes = binary ? f.bt : f.ot;
    SCOPED_TRACE(binary ? ".bt" : ".ot");
    // size 0 with data: OctoMap read nothing and reported success.
    expectRefused(withHeaderLine(bytes, "size", "size 0"), binary, "announces 0 nodes", "size 0");
    // No size line: OctoMap took size 0 and ignored the data.
    expectRefused(withHeaderLine(bytes, "size", ""), binary, "no 'size' line", "no size");
    const std::unique_ptr<octomap::OcTree> tree = parsePlain(bytes, binary, "valid");
    const std::string more = "size " + std::to_string(tree->size() + 1);
    expectRefused(withHeaderLine(bytes, "size", more), binary, "the data holds", "size + 1");
    for (const char* bad : {"size -1", "size 1e3", "size 18446744073709551616", "size 5 5"})
      expectRefused(withHeaderLine(bytes, "size", bad), binary, "size", bad);
    expectRefused(withHeaderLine(bytes, "size", more) + withHeaderLine(bytes, "size", more), binary,
                  "bytes follow", "two files in one");
  }
}

TEST(IoHostile, TreeTypeMustBeOneOctovkReads) {
  const TreeFiles& f = sphericalFiles();
  for (const bool binary : {true, false}) {
    const std::string& bytes = binary ? f.bt : f.ot;
    SCOPED_TRACE(binary ? ".bt" : ".ot");
    // OctoMap's readBinary ignores the id; octovk reads the three types it has, by name only.
    for (const char* id : {"Foo", "octree", "ColorOcTree2", "CountingOcTree", "ocTreeStamped"})
      expectRefused(withHeaderLine(bytes, "id", std::string("id ") + id), binary,
                    std::string("'") + id + "'; octovk reads OcTree, ColorOcTree and OcTreeStamped",
                    id);
    expectRefused(withHeaderLine(bytes, "id", "id"), binary, "one value", "empty id");
    expectRefused(withHeaderLine(bytes, "id", ""), binary, "no 'id' line", "no id line");
    expectRefused(withHeaderLine(bytes, "id", "id OcTree extra"), binary, "one value", "two ids");
    expectRefused(withHeaderLine(bytes, "id", "id OcTree\nid OcTree"), binary, "twice", "id twice");
  }
}

TEST(IoHostile, ResolutionMustBeOneFinitePositiveNumber) {
  const TreeFiles& f = sphericalFiles();
  for (const bool binary : {true, false}) {
    const std::string& bytes = binary ? f.bt : f.ot;
    SCOPED_TRACE(binary ? ".bt" : ".ot");
    // OctoMap read "res 0.2 0.3" as 0.2 and skipped the 0.3 as an unknown keyword.
    expectRefused(withHeaderLine(bytes, "res", "res 0.2 0.3"), binary, "one value", "two values");
    for (const char* res : {"res 0", "res -0.1", "res nan", "res inf", "res -inf", "res 0.1abc",
                            "res abc", "res 1e-300", "res 1e300"})
      expectRefused(withHeaderLine(bytes, "res", res), binary, "resolution", res);
    expectRefused(withHeaderLine(bytes, "res", ""), binary, "no 'res' line", "no res");
    expectRefused(withHeaderLine(bytes, "res", "res 0.1\nres 0.1"), binary, "twice", "res twice");
    expectRefused(withHeaderLine(bytes, "res", "resolution 0.1"), binary, "unknown header line",
                  "unknown keyword");
    expectRefused(withHeaderLine(bytes, "data", "data more"), binary, "just 'data'", "data x");
    expectRefused(bytes.substr(0, bytes.find("\ndata\n")), binary, "no 'data' line", "no data");
  }
  expectRefused("", true, "empty", "empty .bt");
  expectRefused("", false, "empty", "empty .ot");
  expectRefused(sphericalFiles().ot, true, "name it .ot", ".ot named .bt");
  expectRefused(sphericalFiles().bt, false, "name it .bt", ".bt named .ot");
}

TEST(IoHostile, OtLogOddsMustBeFinite) {
  // NaN log-odds were counted as free and written as "nan" into PLY files.
  const TreeFiles& f = sphericalFiles();
  const std::size_t records = (f.ot.size() - f.ot_data) / 5;
  for (const float v :
       {std::numeric_limits<float>::quiet_NaN(), std::numeric_limits<float>::infinity(),
        -std::numeric_limits<float>::infinity()}) {
    for (const std::size_t record : {std::size_t{0}, records / 2, records - 1}) {
      std::string bytes = f.ot;
      std::memcpy(bytes.data() + f.ot_data + 5 * record, &v, sizeof v);
      expectRefused(bytes, false, "not a finite number",
                    std::to_string(v) + " in record " + std::to_string(record));
    }
  }
}

TEST(IoHostile, MessagesFromReadMapFileNameTheFile) {
  OCTOVK_REQUIRE_CONTEXT(ctx);
  const std::string path = tmpPath("size_zero.bt");
  test::writeBytes(path, withHeaderLine(sphericalFiles().bt, "size", "size 0"));
  const std::string message =
      expectError([&] { readMapFile(ctx, path); }, ErrorCode::kFormat, "size 0 .bt");
  EXPECT_NE(message.find(path), std::string::npos) << message;
  EXPECT_NE(message.find("announces 0 nodes"), std::string::npos) << message;
}

TEST(IoHostile, StoredInputsAreRefused) {
  // tests/data/hostile/: inputs that once broke a reader (see its README).
  const fs::path dir = fs::path(OCTOVK_PATH(OCTOVK_SHARED_DATA_DIR)) / "hostile";
  std::size_t files = 0;
  for (const auto& entry : fs::directory_iterator(dir)) {
    const std::string ext = entry.path().extension().string();
    if (ext != ".bt" && ext != ".ot" && ext != ".graph") continue;
    ++files;
    const std::string name = entry.path().filename().string();
    const std::string bytes = fileBytes(entry.path().string());
    const std::string message = expectError(
        [&] {
          if (ext == ".graph")
            (void)io::parseScanGraph(bytes, name);
          else
            (void)io::parseTreeFile(bytes, ext == ".bt", name);
        },
        ErrorCode::kFormat, name.c_str());
    EXPECT_NE(message.find(name), std::string::npos) << message;
  }
  EXPECT_GE(files, 1u) << "no stored inputs in " << dir;
}

TEST(IoHostile, DevicesNamedLikeInputsAreRefusedAtOnce) {
  // A link named like a map or graph to a device that never ends (/dev/zero).
  OCTOVK_REQUIRE_CONTEXT(ctx);
  if (!fs::exists("/dev/zero")) GTEST_SKIP() << "no /dev/zero";
  for (const char* name : {"zero.bt", "zero.ot", "zero.graph"}) {
    const std::string link = tmpPath(name);
    fs::remove(link);
    fs::create_symlink("/dev/zero", link);
    const std::string message = expectError(
        [&] {
          if (fs::path(link).extension() == ".graph")
            (void)readScanGraph(link);
          else
            (void)readMapFile(ctx, link);
        },
        ErrorCode::kIo, name);
    EXPECT_NE(message.find("not a regular file"), std::string::npos) << message;
    fs::remove(link);
  }
}

// A sparse file of `size` bytes that starts with `prefix` (the rest reads as zeros, holding no
// disk).
void writeSparse(const std::string& path, const std::string& prefix, std::uintmax_t size) {
  test::writeBytes(path, prefix);
  fs::resize_file(path, size);
}

// The peak RSS of this process so far, in MiB.
long peakRssMib() {
  rusage usage{};
  getrusage(RUSAGE_SELF, &usage);
  return usage.ru_maxrss / 1024;
}

TEST(IoHostile, SparseFilesFailAtTheirFirstFaultUnread) {
  // A 2 GiB file holding 4 kB on disk was read whole before its first record was checked: 3 GiB
  // took 17 s and 3.2 GB of RSS. Now the reader reads pieces as its checks reach them, and the
  // zeros fail at once: memory and time follow what the file holds, not its size.
  OCTOVK_REQUIRE_CONTEXT(ctx);
  const std::uintmax_t size = std::uintmax_t{2} << 30;
  const std::string bt_header =
      "# Octomap OcTree binary file\nid OcTree\nsize 1000\nres 0.1\ndata\n";
  const std::string ot_header = "# Octomap OcTree file\nid OcTree\nsize 1000\nres 0.1\ndata\n";
  const auto u32 = [](std::uint32_t v) {  // the graph's counts, in host order
    return std::string(reinterpret_cast<const char*>(&v), 4);
  };
  // Edges fill the rest exactly: 0 scans, then as many 80-byte edges as the zeros make up.
  const std::uint32_t edges = static_cast<std::uint32_t>((size - 8) / 80);
  struct Case {
    const char* name;
    std::string prefix;
    std::uintmax_t size;
    const char* why;
  };
  const std::vector<Case> cases = {
      {"zeros.bt", "", size, "first line"},
      {"zeros.ot", "", size, "first line"},
      {"header.bt", bt_header, size, "bytes follow"},
      {"header.ot", ot_header, size, "bytes follow"},
      {"comment.bt", "# Octomap OcTree binary file\n# ", size, "longer than"},
      {"zeros.graph", "", size, "length does not match"},
      {"one_scan.graph", u32(1), size, "bad scan 0 pose translation record"},
      {"edges.graph", u32(0) + u32(edges), 8 + std::uintmax_t{edges} * 80,
       "bad edge 0 translation record"},
  };
  for (const Case& c : cases) {
    SCOPED_TRACE(c.name);
    const std::string path = tmpPath(std::string("sparse_") + c.name);
    writeSparse(path, c.prefix, c.size);
    const long rss_before = peakRssMib();
    const auto start = std::chrono::steady_clock::now();
    const std::string message = expectError(
        [&] {
          if (fs::path(path).extension() == ".graph")
            (void)readScanGraph(path);
          else
            (void)readMapFile(ctx, path);
        },
        ErrorCode::kFormat, c.name);
    const double seconds =
        std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
    fs::remove(path);
    EXPECT_NE(message.find(c.why), std::string::npos) << message;
    EXPECT_NE(message.find(path), std::string::npos) << message;
    EXPECT_LT(peakRssMib() - rss_before, 64) << "MiB of RSS for a file of 2 GiB of zeros";
    EXPECT_LT(seconds, 2.0) << "to refuse a file of 2 GiB of zeros";
  }
}

TEST(IoHostile, TreeFilesAreCheckedAsTheyAreRead) {
  // The streamed reader gives the buffer's verdicts: a valid file reads as OctoMap's, a byte
  // more is refused, and a comment line too long to be one fails without being read whole.
  OCTOVK_REQUIRE_CONTEXT(ctx);
  const TreeFiles& f = sphericalFiles();
  for (const bool binary : {true, false}) {
    SCOPED_TRACE(binary ? ".bt" : ".ot");
    const std::string& bytes = binary ? f.bt : f.ot;
    const std::string path = tmpPath(binary ? "streamed.bt" : "streamed.ot");
    test::writeBytes(path, bytes);
    OccupancyMap map = readMapFile(ctx, path);
    EXPECT_TRUE(sameTree(*toOcTree(map), *parsePlain(bytes, binary, "valid")));
    test::writeBytes(path, bytes + '\0');
    expectError([&] { (void)readMapFile(ctx, path); }, ErrorCode::kFormat, "a byte more");
    std::string long_comment = bytes;
    long_comment.insert(long_comment.find('\n') + 1, "# " + std::string(70000, 'x') + "\n");
    const std::string message =
        expectError([&] { (void)io::parseTreeFile(long_comment, binary, "long"); },
                    ErrorCode::kFormat, "a 70 kB comment line");
    EXPECT_NE(message.find("longer than 65536 bytes"), std::string::npos) << message;
    fs::remove(path);
  }
}

// ---- hostile scan graphs ----

std::string u32Bytes(std::uint32_t v) { return std::string(reinterpret_cast<const char*>(&v), 4); }

TEST(IoHostile, GraphCountsBeyondTheBytesAreRefusedBeforeAllocating) {
  const std::string graph = fileBytes(kSpherical);
  ASSERT_GT(graph.size(), 1000u);
  // 4 billion scans in 8 bytes, and 4 billion points in the first scan.
  for (const std::string& bytes : {u32Bytes(0xFFFFFFFFu) + u32Bytes(0),
                                   u32Bytes(1) + u32Bytes(0xFFFFFFFFu) + graph.substr(8)}) {
    const std::string message = expectError([&] { (void)io::parseScanGraph(bytes, "huge.graph"); },
                                            ErrorCode::kFormat, "huge count");
    EXPECT_NE(message.find("'huge.graph'"), std::string::npos) << message;
    EXPECT_NE(message.find("more than"), std::string::npos) << message;
  }
  // Every truncation of a real graph.
  for (std::size_t keep = 0; keep < graph.size(); keep += 1 + graph.size() / 300)
    expectError([&] { (void)io::parseScanGraph(graph.substr(0, keep), "cut.graph"); },
                ErrorCode::kFormat, ("graph cut to " + std::to_string(keep)).c_str());
  EXPECT_FALSE(io::parseScanGraph(graph, "whole.graph").empty());
}

TEST(IoHostile, GraphPosesMustBeFinitePointsMayBeNaN) {
  // One scan: a NaN point and a regular one, then the pose.
  const auto vec = [](double x, double y, double z) {
    std::string s = u32Bytes(3);
    for (double v : {x, y, z}) s.append(reinterpret_cast<const char*>(&v), 8);
    return s;
  };
  const auto graph = [&](double tx) {
    std::string pose = vec(tx, 0, 0) + u32Bytes(4);
    for (double v : {1.0, 0.0, 0.0, 0.0}) pose.append(reinterpret_cast<const char*>(&v), 8);
    return u32Bytes(1) + u32Bytes(2) + vec(std::numeric_limits<double>::quiet_NaN(), 0, 0) +
           vec(1, 2, 3) + pose + u32Bytes(0) + u32Bytes(0);
  };
  const std::vector<GraphScan> scans = io::parseScanGraph(graph(0.5), "nan_point.graph");
  ASSERT_EQ(scans.size(), 1u);
  ASSERT_EQ(scans[0].points_sensor.size(), 2u);
  EXPECT_TRUE(std::isnan(scans[0].points_sensor[0].x()));
  EXPECT_EQ(scans[0].T_world_sensor.translation.x(), 0.5f);
  for (const double bad :
       {std::numeric_limits<double>::quiet_NaN(), std::numeric_limits<double>::infinity(), 1e300}) {
    const std::string message =
        expectError([&] { (void)io::parseScanGraph(graph(bad), "bad_pose.graph"); },
                    ErrorCode::kFormat, "non-finite pose");
    EXPECT_NE(message.find("pose is not finite"), std::string::npos) << message;
  }
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
