// Map message bodies (octomap_msgs/Octomap's id, resolution, binary and data): the bytes octovk
// gives equal OctoMap's writeBinaryData / writeData on the tree OctoMap builds from the same
// scans; a body read back is that tree; damaged and hostile bodies are refused with kFormat and
// leave a map as it was.
#include <octomap/octomap.h>

#include <cmath>
#include <cstring>
#include <limits>
#include <random>
#include <sstream>

#include "io/parse.hpp"
#include "test_support.hpp"

namespace octovk::test {
namespace {

std::vector<std::int8_t> bytesOf(const std::string& s) {
  std::vector<std::int8_t> out(s.size());
  if (!s.empty()) std::memcpy(out.data(), s.data(), s.size());
  return out;
}

std::string octomapBody(const octomap::OcTree& tree, bool binary) {
  std::ostringstream out(std::ios_base::binary);
  if (binary)
    tree.writeBinaryData(out);
  else
    tree.writeData(out);
  return out.str();
}

// OctoMap and octovk fed the same random scans (with a pose, max range on the third).
struct Pair {
  OccupancyMap map;
  octomap::OcTree oracle;
};

Pair scanned(Context& ctx, double resolution, int scans) {
  MapParams params;
  params.resolution = resolution;
  Pair p{OccupancyMap(ctx, params), makeOracle(params)};
  std::mt19937 rng(7);
  for (int i = 0; i < scans; ++i) {
    const Eigen::Vector3f origin(0.3f * static_cast<float>(i), 0.1f, -0.2f);
    const std::vector<Eigen::Vector3f> pts = test::randomScan(rng, origin, 1500, 3.0f);
    const double max_range = i == 2 ? 2.0 : -1.0;
    p.oracle.insertPointCloud(toPointcloud(pts), toPoint(origin), max_range);
    (void)p.map.insertPointCloud(pts, origin, ScanOptions{.max_range_m = max_range});
  }
  return p;
}

TEST(MapMessage, BodiesAreOctoMapsBytesOnTheSameScans) {
  OCTOVK_REQUIRE_CONTEXT(ctx);
  for (const double res : {0.05, 0.2}) {
    Pair p = scanned(ctx, res, 4);
    ASSERT_GT(p.oracle.size(), 1000u);
    const MapMessage binary = binaryMapToMessage(p.map);
    const MapMessage full = fullMapToMessage(p.map);
    for (const MapMessage* m : {&binary, &full}) {
      EXPECT_EQ(m->id, p.oracle.getTreeType());
      EXPECT_EQ(m->resolution, p.oracle.getResolution());
      EXPECT_TRUE(m->data == bytesOf(octomapBody(p.oracle, m->binary)))
          << (m->binary ? "binary" : "full") << " body at " << res << " m differs from OctoMap's ("
          << m->data.size() << " bytes against " << octomapBody(p.oracle, m->binary).size() << ")";
    }
    EXPECT_TRUE(binary.binary);
    EXPECT_FALSE(full.binary);
  }
}

TEST(MapMessage, EmptyMapGivesOctoMapsEmptyBodies) {
  OCTOVK_REQUIRE_CONTEXT(ctx);
  OccupancyMap map(ctx, test::withResolution(0.1));
  const octomap::OcTree empty(0.1);
  for (const bool binary : {true, false}) {
    const MapMessage m = binary ? binaryMapToMessage(map) : fullMapToMessage(map);
    EXPECT_TRUE(m.data.empty());
    EXPECT_EQ(octomapBody(empty, binary), "");
    OccupancyMap back = messageToMap(ctx, m);
    EXPECT_EQ(back.nodeCount(), 0u);
    EXPECT_EQ(back.params().resolution, 0.1);
  }
}

TEST(MapMessage, BodiesReadBackAsOctoMapReadsThem) {
  OCTOVK_REQUIRE_CONTEXT(ctx);
  Pair p = scanned(ctx, 0.1, 3);
  for (const bool binary : {true, false}) {
    SCOPED_TRACE(binary ? "binary" : "full");
    const MapMessage m = binary ? binaryMapToMessage(p.map) : fullMapToMessage(p.map);
    // What OctoMap's msgToMap makes of the same body.
    octomap::OcTree theirs(m.resolution);
    std::istringstream in(octomapBody(p.oracle, binary), std::ios_base::binary);
    if (binary)
      theirs.readBinaryData(in);
    else
      theirs.readData(in);
    OccupancyMap ours = messageToMap(ctx, m);
    EXPECT_TRUE(sameTree(theirs, *toOcTree(ours)));
    // Into an existing map of the same resolution: replaces what it held.
    OccupancyMap other(ctx, test::withResolution(0.1));
    (void)other.insertPointCloud(test::sphere(1.0f, 200, Eigen::Vector3f(5, 5, 5)),
                                 Eigen::Vector3f(5, 5, 5));
    messageToMap(other, m);
    EXPECT_TRUE(sameTree(theirs, *toOcTree(other)));
    // And the round trip gives the same bytes again.
    const MapMessage again = binary ? binaryMapToMessage(ours) : fullMapToMessage(ours);
    EXPECT_TRUE(again.data == m.data);
    // Scans after the import stay equal to OctoMap continuing from the same tree.
    std::mt19937 rng(11);
    const Eigen::Vector3f origin(0.5f, 0.5f, 0.5f);
    const std::vector<Eigen::Vector3f> pts = test::randomScan(rng, origin, 800, 2.5f);
    theirs.insertPointCloud(toPointcloud(pts), toPoint(origin));
    (void)ours.insertPointCloud(pts, origin);
    EXPECT_TRUE(sameTree(theirs, *toOcTree(ours)));
  }
}

// `what` must be refused with `code`, the message naming `name` and containing `why`; the map
// (if any) unchanged.
void expectRefused(const std::function<void()>& call, ErrorCode code, const std::string& name,
                   const std::string& why, const std::string& what) {
  try {
    call();
    ADD_FAILURE() << what << ": accepted";
  } catch (const Error& e) {
    EXPECT_EQ(e.code(), code) << what << ": " << e.what();
    EXPECT_NE(std::string(e.what()).find(name), std::string::npos) << what << ": " << e.what();
    EXPECT_NE(std::string(e.what()).find(why), std::string::npos)
        << what << ": expected '" << why << "' in: " << e.what();
  }
}

TEST(MapMessage, DamagedBodiesAreRefusedAndTheMapKept) {
  OCTOVK_REQUIRE_CONTEXT(ctx);
  Pair p = scanned(ctx, 0.1, 2);
  const std::string before = test::otBytes(*toOcTree(p.map));
  for (const bool binary : {true, false}) {
    SCOPED_TRACE(binary ? "binary" : "full");
    const MapMessage good = binary ? binaryMapToMessage(p.map) : fullMapToMessage(p.map);
    const auto refused = [&](MapMessage m, ErrorCode code, const std::string& why,
                             const std::string& what) {
      expectRefused([&] { messageToMap(p.map, m, "msg-under-test"); }, code, "msg-under-test", why,
                    what);
      expectRefused([&] { (void)messageToMap(ctx, m, 0, "msg-under-test"); }, code,
                    "msg-under-test", why, what);
    };
    MapMessage m = good;
    m.id = "Foo";
    refused(m, ErrorCode::kFormat, "'Foo'; octovk reads OcTree, ColorOcTree and OcTreeStamped",
            "another tree type");
    for (const double res : {0.0, -0.1, std::nan(""), std::numeric_limits<double>::infinity()}) {
      m = good;
      m.resolution = res;
      refused(m, ErrorCode::kFormat, "resolution", "resolution " + std::to_string(res));
    }
    m = good;
    m.resolution = 0.2;
    expectRefused([&] { messageToMap(p.map, m, "msg-under-test"); }, ErrorCode::kInvalidArgument,
                  "msg-under-test", "resolution", "another resolution into this map");
    m = good;
    m.data.push_back(0);
    refused(m, ErrorCode::kFormat, "bytes follow", "a byte after the last record");
    // Every truncation (but to nothing, which is the empty tree) leaves a record unfinished.
    for (std::size_t keep = 1; keep < good.data.size(); keep += 1 + good.data.size() / 97) {
      m = good;
      m.data.resize(keep);
      refused(m, ErrorCode::kFormat, "runs past the end", "truncated to " + std::to_string(keep));
    }
    m = good;
    m.binary = !binary;
    try {  // read as the other kind: refused, or (rarely) a valid tree of the other kind
      (void)messageToMap(ctx, m);
    } catch (const Error& e) {
      EXPECT_EQ(e.code(), ErrorCode::kFormat) << e.what();
    }
  }
  // A full body whose root log-odds is NaN; a binary body nesting deeper than 16 levels.
  MapMessage nan = fullMapToMessage(p.map);
  const float q = std::numeric_limits<float>::quiet_NaN();
  std::memcpy(nan.data.data(), &q, sizeof(q));
  expectRefused([&] { messageToMap(p.map, nan, "nan-body"); }, ErrorCode::kFormat, "nan-body",
                "not a finite number", "NaN log-odds");
  MapMessage deep;
  deep.resolution = 0.1;
  for (int level = 0; level < 40; ++level) {  // child 0 an inner node, all the way down
    deep.data.push_back(3);
    deep.data.push_back(0);
  }
  expectRefused([&] { messageToMap(p.map, deep, "deep-body"); }, ErrorCode::kFormat, "deep-body",
                "deeper than a tree's 16 levels", "41 levels");
  EXPECT_EQ(test::otBytes(*toOcTree(p.map)), before) << "a refused body changed the map";
}

}  // namespace
}  // namespace octovk::test
