// ColorMap and StampedMap against OctoMap's ColorOcTree and OcTreeStamped (issue 29): the same
// scans into both, and after every scan the trees equal node by node (log-odds bits, colours of
// all nodes after updateInnerOccupancy, stamps of leaves); then every other feature on payload
// maps (search, castRays, leavesInBox, clearBox, keepBox, change detection, compact, download and
// upload, .ot files) keeps the colours and stamps OctoMap would.
#include "payload_oracle.hpp"

#include <octomap/ScanGraph.h>
#include <octomap/octomap.h>
#include <quadmath.h>
#include <unistd.h>

#include <Eigen/Geometry>
#include <algorithm>
#include <bit>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <limits>
#include <mutex>
#include <random>
#include <set>
#include <tuple>

#include "changed_keys.hpp"
#include "map/context_access.hpp"
#include "map/device_probe.hpp"
#include "probability_oracle.hpp"
#include "rt_paths.hpp"

namespace octovk::test {
namespace {

// ---- one scan into both ------------------------------------------------------------------------

/// Channels of integrateNodeColor's steps whose double is negative (old * p + new * (0.99 - p)
/// with p > 0.99, converted to uint8_t as x86-64 GCC does) if `point`'s colour `c` were folded now.
std::size_t negativeChannels(const octomap::ColorOcTree& oracle, const Eigen::Vector3f& point,
                             const Rgb& c) {
  const octomap::ColorOcTreeNode* n = oracle.search(toPoint(point));
  if (!n || !n->isColorSet()) return 0;
  const double p = n->getOccupancy();
  const auto old = n->getColor();
  std::size_t count = 0;
  for (auto [o, v] : {std::pair{old.r, c.r}, {old.g, c.g}, {old.b, c.b}})
    count += static_cast<double>(o) * p + static_cast<double>(v) * (0.99 - p) < 0.0;
  return count;
}

/// ColorOcTree::insertPointCloud, then averageNodeColor (integrateNodeColor) for every point in
/// order, then updateInnerOccupancy(); the map's scan; the trees compared. `negative` (if given)
/// adds up negativeChannels of the integrated points.
::testing::AssertionResult insertColorBoth(ColorMap& map, octomap::ColorOcTree& oracle,
                                           const std::vector<Eigen::Vector3f>& points,
                                           const Eigen::Vector3f& origin,
                                           const std::vector<Rgb>& colors, double max_range,
                                           bool discretize, ColorFold fold = ColorFold::kAverage,
                                           std::size_t* negative = nullptr) {
  oracle.insertPointCloud(toPointcloud(points), toPoint(origin), max_range, false, discretize);
  for (std::size_t i = 0; i < points.size(); ++i) {
    const Eigen::Vector3f& p = points[i];
    const Rgb& c = colors[i];
    if (fold == ColorFold::kAverage) {
      oracle.averageNodeColor(p.x(), p.y(), p.z(), c.r, c.g, c.b);
    } else {
      if (negative) *negative += negativeChannels(oracle, p, c);
      oracle.integrateNodeColor(p.x(), p.y(), p.z(), c.r, c.g, c.b);
    }
  }
  oracle.updateInnerOccupancy();
  const ScanStats s = map.insertPointCloud(
      points, origin, colors,
      {.max_range_m = max_range, .discretize = discretize, .color_fold = fold});
  if (s.nodes != oracle.size())
    return ::testing::AssertionFailure()
           << "ScanStats::nodes " << s.nodes << " but OctoMap has " << oracle.size() << " nodes";
  return samePayloadTree(oracle, map.download(), Payload::kColor);
}

/// OcTreeStamped (stamping `stamp`) and the map's scan with that stamp; the trees compared.
::testing::AssertionResult insertStampedBoth(StampedMap& map, StampedOracle& oracle,
                                             const std::vector<Eigen::Vector3f>& points,
                                             const Eigen::Vector3f& origin, std::uint32_t stamp,
                                             double max_range = -1.0, bool discretize = false) {
  oracle.setScanTime(stamp);
  oracle.insertPointCloud(toPointcloud(points), toPoint(origin), max_range, false, discretize);
  const ScanStats s = map.insertPointCloud(points, origin, stamp,
                                           {.max_range_m = max_range, .discretize = discretize});
  if (s.nodes != oracle.size())
    return ::testing::AssertionFailure()
           << "ScanStats::nodes " << s.nodes << " but OctoMap has " << oracle.size() << " nodes";
  return samePayloadTree(oracle, map.download(), Payload::kStamp);
}

/// The map's stamps(points) against OctoMap's search()->getTimestamp() (0 where none).
::testing::AssertionResult sameStamps(StampedMap& map, const StampedOracle& oracle,
                                      const std::vector<Eigen::Vector3f>& points) {
  const std::vector<std::uint32_t> got = map.stamps(points);
  if (got.size() != points.size())
    return ::testing::AssertionFailure() << got.size() << " stamps for " << points.size();
  for (std::size_t i = 0; i < points.size(); ++i) {
    const auto* n = oracle.search(toPoint(points[i]));
    const std::uint32_t want = n ? n->getTimestamp() : 0u;
    if (got[i] != want)
      return ::testing::AssertionFailure() << "point " << i << " (" << points[i].transpose()
                                           << "): stamp OctoMap " << want << ", octovk " << got[i];
  }
  return ::testing::AssertionSuccess();
}

/// The map's colors(points) against OctoMap's search()->getColor() (white where none).
::testing::AssertionResult sameColors(ColorMap& map, const octomap::ColorOcTree& oracle,
                                      const std::vector<Eigen::Vector3f>& points) {
  const std::vector<Rgb> got = map.colors(points);
  if (got.size() != points.size())
    return ::testing::AssertionFailure() << got.size() << " colours for " << points.size();
  for (std::size_t i = 0; i < points.size(); ++i) {
    const auto* n = oracle.search(toPoint(points[i]));
    const std::uint32_t want = n ? payloadOf(*n) : packRgb(Rgb{});
    if (packRgb(got[i]) != want)
      return ::testing::AssertionFailure()
             << "point " << i << " (" << points[i].transpose() << "): colour OctoMap "
             << payloadText(Payload::kColor, want) << ", octovk "
             << payloadText(Payload::kColor, packRgb(got[i]));
  }
  return ::testing::AssertionSuccess();
}

// A wall two cells thick (x cells 16 and 17 from the origin's cell, one octant deep) over y and z
// cells [y0, y1) x [-8, 8), four points per cell and layer: once clamped, its octants prune.
std::vector<Eigen::Vector3f> thickWall(float res, int y0, int y1) {
  std::vector<Eigen::Vector3f> pts;
  for (int layer = 16; layer <= 17; ++layer)
    for (int y = 2 * y0; y < 2 * y1; ++y)
      for (int z = -16; z < 16; ++z)
        pts.emplace_back((static_cast<float>(layer) + 0.25f) * res,
                         (static_cast<float>(y) * 0.5f + 0.2f) * res,
                         (static_cast<float>(z) * 0.5f + 0.3f) * res);
  return pts;
}

std::size_t prunedOccupiedLeaves(const octomap::ColorOcTree& tree) {
  std::size_t n = 0;
  for (auto it = tree.begin_leafs(), end = tree.end_leafs(); it != end; ++it)
    n += it.getDepth() < 16 && tree.isNodeOccupied(*it);
  return n;
}

// ---- ColorMap: scans that prune, expand, fold several points per cell ---------------------------

struct ColorCase {
  double resolution;
  bool discretize;
  ColorFold fold;
};

void PrintTo(const ColorCase& c, std::ostream* os) {
  *os << "resolution " << c.resolution << ", discretize " << c.discretize << ", "
      << (c.fold == ColorFold::kAverage ? "average" : "integrate");
}

std::string colorCaseName(const ::testing::TestParamInfo<ColorCase>& info) {
  const ColorCase& c = info.param;
  return "res" + std::to_string(std::lround(c.resolution * 1000)) + "mm" +
         (c.discretize ? "_discretize" : "") +
         (c.fold == ColorFold::kAverage ? "_average" : "_integrate");
}

class ColorScans : public ::testing::TestWithParam<ColorCase> {};

// Repeated wall scans clamp the wall, whose octants prune with the children's averaged colours;
// a crossing scan from behind expands them (children copy the colour); a scan whose max range
// stops short of the wall still folds its colours into the wall's nodes.
TEST_P(ColorScans, WallPrunesExpandsAndFoldsEqualColorOcTree) {
  OCTOVK_REQUIRE_CONTEXT(ctx);
  const ColorCase c = GetParam();
  const MapParams params = withResolution(c.resolution);
  ColorMap map(ctx, params);
  auto oracle = makeColorOracle(params);
  const float res = static_cast<float>(c.resolution);
  const Eigen::Vector3f origin(0.5f * res, 0.5f * res, 0.5f * res);
  const auto wall = thickWall(res, -8, 8);
  std::size_t scan = 0;
  for (int rep = 0; rep < 6; ++rep, ++scan)
    ASSERT_TRUE(insertColorBoth(map, *oracle, wall, origin, colorsOf(scan, wall.size()), -1.0,
                                c.discretize, c.fold))
        << "wall scan " << rep;
  EXPECT_GT(prunedOccupiedLeaves(*oracle), 10u) << "the clamped wall should have pruned";
  EXPECT_TRUE(sameColors(map, *oracle, wall));

  // From behind the wall towards points in front of it: the rays cross the pruned wall.
  const Eigen::Vector3f behind(30.5f * res, 2.5f * res, 1.5f * res);
  std::vector<Eigen::Vector3f> cross;
  for (int i = 0; i < 60; ++i) {
    const float t = static_cast<float>(i) / 60.0f;
    cross.emplace_back((6.0f + 4.0f * t) * res, (-6.0f + 12.0f * t) * res,
                       (5.0f - 10.0f * t) * res);
  }
  for (int rep = 0; rep < 2; ++rep, ++scan)
    ASSERT_TRUE(insertColorBoth(map, *oracle, cross, behind, colorsOf(scan, cross.size()), -1.0,
                                c.discretize, c.fold))
        << "crossing scan " << rep;

  // A max range short of the wall: no occupied update, but the points' colours still go to the
  // nodes search() finds (the wall's, existing from before).
  const double short_range = 10.0 * c.resolution;
  std::size_t beyond_found = 0;
  for (const auto& p : wall)
    beyond_found += (p - origin).norm() > short_range && oracle->search(toPoint(p)) != nullptr;
  EXPECT_GT(beyond_found, wall.size() / 2);
  ASSERT_TRUE(insertColorBoth(map, *oracle, wall, origin, colorsOf(scan++, wall.size()),
                              short_range, c.discretize, c.fold));

  // The wall again: expanded nodes clamp and prune again.
  for (int rep = 0; rep < 3; ++rep, ++scan)
    ASSERT_TRUE(insertColorBoth(map, *oracle, wall, origin, colorsOf(scan, wall.size()), -1.0,
                                c.discretize, c.fold))
        << "wall again, scan " << rep;
  EXPECT_TRUE(sameColors(map, *oracle, wall));
  EXPECT_TRUE(sameColors(map, *oracle, cross));
}

INSTANTIATE_TEST_SUITE_P(Cases, ColorScans,
                         ::testing::Values(ColorCase{0.1, false, ColorFold::kAverage},
                                           ColorCase{0.05, true, ColorFold::kAverage},
                                           ColorCase{0.2, false, ColorFold::kAverage},
                                           ColorCase{0.1, false, ColorFold::kIntegrate},
                                           ColorCase{0.05, true, ColorFold::kIntegrate}),
                         colorCaseName);

// ---- integrateNodeColor's weight: octomap::probability on the device ----------------------------

// Every float from `lo` to `hi` whose ordinal is a multiple of `stride` away from lo's.
void addFloats(std::vector<float>& out, float lo, float hi, std::int64_t stride) {
  for (std::int64_t o = ordinalOf(lo), end = ordinalOf(hi); o <= end; o += stride)
    out.push_back(floatOfOrdinal(o));
}

// The log-odds a leaf reaches from 0 by OctoMap's updates (+ hit or + miss in float, clamped:
// OccupancyOcTreeBase::updateNodeLogOdds) in at most `updates` of them.
std::vector<float> reachableLogOdds(const octomap::ColorOcTree& tree, int updates) {
  std::set<float> seen{0.0f};
  std::vector<float> frontier{0.0f};
  for (int step = 0; step < updates && !frontier.empty(); ++step) {
    std::vector<float> next;
    for (float v : frontier)
      for (float update : {tree.getProbHitLog(), tree.getProbMissLog()}) {
        const float w =
            std::clamp(v + update, tree.getClampingThresMinLog(), tree.getClampingThresMaxLog());
        if (seen.insert(w).second) next.push_back(w);
      }
    frontier = std::move(next);
  }
  return {seen.begin(), seen.end()};
}

// occupancyProbability (shaders/probability.glsl: exp built from the probed double arithmetic,
// correctly rounded) against the host, bit for bit: a stride through every float of the default
// clamping range, the log-odds that 200 updates reach under the default and a 0.999 clamping,
// strides through [-40, 40] and all floats, and the edges (exp's overflow and underflow,
// subnormals, zeros, infinities).
// - against 1 - 1 / (1 + exp(l)) with exp correctly rounded (libquadmath's expq rounded to
//   double): no difference at all;
// - against OctoMap's getOccupancy() (glibc's exp, about 0.51 ULP): a difference only where glibc's
//   exp is not correctly rounded (4 in 100,000 of these log-odds), and none of those here changes
//   the colour integrateNodeColor gives for any pair of channel values (old, new). Over the whole
//   clamping range 21 log-odds do, for old = new = 100 or 200 (docs/benchmarks.md).
// The exhaustive run over the clamping range is bench/probability_exhaustive.cpp
// (docs/benchmarks.md).
TEST(ColorFolds, DeviceOccupancyEqualsOctoMapsGetOccupancy) {
  OCTOVK_REQUIRE_CONTEXT(ctx);
  const MapParams params = withResolution(0.1);
  auto tree = makeColorOracle(params);
  std::vector<float> values;
  addFloats(values, tree->getClampingThresMinLog(), tree->getClampingThresMaxLog(), 1789);
  addFloats(values, -40.0f, 40.0f, 20011);
  addFloats(values, std::numeric_limits<float>::lowest(), std::numeric_limits<float>::max(),
            100003);
  for (float v : reachableLogOdds(*tree, 200)) values.push_back(v);
  tree->setClampingThresMax(0.999);
  for (float v : reachableLogOdds(*tree, 120)) values.push_back(v);
  const float inf = std::numeric_limits<float>::infinity();
  for (float v : {0.0f,
                  std::numeric_limits<float>::denorm_min(),
                  std::numeric_limits<float>::min(),
                  1e-30f,
                  1e-8f,
                  0.5f,
                  1.0f,
                  4.59511985f,
                  20.0f,
                  36.0f,
                  37.0f,
                  38.0f,
                  100.0f,
                  700.0f,
                  708.39f,
                  709.0f,
                  709.78f,
                  709.79f,
                  710.0f,
                  744.0f,
                  745.0f,
                  745.13f,
                  745.14f,
                  746.0f,
                  1e10f,
                  std::numeric_limits<float>::max(),
                  inf}) {
    values.push_back(v);
    values.push_back(-v);
  }
  const auto start = std::chrono::steady_clock::now();
  const std::vector<double> got = deviceOccupancies(ContextAccess::device(ctx), values);
  const double seconds =
      std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  ASSERT_EQ(got.size(), values.size());
  auto bits = [](double d) { return std::bit_cast<std::uint64_t>(d); };
  std::size_t wrong = 0, glibc_differs = 0, colour_pairs_differ = 0;
  octomap::ColorOcTreeNode node;
  for (std::size_t i = 0; i < values.size(); ++i) {
    const double x = static_cast<double>(values[i]);
    const double exact_exp = static_cast<double>(expq(static_cast<__float128>(x)));
    const double want = 1. - (1. / (1. + exact_exp));
    node.setLogOdds(values[i]);
    const double octomap_p = node.getOccupancy();
    char text[200];
    if (bits(want) != bits(got[i])) {
      if (++wrong <= 10) {
        std::snprintf(text, sizeof text, "log-odds %a (%.9g): correctly rounded p %a, device %a", x,
                      x, want, got[i]);
        ADD_FAILURE() << text;
      }
      continue;
    }
    if (bits(octomap_p) == bits(got[i])) continue;
    ++glibc_differs;
    if (bits(std::exp(x)) == bits(exact_exp)) {
      std::snprintf(text, sizeof text,
                    "log-odds %a: OctoMap's p %a differs from the device's %a though glibc's exp "
                    "is correctly rounded there",
                    x, octomap_p, got[i]);
      ADD_FAILURE() << text;
    }
    for (int old = 0; old < 256; ++old)
      for (int c = 0; c < 256; ++c)
        colour_pairs_differ +=
            integratedChannel(old, c, octomap_p) != integratedChannel(old, c, got[i]);
  }
  EXPECT_EQ(wrong, 0u) << "of " << values.size() << " log-odds";
  EXPECT_EQ(colour_pairs_differ, 0u);
  EXPECT_LT(glibc_differs, values.size() / 10000);
  std::printf(
      "%zu log-odds (device %.2f s): OctoMap's p differs by glibc's exp's rounding at %zu; "
      "colours differing for any (old, new): %zu\n",
      values.size(), seconds, glibc_differs, colour_pairs_differ);
}

// A clamping_max above 0.99: once a node's occupancy passes 0.99, integrateNodeColor's weight of
// the new colour (0.99 - p) is negative, and a dark colour folded with a bright one gives a
// negative double, which OctoMap's conversion to uint8_t wraps (-1.3 -> -1 -> 255 on x86-64).
// Wall scans that clamp and prune at 0.999, dark and bright colours by turns.
TEST(ColorFolds, IntegrateAboveOccupancy099WrapsLikeOctoMap) {
  OCTOVK_REQUIRE_CONTEXT(ctx);
  MapParams params = withResolution(0.1);
  params.clamping_max = 0.999;
  ColorMap map(ctx, params);
  auto oracle = makeColorOracle(params);
  const float res = static_cast<float>(params.resolution);
  const Eigen::Vector3f origin(0.5f * res, 0.5f * res, 0.5f * res);
  const auto wall = thickWall(res, -4, 4);
  std::size_t negative = 0;
  for (std::size_t scan = 0; scan < 14; ++scan) {
    std::vector<Rgb> colors = colorsOf(scan, wall.size());
    for (std::size_t i = 0; i < colors.size(); ++i) {
      const auto k = static_cast<std::uint8_t>((i + scan) % 7);
      if (scan % 2 == 0)
        colors[i] = Rgb{k, static_cast<std::uint8_t>(2 * k), 0};
      else if (i % 3 != 0)
        colors[i] = Rgb{250, static_cast<std::uint8_t>(200 + k), 30};
    }
    ASSERT_TRUE(insertColorBoth(map, *oracle, wall, origin, colors, -1.0, false,
                                ColorFold::kIntegrate, &negative))
        << "scan " << scan;
  }
  EXPECT_GT(negative, 100u) << "the negative path was not taken";
  EXPECT_GT(prunedOccupiedLeaves(*oracle), 0u);
  EXPECT_TRUE(sameColors(map, *oracle, wall));
  // The .ot written equals OctoMap's bytes.
  std::stringstream want;
  oracle->write(want);
  const std::string path = tmpPath("payload_oracle_wrap." + std::to_string(::getpid()) + ".ot");
  writeMapFile(map, path);
  EXPECT_EQ(want.str(), fileBytes(path));
  std::remove(path.c_str());
}

// Random scans with repeated origins, every fifth point given twice more (several points in one
// cell of one scan), max range and discretize by turns.
TEST_P(ColorScans, RandomScansEqualColorOcTree) {
  OCTOVK_REQUIRE_CONTEXT(ctx);
  const ColorCase c = GetParam();
  const MapParams params = withResolution(c.resolution);
  ColorMap map(ctx, params);
  auto oracle = makeColorOracle(params);
  std::mt19937 rng(static_cast<unsigned>(c.resolution * 1000) + c.discretize);
  const float radius = static_cast<float>(c.resolution * 30);
  for (std::size_t scan = 0; scan < 6; ++scan) {
    const auto k = static_cast<double>(scan);
    const Eigen::Vector3f origin(static_cast<float>(c.resolution * std::fmod(k, 2.0)),
                                 static_cast<float>(-c.resolution * 0.5 * std::fmod(k, 3.0)), 0.0f);
    std::vector<Eigen::Vector3f> pts;
    for (const auto& p : randomScan(rng, origin, 300, radius)) {
      pts.push_back(p);
      if (pts.size() % 5 == 0) {
        pts.push_back(p);
        pts.push_back(p + Eigen::Vector3f::Constant(0.01f * radius / 30.0f));
      }
    }
    const double max_range = scan % 3 == 1 ? 0.6 * radius : -1.0;
    const bool discretize = c.discretize != (scan % 2 == 1);
    ASSERT_TRUE(insertColorBoth(map, *oracle, pts, origin, colorsOf(scan, pts.size()), max_range,
                                discretize, c.fold))
        << "scan " << scan;
  }
  EXPECT_GT(oracle->size(), 500u);
}

// Another way in for the colours: the sensor-frame cloud (points moved by the pose on the
// device) and a depth image (a colour per pixel, row by row; pixels without depth skip theirs).
// OctoMap's insertPointCloud(scan, sensor_origin, frame_origin), then the colours of the points
// it moved, in order.
::testing::AssertionResult colorOracleInSensorFrame(octomap::ColorOcTree& oracle,
                                                    const std::vector<Eigen::Vector3f>& points,
                                                    const Eigen::Vector3f& origin, const Pose& pose,
                                                    const std::vector<Rgb>& colors) {
  if (points.size() != colors.size())
    return ::testing::AssertionFailure()
           << points.size() << " points, " << colors.size() << " colours";
  const octomath::Pose6D frame = toPose6D(pose);
  oracle.insertPointCloud(toPointcloud(points), toPoint(origin), frame);
  octomap::Pointcloud world = toPointcloud(points);
  world.transform(frame);
  for (std::size_t i = 0; i < world.size(); ++i)
    oracle.averageNodeColor(world[i].x(), world[i].y(), world[i].z(), colors[i].r, colors[i].g,
                            colors[i].b);
  oracle.updateInnerOccupancy();
  return ::testing::AssertionSuccess();
}

TEST(ColorInputs, SensorFrameCloudAndDepthImageEqualColorOcTree) {
  OCTOVK_REQUIRE_CONTEXT(ctx);
  const MapParams params = withResolution(0.05);
  ColorMap map(ctx, params);
  auto oracle = makeColorOracle(params);
  std::mt19937 rng(31);
  Pose pose;
  pose.translation = Eigen::Vector3f(0.3f, -0.2f, 0.15f);
  pose.rotation =
      Eigen::Quaternionf(Eigen::AngleAxisf(0.7f, Eigen::Vector3f(0.2f, 0.3f, 1.0f).normalized()));
  for (std::size_t scan = 0; scan < 2; ++scan) {
    const Eigen::Vector3f origin(0.02f, 0.0f, 0.01f);
    const auto pts = randomScan(rng, origin, 600, 1.2f);
    const auto colors = colorsOf(40 + scan, pts.size());
    ASSERT_TRUE(colorOracleInSensorFrame(*oracle, pts, origin, pose, colors));
    const ScanStats s = map.insertPointCloud(pts, origin, pose, {.colors = colors});
    EXPECT_EQ(s.nodes, oracle->size());
    ASSERT_TRUE(samePayloadTree(*oracle, map.download(), Payload::kColor)) << "cloud " << scan;
  }
  // A 40 x 30 image of a slanted plane 1-2 m away, some pixels without depth.
  DepthImage cam;
  cam.width = 40;
  cam.height = 30;
  cam.fx = cam.fy = 30.0f;
  cam.cx = 19.5f;
  cam.cy = 14.5f;
  cam.encoding = DepthImage::Encoding::kFloat32;
  cam.depth_scale = 1.0f;
  std::vector<float> depth(std::size_t{cam.width} * cam.height);
  for (std::size_t i = 0; i < depth.size(); ++i)
    depth[i] = 1.0f + 0.02f * static_cast<float>(i % cam.width) +
               0.01f * static_cast<float>(i / cam.width);
  depth[3] = 0.0f;
  depth[77] = std::numeric_limits<float>::quiet_NaN();
  depth[500] = 0.0f;
  cam.depths = std::span<const float>(depth);
  const auto pixel_colors = colorsOf(50, depth.size());
  std::vector<Rgb> point_colors;
  for (std::size_t i = 0; i < depth.size(); ++i)
    if (std::isnormal(depth[i])) point_colors.push_back(pixel_colors[i]);
  const auto points = unprojectDepthImage(cam);
  ASSERT_EQ(points.size(), depth.size() - 3);
  const Eigen::Vector3f origin_camera(0.01f, 0.0f, 0.0f);
  for (int view = 0; view < 2; ++view) {
    ASSERT_TRUE(colorOracleInSensorFrame(*oracle, points, origin_camera, pose, point_colors));
    (void)map.insertDepthImage(cam, pose, {.colors = pixel_colors}, origin_camera);
    ASSERT_TRUE(samePayloadTree(*oracle, map.download(), Payload::kColor)) << "image " << view;
  }
  // Submitted (the pixels and colours staged, copied before the call returns).
  std::vector<Rgb> staged = pixel_colors;
  ASSERT_TRUE(colorOracleInSensorFrame(*oracle, points, origin_camera, pose, point_colors));
  (void)map.submitDepthImage(cam, pose, {.colors = staged}, origin_camera);
  std::fill(staged.begin(), staged.end(), Rgb{9, 9, 9});
  map.flush();
  EXPECT_TRUE(samePayloadTree(*oracle, map.download(), Payload::kColor)) << "submitted image";
}

// Scans submitted back to back (the colour and stamp staged per frame, refused scans run again
// as the pool grows): the same map as the blocking scans, colours and stamps included. The
// colour vectors are overwritten after each submit (they are copied).
TEST(PayloadStreaming, SubmittedScansEqualOctoMap) {
  OCTOVK_REQUIRE_CONTEXT(ctx);
  const MapParams params = withResolution(0.05);
  ColorMap cmap(ctx, params);
  auto coracle = makeColorOracle(params);
  StampedMap smap(ctx, params);
  StampedOracle soracle(params);
  std::mt19937 rng(33);
  std::vector<Rgb> colors;
  for (std::uint32_t scan = 0; scan < 6; ++scan) {
    const Eigen::Vector3f origin(0.05f * static_cast<float>(scan % 2), 0.0f, 0.0f);
    const auto pts = randomScan(rng, origin, 1500, 1.0f + 0.4f * static_cast<float>(scan));
    colors = colorsOf(60 + scan, pts.size());
    coracle->insertPointCloud(toPointcloud(pts), toPoint(origin));
    for (std::size_t i = 0; i < pts.size(); ++i)
      coracle->averageNodeColor(pts[i].x(), pts[i].y(), pts[i].z(), colors[i].r, colors[i].g,
                                colors[i].b);
    soracle.setScanTime(3000 + scan);
    soracle.insertPointCloud(toPointcloud(pts), toPoint(origin));
    (void)cmap.submitPointCloud(pts, origin, {.colors = colors});
    (void)smap.submitPointCloud(pts, origin, {.stamp = 3000 + scan});
    std::fill(colors.begin(), colors.end(), Rgb{1, 2, 3});
  }
  cmap.flush();
  smap.flush();
  std::size_t reruns = 0;
  for (OccupancyMap* m : {static_cast<OccupancyMap*>(&cmap), static_cast<OccupancyMap*>(&smap)})
    for (const ScanStats& st : m->takeScanStats()) reruns += st.cell_set_attempts > 1;
  EXPECT_GT(reruns, 0u) << "some submitted scans should have been refused and run again";
  coracle->updateInnerOccupancy();
  EXPECT_TRUE(samePayloadTree(*coracle, cmap.download(), Payload::kColor));
  EXPECT_TRUE(samePayloadTree(soracle, smap.download(), Payload::kStamp));
}

// Under a memory cap that the scans' cell sets do not fit, colour and stamp scans are applied in
// groups of tiles: the colours are folded once every part is in (after the whole scan's pruning,
// as ColorOcTree does), every part stamps its nodes with the scan's stamp; blocking and submitted,
// equal to OctoMap.
TEST(PayloadStreaming, ScansInGroupsOfTilesEqualOctoMap) {
  OCTOVK_REQUIRE_CONTEXT(ctx);
  MapParams params = withResolution(0.05);
  struct Scan {
    std::vector<Eigen::Vector3f> points;
    Eigen::Vector3f origin;
    std::vector<Rgb> colors;
  };
  std::vector<Scan> scans;
  std::mt19937 rng(35);
  for (std::uint32_t scan = 0; scan < 4; ++scan) {
    const Eigen::Vector3f origin(0.03f * static_cast<float>(scan), 0.01f, 0.0f);
    // Many points to a node near the sensor (their colours' order counts) and long rays.
    auto pts = randomScan(rng, origin, 600, 0.6f);
    const auto far = sphere(20.0f + static_cast<float>(scan), 48, origin);
    pts.insert(pts.end(), far.begin(), far.end());
    scans.push_back({pts, origin, colorsOf(91 + scan, pts.size())});
  }
  // The pool as uncapped (the map fits), and a 16th of the rest (the scans' sets do not).
  std::size_t pool = 0, total = 0;
  {
    ColorMap probe(ctx, params);
    for (const Scan& s : scans) {
      probe.insertPointCloud(s.points, s.origin, s.colors);
      pool = std::max(pool, probe.poolBytes());
      total = std::max(total, probe.deviceBytes());
    }
  }
  params.max_device_bytes = pool + (total - pool) / 16;
  ColorMap cmap(ctx, params);
  auto coracle = makeColorOracle(params);
  StampedMap smap(ctx, params);
  StampedOracle soracle(params);
  std::size_t in_parts = 0;
  for (std::uint32_t scan = 0; scan < scans.size(); ++scan) {
    const Scan& s = scans[scan];
    coracle->insertPointCloud(toPointcloud(s.points), toPoint(s.origin));
    for (std::size_t i = 0; i < s.points.size(); ++i)
      coracle->averageNodeColor(s.points[i].x(), s.points[i].y(), s.points[i].z(), s.colors[i].r,
                                s.colors[i].g, s.colors[i].b);
    soracle.setScanTime(5000 + scan);
    soracle.insertPointCloud(toPointcloud(s.points), toPoint(s.origin));
    if (scan < 2) {
      in_parts += cmap.insertPointCloud(s.points, s.origin, s.colors).tile_groups > 1;
      in_parts += smap.insertPointCloud(s.points, s.origin, 5000 + scan).tile_groups > 1;
    } else {
      (void)cmap.submitPointCloud(s.points, s.origin, {.colors = s.colors});
      (void)smap.submitPointCloud(s.points, s.origin, {.stamp = 5000 + scan});
    }
  }
  cmap.flush();
  smap.flush();
  for (OccupancyMap* m : {static_cast<OccupancyMap*>(&cmap), static_cast<OccupancyMap*>(&smap)})
    for (const ScanStats& st : m->takeScanStats()) in_parts += st.tile_groups > 1;
  EXPECT_EQ(in_parts, 8u) << "every scan should have been applied in groups of tiles";
  EXPECT_LE(cmap.deviceBytes(), params.max_device_bytes);
  EXPECT_LE(smap.deviceBytes(), params.max_device_bytes);
  coracle->updateInnerOccupancy();
  EXPECT_TRUE(samePayloadTree(*coracle, cmap.download(), Payload::kColor));
  EXPECT_TRUE(samePayloadTree(soracle, smap.download(), Payload::kStamp));
}

// Colour and stamped maps that outgrow the cap with a spill: the spilled tiles keep their colours
// and stamps, the places revisited load them back (submitted back to back), and the maps equal
// ColorOcTree's and OcTreeStamped's node for node, payloads included.
TEST(PayloadStreaming, MapsOverCapSpillTilesAndEqualOctoMap) {
  OCTOVK_REQUIRE_CONTEXT(ctx);
  MapParams params = withResolution(0.1);
  const auto at = [](int k) { return Eigen::Vector3f(20.0f * static_cast<float>(k), 0, 0); };
  std::size_t after_first = 0, pool_after_first = 0;
  {
    ColorMap probe(ctx, params);
    const auto pts = sphere(0.6f, 200, at(0));
    probe.insertPointCloud(pts, at(0), colorsOf(3, pts.size()));
    after_first = probe.deviceBytes();
    pool_after_first = probe.poolBytes();
  }
  params.max_device_bytes = after_first + pool_after_first / 8;
  ColorMap cmap(ctx, params);
  StampedMap smap(ctx, params);
  cmap.spillTilesTo(makeHostTileSpill());
  smap.spillTilesTo(makeHostTileSpill());
  auto coracle = makeColorOracle(params);
  StampedOracle soracle(params);
  std::vector<int> places;
  for (int k = 0; k < 10; ++k) places.push_back(k);
  for (int k = 8; k >= 0; k -= 2) places.push_back(k);
  std::size_t most_spilled = 0;
  for (std::size_t i = 0; i < places.size(); ++i) {
    const Eigen::Vector3f o = at(places[i]);
    const auto pts = sphere(i < 10 ? 0.6f : 0.8f, 200, o);
    const auto colors = colorsOf(40 + static_cast<std::uint32_t>(i), pts.size());
    const auto stamp = static_cast<std::uint32_t>(7000 + i);
    coracle->insertPointCloud(toPointcloud(pts), toPoint(o));
    for (std::size_t j = 0; j < pts.size(); ++j)
      coracle->averageNodeColor(pts[j].x(), pts[j].y(), pts[j].z(), colors[j].r, colors[j].g,
                                colors[j].b);
    soracle.setScanTime(stamp);
    soracle.insertPointCloud(toPointcloud(pts), toPoint(o));
    if (i < 10) {
      cmap.insertPointCloud(pts, o, colors);
      smap.insertPointCloud(pts, o, stamp);
    } else {
      (void)cmap.submitPointCloud(pts, o, {.colors = colors});
      (void)smap.submitPointCloud(pts, o, {.stamp = stamp});
    }
    most_spilled = std::max({most_spilled, cmap.spilledTiles(), smap.spilledTiles()});
  }
  cmap.flush();
  smap.flush();
  EXPECT_GT(most_spilled, 0u) << "the maps never outgrew the cap";
  EXPECT_GT(cmap.spilledTiles(), 0u);
  EXPECT_GT(smap.spilledTiles(), 0u);
  EXPECT_LE(cmap.deviceBytes(), params.max_device_bytes);
  EXPECT_LE(smap.deviceBytes(), params.max_device_bytes);
  coracle->updateInnerOccupancy();
  EXPECT_TRUE(samePayloadTree(*coracle, cmap.download(), Payload::kColor));
  EXPECT_TRUE(samePayloadTree(soracle, smap.download(), Payload::kStamp));
}

// Many points in few nodes, in shuffled order (the integer mean depends on the order), some
// white; then a scan with no colours whose pruning still averages the children's colours.
TEST(ColorInputs, ManyPointsPerNodeAndScansWithoutColours) {
  OCTOVK_REQUIRE_CONTEXT(ctx);
  const MapParams params = withResolution(0.1);
  ColorMap map(ctx, params);
  auto oracle = makeColorOracle(params);
  std::mt19937 rng(35);
  std::uniform_real_distribution<float> u(0.0f, 1.0f);
  std::vector<Eigen::Vector3f> pts;
  for (int i = 0; i < 12000; ++i)  // 4 x 4 x 2 cells of a 2-cell-thick wall
    pts.emplace_back(1.6f + 0.2f * u(rng), 0.4f * u(rng), 0.4f * u(rng));
  const Eigen::Vector3f origin(0.05f, 0.05f, 0.05f);
  for (std::size_t scan = 0; scan < 3; ++scan) {
    std::shuffle(pts.begin(), pts.end(), rng);
    ASSERT_TRUE(insertColorBoth(map, *oracle, pts, origin, colorsOf(70 + scan, pts.size()), -1.0,
                                scan == 1))
        << "scan " << scan;
  }
  // Without colours: the occupancy only, and the pruning of the now clamped wall averages the
  // children's colours (ColorOcTree::pruneNode).
  for (int rep = 0; rep < 3; ++rep) {
    oracle->insertPointCloud(toPointcloud(pts), toPoint(origin));
    oracle->updateInnerOccupancy();
    (void)map.insertPointCloud(pts, origin);
    ASSERT_TRUE(samePayloadTree(*oracle, map.download(), Payload::kColor)) << "no colours " << rep;
  }
  EXPECT_GT(prunedOccupiedLeaves(*oracle), 0u);
  EXPECT_TRUE(sameColors(map, *oracle, pts));
}

// Calls that throw leave a payload map as it was: colours of the wrong count, colours for a
// stamped map, a scan beyond max_nodes (its colours not folded either).
TEST(ColorInputs, RefusedScansLeaveColoursAndStampsAsTheyWere) {
  OCTOVK_REQUIRE_CONTEXT(ctx);
  MapParams params = withResolution(0.1);
  params.max_nodes = 20000;
  ColorMap map(ctx, params);
  auto oracle = makeColorOracle(params);
  const Eigen::Vector3f origin = Eigen::Vector3f::Zero();
  const auto small = sphere(0.5f, 300, origin);
  ASSERT_TRUE(
      insertColorBoth(map, *oracle, small, origin, colorsOf(80, small.size()), -1.0, false));
  auto expectRefused = [&](const char* what, auto&& call, ErrorCode code) {
    try {
      call();
      ADD_FAILURE() << what << " did not throw";
    } catch (const Error& e) {
      EXPECT_EQ(e.code(), code) << what << ": " << e.what();
    }
    EXPECT_TRUE(samePayloadTree(*oracle, map.download(), Payload::kColor)) << what;
  };
  expectRefused(
      "one colour too few",
      [&] {
        const auto colors = colorsOf(81, small.size() - 1);
        map.insertPointCloud(small, origin, colors);
      },
      ErrorCode::kInvalidArgument);
  const auto big = sphere(4.0f, 4000, origin);
  expectRefused(
      "a scan beyond max_nodes",
      [&] {
        const auto colors = colorsOf(82, big.size());
        map.insertPointCloud(big, origin, colors);
      },
      ErrorCode::kOutOfDeviceMemory);
  // The map still folds colours afterwards.
  ASSERT_TRUE(
      insertColorBoth(map, *oracle, small, origin, colorsOf(83, small.size()), -1.0, false));
  // A stamped scan beyond max_nodes leaves the stamps as they were.
  StampedMap limited(ctx, params);
  StampedOracle soracle(params);
  ASSERT_TRUE(insertStampedBoth(limited, soracle, small, origin, 10));
  try {
    limited.insertPointCloud(big, origin, 11u);
    ADD_FAILURE() << "a stamped scan beyond max_nodes did not throw";
  } catch (const Error& e) {
    EXPECT_EQ(e.code(), ErrorCode::kOutOfDeviceMemory) << e.what();
  }
  EXPECT_TRUE(samePayloadTree(soracle, limited.download(), Payload::kStamp));
  ASSERT_TRUE(insertStampedBoth(limited, soracle, small, origin, 12));
  StampedMap stamped(ctx, withResolution(0.1));
  const auto colors = colorsOf(84, small.size());
  try {
    stamped.insertPointCloud(small, origin, {.colors = colors});
    ADD_FAILURE() << "colours accepted by a stamped map";
  } catch (const Error& e) {
    EXPECT_EQ(e.code(), ErrorCode::kInvalidArgument) << e.what();
  }
  EXPECT_FALSE(stamped.download().root_exists);
}

// End points exactly on cell borders (k * resolution, signed zeros) and at cell centres, from
// origins on borders and centres: the fold's key of each point is OctoMap's coordToKeyChecked.
TEST(ColorInputs, PointsOnCellBordersFoldIntoOctoMapsCells) {
  OCTOVK_REQUIRE_CONTEXT(ctx);
  for (const double resolution : {0.1, 0.02}) {
    SCOPED_TRACE("resolution " + std::to_string(resolution));
    const MapParams params = withResolution(resolution);
    ColorMap map(ctx, params);
    auto oracle = makeColorOracle(params);
    const auto r = static_cast<float>(resolution);
    std::vector<Eigen::Vector3f> pts = {{0.0f, -0.0f, 0.0f}, {-0.0f, -0.0f, -0.0f}};
    for (int k = -6; k <= 6; ++k) {
      const auto fk = static_cast<float>(k);
      pts.emplace_back(fk * r, 0.0f, -fk * r);
      pts.emplace_back(fk * r, fk * r, fk * r);
      pts.emplace_back((fk + 0.5f) * r, -0.0f, (fk - 0.5f) * r);
      pts.emplace_back(static_cast<float>(k * resolution), 3.0f * r,
                       static_cast<float>(-k * resolution));
    }
    std::size_t scan = 0;
    for (const Eigen::Vector3f& origin :
         {Eigen::Vector3f(0.0f, 0.0f, 0.0f), Eigen::Vector3f(0.5f * r, 0.5f * r, 0.5f * r),
          Eigen::Vector3f(-7.0f * r, 7.0f * r, r)})
      for (const bool discretize : {false, true})
        ASSERT_TRUE(insertColorBoth(map, *oracle, pts, origin, colorsOf(90 + scan++, pts.size()),
                                    -1.0, discretize))
            << "origin " << origin.transpose() << (discretize ? ", discretize" : "");
    EXPECT_TRUE(sameColors(map, *oracle, pts));
  }
}

// A plain map, a colour map and a stamped map on one Context, scans interleaved: each equals its
// own OctoMap tree (no pipeline or buffer state of one payload leaks into another map's scans).
TEST(PayloadFeatures, PlainColourAndStampedMapsInterleaved) {
  OCTOVK_REQUIRE_CONTEXT(ctx);
  const MapParams params = withResolution(0.05);
  OccupancyMap plain(ctx, params);
  octomap::OcTree plain_oracle = makeOracle(params);
  ColorMap cmap(ctx, params);
  auto coracle = makeColorOracle(params);
  StampedMap smap(ctx, params);
  StampedOracle soracle(params);
  std::mt19937 rng(37);
  for (std::uint32_t scan = 0; scan < 3; ++scan) {
    const Eigen::Vector3f origin(0.05f * static_cast<float>(scan), 0.0f, 0.0f);
    const auto pts = randomScan(rng, origin, 700, 1.5f);
    ASSERT_TRUE(
        insertColorBoth(cmap, *coracle, pts, origin, colorsOf(95 + scan, pts.size()), -1.0, false));
    ASSERT_TRUE(insertBoth(plain, plain_oracle, pts, origin, -1.0, false));
    ASSERT_TRUE(insertStampedBoth(smap, soracle, pts, origin, 4000 + scan));
  }
  EXPECT_TRUE(samePayloadTree(*coracle, cmap.download(), Payload::kColor));
  const HostTree p = plain.download();
  EXPECT_EQ(p.payload, Payload::kNone);
  for (const auto& n : p.nodes) {
    if (n.payload != 0u) {
      ADD_FAILURE() << "a plain map's node carries payload " << n.payload;
      break;
    }
  }
}

// ---- StampedMap
// ----------------------------------------------------------------------------------

// Two halves of a thick wall clamped at different times: the octants that straddle the halves
// are equal in log-odds but not in stamp, so OcTreeStamped keeps them (a plain OcTree prunes
// them); degradeOutdated mid-run degrades one half; later scans early-abort on clamped leaves,
// which keep their stamps; a query time before the stamps wraps (unsigned) and degrades all.
TEST(StampedScans, StampsPreventPruningDegradeAndEarlyAbortEqualOcTreeStamped) {
  OCTOVK_REQUIRE_CONTEXT(ctx);
  for (const double resolution : {0.1, 0.05}) {
    SCOPED_TRACE("resolution " + std::to_string(resolution));
    const MapParams params = withResolution(resolution);
    StampedMap map(ctx, params);
    StampedOracle oracle(params);
    octomap::OcTree plain = makeOracle(params);
    const float res = static_cast<float>(resolution);
    const Eigen::Vector3f origin(0.5f * res, 0.5f * res, 0.5f * res);
    // y cells [-4, 1) and [1, 4): the octant of y cells 0 and 1 straddles the halves.
    const auto half_a = thickWall(res, -4, 1);
    const auto half_b = thickWall(res, 1, 4);
    std::uint32_t t = 100;
    for (const auto* half : {&half_a, &half_b})
      for (int rep = 0; rep < 5; ++rep) {
        ++t;
        ASSERT_TRUE(insertStampedBoth(map, oracle, *half, origin, t)) << "stamp " << t;
        plain.insertPointCloud(toPointcloud(*half), toPoint(origin));
      }
    EXPECT_GT(oracle.size(), plain.size()) << "the stamps should have kept octants from pruning";
    std::vector<Eigen::Vector3f> probes = half_a;
    probes.insert(probes.end(), half_b.begin(), half_b.end());
    probes.emplace_back(-40.0f * res, 0.0f, 0.0f);  // unknown
    EXPECT_TRUE(sameStamps(map, oracle, probes));
    EXPECT_EQ(map.lastUpdateTime(), t);

    // Half a (stamp 105) is older than 5 s at 112, half b (110) is not.
    oracle.degradeOutdated(112, 5);
    map.degradeOutdated(112, 5);
    ASSERT_TRUE(samePayloadTree(oracle, map.download(), Payload::kStamp)) << "after degrade";
    EXPECT_EQ(map.lastUpdateTime(), 112u);
    std::size_t degraded = 0;
    for (auto it = oracle.begin_leafs(), end = oracle.end_leafs(); it != end; ++it)
      degraded += oracle.isNodeOccupied(*it) && it->getLogOdds() < oracle.getClampingThresMaxLog();
    EXPECT_GT(degraded, 0u);

    // Half a again at 113 (back to clamped, new stamp); half b at 114 early-aborts: keeps 110.
    ASSERT_TRUE(insertStampedBoth(map, oracle, half_a, origin, 113));
    ASSERT_TRUE(insertStampedBoth(map, oracle, half_b, origin, 114, -1.0, true));
    EXPECT_TRUE(sameStamps(map, oracle, probes));
    const auto* kept = oracle.search(toPoint(half_b.front()));
    ASSERT_NE(kept, nullptr);
    EXPECT_EQ(kept->getTimestamp(), 110u);

    // A query time before every stamp: now - stamp wraps, so every occupied leaf degrades.
    oracle.degradeOutdated(50, 1000);
    map.degradeOutdated(50, 1000);
    ASSERT_TRUE(samePayloadTree(oracle, map.download(), Payload::kStamp))
        << "after wrapped degrade";
    ASSERT_TRUE(insertStampedBoth(map, oracle, half_b, origin, 115, 12.0 * resolution));
    EXPECT_TRUE(sameStamps(map, oracle, probes));
  }
}

// Random scans with increasing stamps, repeated origins, max range and discretize, and
// degradeOutdated every third scan.
TEST(StampedScans, RandomScansWithDegradeEqualOcTreeStamped) {
  OCTOVK_REQUIRE_CONTEXT(ctx);
  const MapParams params = withResolution(0.05);
  StampedMap map(ctx, params);
  StampedOracle oracle(params);
  std::mt19937 rng(29);
  const float radius = 1.5f;
  std::vector<Eigen::Vector3f> all;
  for (std::uint32_t scan = 0; scan < 9; ++scan) {
    const Eigen::Vector3f origin(0.05f * static_cast<float>(scan % 2), 0.0f,
                                 -0.025f * static_cast<float>(scan % 3));
    const auto pts = randomScan(rng, origin, 400, radius);
    all.insert(all.end(), pts.begin(), pts.begin() + 50);
    const std::uint32_t stamp = 1000 + 3 * scan;
    ASSERT_TRUE(insertStampedBoth(map, oracle, pts, origin, stamp,
                                  scan % 4 == 1 ? 0.7 * radius : -1.0, scan % 3 == 2))
        << "scan " << scan;
    if (scan % 3 == 2) {
      oracle.degradeOutdated(stamp + 1, 4);
      map.degradeOutdated(stamp + 1, 4);
      ASSERT_TRUE(samePayloadTree(oracle, map.download(), Payload::kStamp))
          << "degrade after scan " << scan;
    }
  }
  EXPECT_TRUE(sameStamps(map, oracle, all));
}

// Scans that share one stamp prune as a plain OcTree does; degradeOutdated is no change for
// change detection (integrateMissNoTime does not note keys); an empty map's last update is 0.
TEST(StampedScans, SameStampPrunesLikeOcTreeAndDegradeIsNoChange) {
  OCTOVK_REQUIRE_CONTEXT(ctx);
  const MapParams params = withResolution(0.1);
  StampedMap map(ctx, params);
  EXPECT_EQ(map.lastUpdateTime(), 0u);
  map.degradeOutdated(100, 5);  // an empty map: nothing to degrade, still empty
  EXPECT_FALSE(map.download().root_exists);
  EXPECT_EQ(map.lastUpdateTime(), 0u);
  StampedOracle oracle(params);
  octomap::OcTree plain = makeOracle(params);
  const float res = 0.1f;
  const Eigen::Vector3f origin(0.5f * res, 0.5f * res, 0.5f * res);
  const auto wall = thickWall(res, -4, 4);
  for (int rep = 0; rep < 6; ++rep) {
    ASSERT_TRUE(insertStampedBoth(map, oracle, wall, origin, 77)) << "scan " << rep;
    plain.insertPointCloud(toPointcloud(wall), toPoint(origin));
  }
  EXPECT_EQ(oracle.size(), plain.size());
  map.enableChangeDetection(true);
  oracle.enableChangeDetection(true);
  ASSERT_TRUE(insertStampedBoth(map, oracle, thickWall(res, 4, 6), origin, 80));
  const auto before = ourChanges(map);
  EXPECT_GT(before.size(), 10u);
  oracle.degradeOutdated(90, 5);
  map.degradeOutdated(90, 5);
  ASSERT_TRUE(samePayloadTree(oracle, map.download(), Payload::kStamp));
  std::vector<KeyFlag> want;
  for (auto it = oracle.changedKeysBegin(); it != oracle.changedKeysEnd(); ++it)
    want.emplace_back(it->first[0], it->first[1], it->first[2], it->second);
  std::sort(want.begin(), want.end());
  EXPECT_EQ(ourChanges(map), want);
  EXPECT_EQ(ourChanges(map), before);
}

// A solid block of 8 x 8 x 8 cells, aligned, clamped occupied: it prunes three levels up (one
// node of depth 13), colours averaged over averages, stamps from child 0; degradeOutdated
// degrades that leaf as one; a miss through a corner expands it three levels (children copy
// colour and stamp) and the fold of the next scan lands in the new leaves.
std::vector<Eigen::Vector3f> solidBlock(float res, int x0, int cells) {
  std::vector<Eigen::Vector3f> pts;
  for (int x = 0; x < cells; ++x)
    for (int y = 0; y < cells; ++y)
      for (int z = 0; z < cells; ++z)
        pts.emplace_back((static_cast<float>(x0 + x) + 0.5f) * res,
                         (static_cast<float>(y) + 0.4f) * res,
                         (static_cast<float>(z) + 0.6f) * res);
  return pts;
}

TEST(PayloadScans, BlockPrunesThreeLevelsDegradesAndExpands) {
  OCTOVK_REQUIRE_CONTEXT(ctx);
  const MapParams params = withResolution(0.1);
  const float res = 0.1f;
  const Eigen::Vector3f origin(-20.0f * res, 4.5f * res, 4.5f * res);
  const auto block = solidBlock(res, 0, 8);
  const auto corner = solidBlock(res, 0, 1);
  ColorMap cmap(ctx, params);
  auto coracle = makeColorOracle(params);
  StampedMap smap(ctx, params);
  StampedOracle soracle(params);
  for (std::uint32_t rep = 0; rep < 6; ++rep) {
    ASSERT_TRUE(insertColorBoth(cmap, *coracle, block, origin, colorsOf(110 + rep, block.size()),
                                -1.0, false))
        << "colour scan " << rep;
    ASSERT_TRUE(insertStampedBoth(smap, soracle, block, origin, 500 + rep)) << "stamped " << rep;
  }
  std::size_t depth13 = 0;
  for (auto it = soracle.begin_leafs(), end = soracle.end_leafs(); it != end; ++it)
    depth13 += it.getDepth() == 13 && soracle.isNodeOccupied(*it);
  EXPECT_EQ(depth13, 1u) << "the block should prune to one node of depth 13";
  soracle.degradeOutdated(520, 10);
  smap.degradeOutdated(520, 10);
  ASSERT_TRUE(samePayloadTree(soracle, smap.download(), Payload::kStamp)) << "degrade";
  // A miss through the corner cell from the other side: expands the pruned block.
  const Eigen::Vector3f behind(30.5f * res, 0.4f * res, 0.6f * res);
  const std::vector<Eigen::Vector3f> through = {
      Eigen::Vector3f(-3.5f * res, 0.4f * res, 0.6f * res)};
  ASSERT_TRUE(insertColorBoth(cmap, *coracle, through, behind, colorsOf(120, 1), -1.0, false));
  ASSERT_TRUE(insertStampedBoth(smap, soracle, through, behind, 530));
  EXPECT_NE(soracle.search(toPoint(corner[0])), soracle.search(toPoint(corner[0]), 13))
      << "the miss should have expanded the block";
  ASSERT_TRUE(
      insertColorBoth(cmap, *coracle, corner, origin, colorsOf(121, corner.size()), -1.0, false));
  ASSERT_TRUE(insertStampedBoth(smap, soracle, corner, origin, 531));
  EXPECT_TRUE(sameColors(cmap, *coracle, block));
  EXPECT_TRUE(sameStamps(smap, soracle, block));
}

// One scan of 30,000 points in as many cells: the fold's table holds a node per point.
TEST(PayloadScans, ManyNodesInOneColourScan) {
  OCTOVK_REQUIRE_CONTEXT(ctx);
  const MapParams params = withResolution(0.02);
  ColorMap map(ctx, params);
  auto oracle = makeColorOracle(params);
  std::mt19937 rng(39);
  const Eigen::Vector3f origin = Eigen::Vector3f::Zero();
  const auto pts = randomScan(rng, origin, 30000, 0.5f);
  ASSERT_TRUE(insertColorBoth(map, *oracle, pts, origin, colorsOf(130, pts.size()), -1.0, false));
  ASSERT_TRUE(insertColorBoth(map, *oracle, pts, origin, colorsOf(131, pts.size()), -1.0, true));
}

// ---- a real multi-scan log: the first scans of FR-079 ------------------------------------------

constexpr std::size_t kFr079Scans = 12;

struct WorldScan {
  std::vector<Eigen::Vector3f> points;
  Eigen::Vector3f origin;
};

// fr079.clf.bz2 -> OctoMap's text log (clf2log.py) -> ScanGraph::readPlainASCII (what log2graph
// does), each scan moved to the world as graph2tree moves it. Made once; empty with `why` set.
const std::vector<WorldScan>& fr079Scans(std::string* why) {
  static std::vector<WorldScan> scans;
  static std::string error;
  static std::once_flag once;
  std::call_once(once, [] {
    const std::string dir = OCTOVK_PATH(OCTOVK_SHARED_DATA_DIR) + "/fr079-2d";
    const std::string log = tmpPath("payload_fr079." + std::to_string(::getpid()) + ".log");
    if (shell("python3 '" + dir + "/clf2log.py' '" + dir + "/fr079.clf.bz2' '" + log + "' " +
              std::to_string(kFr079Scans) + " > /dev/null") != 0) {
      error = "clf2log.py failed on " + dir;
      return;
    }
    octomap::ScanGraph graph;
    {
      QuietCout quiet;
      graph.readPlainASCII(log);
    }
    std::remove(log.c_str());
    for (octomap::ScanNode* node : graph) {
      const octomath::Pose6D pose = node->pose;
      octomap::Pointcloud cloud = *node->scan;
      cloud.transform(pose);
      const octomap::point3d o = pose.transform(pose.inv().transform(pose.trans()));
      WorldScan s;
      for (const auto& p : cloud) s.points.emplace_back(p.x(), p.y(), p.z());
      s.origin = Eigen::Vector3f(o.x(), o.y(), o.z());
      scans.push_back(std::move(s));
    }
    if (scans.size() != kFr079Scans) error = "read " + std::to_string(scans.size()) + " scans";
  });
  if (why) *why = error;
  return scans;
}

TEST(RealLog, Fr079FirstScansColorMapEqualsColorOcTree) {
  OCTOVK_REQUIRE_CONTEXT(ctx);
  std::string why;
  const auto& scans = fr079Scans(&why);
  ASSERT_TRUE(why.empty()) << why;
  const MapParams params = withResolution(0.1);
  ColorMap map(ctx, params);
  auto oracle = makeColorOracle(params);
  for (std::size_t i = 0; i < scans.size(); ++i)
    ASSERT_TRUE(insertColorBoth(map, *oracle, scans[i].points, scans[i].origin,
                                colorsOf(i, scans[i].points.size()), i % 4 == 3 ? 8.0 : -1.0,
                                false))
        << "scan " << i;
  EXPECT_TRUE(sameColors(map, *oracle, scans.back().points));
}

TEST(RealLog, Fr079FirstScansStampedMapEqualsOcTreeStamped) {
  OCTOVK_REQUIRE_CONTEXT(ctx);
  std::string why;
  const auto& scans = fr079Scans(&why);
  ASSERT_TRUE(why.empty()) << why;
  const MapParams params = withResolution(0.1);
  StampedMap map(ctx, params);
  StampedOracle oracle(params);
  for (std::size_t i = 0; i < scans.size(); ++i) {
    const auto stamp = static_cast<std::uint32_t>(5000 + 2 * i);
    ASSERT_TRUE(insertStampedBoth(map, oracle, scans[i].points, scans[i].origin, stamp))
        << "scan " << i;
    if (i == scans.size() / 2) {
      oracle.degradeOutdated(stamp, 5);
      map.degradeOutdated(stamp, 5);
      ASSERT_TRUE(samePayloadTree(oracle, map.download(), Payload::kStamp)) << "degrade";
    }
  }
  EXPECT_TRUE(sameStamps(map, oracle, scans.front().points));
}

// ---- every other feature on payload maps
// ---------------------------------------------------------

// Random scans with colours and stamps (occupied, free and pruned leaves, unknown space).
struct ColorScene {
  ColorMap map;
  std::unique_ptr<octomap::ColorOcTree> oracle;
};
struct StampedScene {
  StampedMap map;
  std::unique_ptr<StampedOracle> oracle;
};

ColorScene colorScene(Context& ctx, double resolution, unsigned seed,
                      ColorFold fold = ColorFold::kAverage) {
  const MapParams params = withResolution(resolution);
  ColorScene s{ColorMap(ctx, params), makeColorOracle(params)};
  std::mt19937 rng(seed);
  for (std::size_t i = 0; i < 4; ++i) {
    const Eigen::Vector3f origin(0.3f * static_cast<float>(i), 0.0f, 0.1f);
    const auto pts = randomScan(rng, origin, 1200, 2.0f);
    EXPECT_TRUE(
        insertColorBoth(s.map, *s.oracle, pts, origin, colorsOf(i, pts.size()), -1.0, false, fold));
  }
  return s;
}

StampedScene stampedScene(Context& ctx, double resolution, unsigned seed) {
  const MapParams params = withResolution(resolution);
  StampedScene s{StampedMap(ctx, params), std::make_unique<StampedOracle>(params)};
  std::mt19937 rng(seed);
  for (std::uint32_t i = 0; i < 4; ++i) {
    const Eigen::Vector3f origin(0.3f * static_cast<float>(i), 0.0f, 0.1f);
    const auto pts = randomScan(rng, origin, 1200, 2.0f);
    EXPECT_TRUE(insertStampedBoth(s.map, *s.oracle, pts, origin, 700 + 10 * i));
  }
  return s;
}

// search() on both: state, log-odds, depth and payload of the node found.
template <class Map, class Tree>
void expectSameLookups(Map& map, const Tree& oracle, Payload kind) {
  std::mt19937 rng(5);
  std::uniform_real_distribution<float> u(-2.5f, 2.5f);
  std::vector<Eigen::Vector3f> pts;
  for (int i = 0; i < 2000; ++i) pts.emplace_back(u(rng), u(rng), 0.3f * u(rng));
  pts.emplace_back(std::nanf(""), 0.0f, 0.0f);
  const std::vector<Lookup> got = map.search(pts);
  ASSERT_EQ(got.size(), pts.size());
  std::size_t known = 0, coloured = 0, wrong = 0;
  std::string first;  // the first point that differs, in words
  for (std::size_t i = 0; i < pts.size(); ++i) {
    const auto* n = oracle.search(pts[i].x(), pts[i].y(), pts[i].z());
    Lookup want;
    if (n) {
      ++known;
      want.state = oracle.isNodeOccupied(n) ? CellState::kOccupied : CellState::kFree;
      want.log_odds = n->getLogOdds();
      want.depth = 16;
      while (want.depth > 1 &&
             oracle.search(pts[i].x(), pts[i].y(), pts[i].z(), want.depth - 1) == n)
        --want.depth;
      want.payload = payloadOf(*n);
      coloured += want.payload != newNodePayload(kind);
    }
    const Lookup& g = got[i];
    if (g.state == want.state && floatBits(g.log_odds) == floatBits(want.log_odds) &&
        g.depth == want.depth && g.payload == want.payload)
      continue;
    if (wrong++ == 0) {
      std::ostringstream out;
      out << "point " << i << " (" << pts[i].transpose() << "): OctoMap state "
          << static_cast<int>(want.state) << " log-odds " << want.log_odds << " depth "
          << want.depth << " payload " << payloadText(kind, want.payload) << "; octovk state "
          << static_cast<int>(g.state) << " log-odds " << g.log_odds << " depth " << g.depth
          << " payload " << payloadText(kind, g.payload);
      first = out.str();
    }
  }
  EXPECT_EQ(wrong, 0u) << "lookups differ from OctoMap's search(); the first: " << first;
  EXPECT_GT(known, pts.size() / 10);
  EXPECT_GT(coloured, 10u) << "the probes should find coloured or stamped nodes";
}

TEST(PayloadFeatures, SearchGivesColoursAndStamps) {
  OCTOVK_REQUIRE_CONTEXT(ctx);
  ColorScene c = colorScene(ctx, 0.1, 1);
  expectSameLookups(c.map, *c.oracle, Payload::kColor);
  StampedScene s = stampedScene(ctx, 0.1, 2);
  expectSameLookups(s.map, *s.oracle, Payload::kStamp);
}

template <class Map, class Tree>
void expectSameRays(Map& map, const Tree& oracle, Payload kind) {
  std::mt19937 rng(8);
  std::uniform_real_distribution<float> u(-1.0f, 1.0f);
  std::vector<Ray> rays;
  for (int i = 0; i < 600; ++i) {
    Ray r;
    r.origin = Eigen::Vector3f(0.3f * u(rng), 0.3f * u(rng), 0.1f);
    r.direction = Eigen::Vector3f(u(rng), u(rng), 0.5f * u(rng));
    r.ignore_unknown = i % 2 == 1;
    r.max_range_m = i % 3 == 0 ? 1.0 : -1.0;
    rays.push_back(r);
  }
  const auto got = map.castRays(rays);
  ASSERT_EQ(got.size(), rays.size());
  std::size_t hits = 0, wrong = 0, hit_payloads = 0;
  std::string first;
  for (std::size_t i = 0; i < rays.size(); ++i) {
    const Ray& r = rays[i];
    octomap::point3d end = toPoint(r.origin);
    const bool hit = oracle.castRay(toPoint(r.origin), toPoint(r.direction), end, r.ignore_unknown,
                                    r.max_range_m);
    hits += hit;
    const Eigen::Vector3f want(end.x(), end.y(), end.z());
    // The hit cell's payload: OctoMap's search() at the end (the hit cell's centre).
    std::uint32_t want_payload = 0;
    if (hit) {
      const auto* n = oracle.search(end);
      want_payload = n ? payloadOf(*n) : 0u;
      hit_payloads += want_payload != newNodePayload(kind);
    }
    if (got[i].hit == hit && got[i].end == want && got[i].payload == want_payload) continue;
    if (wrong++ == 0) {
      std::ostringstream out;
      out << "ray " << i << ": OctoMap hit " << hit << " end (" << want.transpose() << ") payload "
          << payloadText(kind, want_payload) << "; octovk hit " << got[i].hit << " end ("
          << got[i].end.transpose() << ") payload " << payloadText(kind, got[i].payload);
      first = out.str();
    }
  }
  EXPECT_EQ(wrong, 0u) << "castRay answers differ; the first: " << first;
  EXPECT_GT(hits, rays.size() / 10);
  EXPECT_GT(hit_payloads, hits / 2) << "most hit cells should be coloured or stamped";
}

TEST(PayloadFeatures, CastRaysOnPayloadMaps) {
  OCTOVK_REQUIRE_CONTEXT(ctx);
  ColorScene c = colorScene(ctx, 0.1, 3);
  expectSameRays(c.map, *c.oracle, Payload::kColor);
  StampedScene s = stampedScene(ctx, 0.1, 4);
  expectSameRays(s.map, *s.oracle, Payload::kStamp);
}

template <class Map, class Tree>
void expectSameBoxLeaves(Map& map, const Tree& oracle) {
  using Leaf = std::tuple<float, float, float, float, float>;
  const Eigen::Vector3f lo(-1.0f, -0.7f, -0.3f), hi(0.9f, 1.3f, 0.25f);
  for (bool occupied_only : {false, true}) {
    std::vector<Leaf> want, got;
    for (auto it = oracle.begin_leafs_bbx(toPoint(lo), toPoint(hi)), end = oracle.end_leafs_bbx();
         it != end; ++it) {
      if (occupied_only && !oracle.isNodeOccupied(*it)) continue;
      const octomap::point3d p = it.getCoordinate();
      want.emplace_back(p.x(), p.y(), p.z(), static_cast<float>(it.getSize()), it->getLogOdds());
    }
    for (const auto& l : map.leavesInBox(lo, hi, occupied_only))
      got.emplace_back(l.center[0], l.center[1], l.center[2], l.size, l.log_odds);
    std::sort(want.begin(), want.end());
    std::sort(got.begin(), got.end());
    EXPECT_GT(want.size(), 10u);
    EXPECT_EQ(got, want) << (occupied_only ? "occupied only" : "all leaves");
  }
}

TEST(PayloadFeatures, LeavesInBoxOnPayloadMaps) {
  OCTOVK_REQUIRE_CONTEXT(ctx);
  ColorScene c = colorScene(ctx, 0.1, 5);
  expectSameBoxLeaves(c.map, *c.oracle);
  // A leaf's colour is colors() at its centre (pruned leaves included).
  std::vector<Eigen::Vector3f> centres;
  std::vector<std::uint32_t> want;
  for (const auto& l : c.map.leavesInBox({-1.0f, -0.7f, -0.3f}, {0.9f, 1.3f, 0.25f})) {
    centres.emplace_back(l.center[0], l.center[1], l.center[2]);
    const auto* n = c.oracle->search(toPoint(centres.back()));
    want.push_back(n ? payloadOf(*n) : 0u);
  }
  std::vector<std::uint32_t> got;
  for (const Rgb& col : c.map.colors(centres)) got.push_back(packRgb(col));
  EXPECT_EQ(got, want);
  StampedScene s = stampedScene(ctx, 0.1, 6);
  expectSameBoxLeaves(s.map, *s.oracle);
}

// clear_bbx: the leaves' log-odds to the lower clamp, colours and stamps untouched, then
// updateInnerOccupancy (ColorOcTree's averages the inner colours again); a scan after it.
template <class Tree>
void clearOracle(Tree& tree, const Eigen::Vector3f& min, const Eigen::Vector3f& max) {
  for (auto it = tree.begin_leafs_bbx(toPoint(min), toPoint(max)), end = tree.end_leafs_bbx();
       it != end; ++it)
    it->setLogOdds(tree.getClampingThresMinLog());
  tree.updateInnerOccupancy();
}

TEST(PayloadFeatures, ClearBoxKeepsColoursAndStamps) {
  OCTOVK_REQUIRE_CONTEXT(ctx);
  const Eigen::Vector3f lo(0.2f, -0.5f, -0.4f), hi(1.1f, 0.7f, 0.6f);
  std::mt19937 rng(12);
  const Eigen::Vector3f origin(0.5f, 0.1f, 0.0f);
  const auto after = randomScan(rng, origin, 800, 1.5f);
  {
    ColorScene c = colorScene(ctx, 0.1, 7);
    clearOracle(*c.oracle, lo, hi);
    c.map.clearBox(lo, hi);
    ASSERT_TRUE(samePayloadTree(*c.oracle, c.map.download(), Payload::kColor)) << "colour map";
    ASSERT_TRUE(
        insertColorBoth(c.map, *c.oracle, after, origin, colorsOf(9, after.size()), -1.0, false))
        << "colour map, scan after the clear";
  }
  {
    StampedScene s = stampedScene(ctx, 0.1, 8);
    clearOracle(*s.oracle, lo, hi);
    s.map.clearBox(lo, hi);
    ASSERT_TRUE(samePayloadTree(*s.oracle, s.map.download(), Payload::kStamp)) << "stamped map";
    ASSERT_TRUE(insertStampedBoth(s.map, *s.oracle, after, origin, 900))
        << "stamped map, scan after the clear";
  }
}

// keepBox keeps the leaves leaf_bbx_iterator visits with their colours and stamps (OctoMap's
// deleteNode-based keep, written leaf by leaf as tests/octomap_keep_box.hpp does); compact()
// after it keeps them too; a scan after both matches OctoMap on the kept tree.
TEST(PayloadFeatures, KeepBoxAndCompactKeepColoursAndStamps) {
  OCTOVK_REQUIRE_CONTEXT(ctx);
  const Eigen::Vector3f lo(-0.8f, -0.9f, -0.35f), hi(0.9f, 0.6f, 0.45f);
  std::mt19937 rng(13);
  const Eigen::Vector3f origin(0.1f, 0.1f, 0.0f);
  const auto after = randomScan(rng, origin, 800, 1.2f);
  {
    ColorScene c = colorScene(ctx, 0.1, 9);
    const std::size_t before = c.oracle->size();
    auto kept = keepBoxOracle(*c.oracle, lo, hi);
    c.map.keepBox(lo, hi);
    EXPECT_LT(kept->size(), before / 2);
    ASSERT_TRUE(samePayloadTree(*kept, c.map.download(), Payload::kColor)) << "colour keepBox";
    c.map.compact();
    ASSERT_TRUE(samePayloadTree(*kept, c.map.download(), Payload::kColor)) << "colour compact";
    ASSERT_TRUE(
        insertColorBoth(c.map, *kept, after, origin, colorsOf(10, after.size()), -1.0, false))
        << "colour map, scan after keepBox";
  }
  {
    StampedScene s = stampedScene(ctx, 0.1, 10);
    auto kept = keepBoxOracle(*s.oracle, lo, hi);
    s.map.keepBox(lo, hi);
    ASSERT_TRUE(samePayloadTree(*kept, s.map.download(), Payload::kStamp)) << "stamped keepBox";
    s.map.compact();
    ASSERT_TRUE(samePayloadTree(*kept, s.map.download(), Payload::kStamp)) << "stamped compact";
    ASSERT_TRUE(insertStampedBoth(s.map, *kept, after, origin, 950))
        << "stamped map, scan after keepBox";
  }
}

// Change detection on payload maps notes the keys OctoMap's trees note (a stamped tree prunes
// differently, so its keys are its own).
TEST(PayloadFeatures, ChangeDetectionOnPayloadMaps) {
  OCTOVK_REQUIRE_CONTEXT(ctx);
  std::mt19937 rng(14);
  ColorScene c = colorScene(ctx, 0.1, 11);
  StampedScene s = stampedScene(ctx, 0.1, 12);
  c.map.enableChangeDetection(true);
  c.oracle->enableChangeDetection(true);
  s.map.enableChangeDetection(true);
  s.oracle->enableChangeDetection(true);
  for (std::uint32_t i = 0; i < 2; ++i) {
    const Eigen::Vector3f origin(-0.2f, 0.1f * static_cast<float>(i), 0.05f);
    const auto pts = randomScan(rng, origin, 800, 1.8f);
    ASSERT_TRUE(
        insertColorBoth(c.map, *c.oracle, pts, origin, colorsOf(20 + i, pts.size()), -1.0, false));
    ASSERT_TRUE(insertStampedBoth(s.map, *s.oracle, pts, origin, 800 + i));
  }
  auto keys = [](const auto& tree) {
    std::vector<KeyFlag> out;
    for (auto it = tree.changedKeysBegin(); it != tree.changedKeysEnd(); ++it)
      out.emplace_back(it->first[0], it->first[1], it->first[2], it->second);
    std::sort(out.begin(), out.end());
    return out;
  };
  const auto want_c = keys(*c.oracle);
  const auto want_s = keys(*s.oracle);
  EXPECT_GT(want_c.size(), 100u);
  EXPECT_EQ(ourChanges(c.map), want_c) << "colour map";
  EXPECT_EQ(ourChanges(s.map), want_s) << "stamped map";
}

// download() then upload() into a fresh map of the same payload gives the same tree, colours
// and stamps included, and scans after the upload go on as OctoMap's; a tree of another payload
// is refused with the map unchanged.
TEST(PayloadFeatures, DownloadUploadRoundTripKeepsColoursAndStamps) {
  OCTOVK_REQUIRE_CONTEXT(ctx);
  std::mt19937 rng(15);
  const Eigen::Vector3f origin(0.2f, -0.1f, 0.0f);
  const auto after = randomScan(rng, origin, 800, 1.6f);
  {
    ColorScene c = colorScene(ctx, 0.1, 13);
    const HostTree tree = c.map.download();
    ColorMap copy(ctx, c.map.params());
    copy.upload(tree);
    ASSERT_TRUE(samePayloadTree(*c.oracle, copy.download(), Payload::kColor));
    ASSERT_TRUE(
        insertColorBoth(copy, *c.oracle, after, origin, colorsOf(30, after.size()), -1.0, false));
    StampedMap other(ctx, c.map.params());
    try {
      other.upload(tree);
      ADD_FAILURE() << "a colour tree uploaded into a stamped map";
    } catch (const Error& e) {
      EXPECT_EQ(e.code(), ErrorCode::kInvalidArgument) << e.what();
    }
    EXPECT_FALSE(other.download().root_exists) << "the refused upload changed the map";
  }
  {
    StampedScene s = stampedScene(ctx, 0.1, 14);
    const HostTree tree = s.map.download();
    StampedMap copy(ctx, s.map.params());
    copy.upload(tree);
    ASSERT_TRUE(samePayloadTree(*s.oracle, copy.download(), Payload::kStamp));
    ASSERT_TRUE(insertStampedBoth(copy, *s.oracle, after, origin, 990));
    OccupancyMap plain(ctx, withResolution(0.1));
    try {
      plain.upload(tree);
      ADD_FAILURE() << "a stamped tree uploaded into a plain map";
    } catch (const Error& e) {
      EXPECT_EQ(e.code(), ErrorCode::kInvalidArgument) << e.what();
    }
  }
}

// An OccupancyMap made with a payload is the same map as ColorMap / StampedMap (its options
// carry the colours and the stamp), and those classes take it over; a map of another payload
// is refused and stays usable.
TEST(PayloadFeatures, OccupancyMapWithPayloadAndTakeOver) {
  OCTOVK_REQUIRE_CONTEXT(ctx);
  MapParams params = withResolution(0.1);
  params.payload = Payload::kColor;
  OccupancyMap generic(ctx, params);
  auto oracle = makeColorOracle(params);
  std::mt19937 rng(41);
  const Eigen::Vector3f origin(0.1f, 0.0f, 0.0f);
  const auto pts = randomScan(rng, origin, 600, 1.5f);
  const auto colors = colorsOf(140, pts.size());
  oracle->insertPointCloud(toPointcloud(pts), toPoint(origin));
  for (std::size_t i = 0; i < pts.size(); ++i)
    oracle->averageNodeColor(pts[i].x(), pts[i].y(), pts[i].z(), colors[i].r, colors[i].g,
                             colors[i].b);
  oracle->updateInnerOccupancy();
  (void)generic.insertPointCloud(pts, origin, {.colors = colors});
  ASSERT_TRUE(samePayloadTree(*oracle, generic.download(), Payload::kColor));
  try {
    StampedMap wrong(std::move(generic));
    ADD_FAILURE() << "a colour map taken over as a stamped map";
  } catch (const Error& e) {
    EXPECT_EQ(e.code(), ErrorCode::kInvalidArgument) << e.what();
  }
  ColorMap taken(std::move(generic));
  EXPECT_TRUE(samePayloadTree(*oracle, taken.download(), Payload::kColor));
  const auto more = randomScan(rng, origin, 400, 1.5f);
  EXPECT_TRUE(
      insertColorBoth(taken, *oracle, more, origin, colorsOf(141, more.size()), -1.0, false));
}

// Scans and castRay through ray tracing (MapParams::scan_rays, cast_ray_backend) on payload
// maps: the traced scan jumps over clamped free leaves, whose updates OctoMap aborts (their
// stamps stay); the trees, colours and stamps equal OctoMap's after every scan. Runs where the
// device traces rays (the Mesa 25 lavapipe step of scripts/test.sh), skipped with the reason
// elsewhere.
class PayloadRtScan : public ::testing::TestWithParam<ScanRays> {};

TEST_P(PayloadRtScan, ScansAndRaysEqualOctoMap) {
  OCTOVK_REQUIRE_CONTEXT(ctx);
  const ScanRays path = GetParam();
  OCTOVK_REQUIRE_TRACE_PATH(ctx, path);
  MapParams params = withResolution(0.1);
  params.scan_rays = path;
  params.cast_ray_backend = static_cast<CastRayBackend>(path);  // numbered alike
  ColorMap cmap(ctx, params);
  auto coracle = makeColorOracle(params);
  StampedMap smap(ctx, params);
  StampedOracle soracle(params);
  std::mt19937 rng(43);
  for (std::uint32_t scan = 0; scan < 8; ++scan) {
    const Eigen::Vector3f origin(0.05f * static_cast<float>(scan % 2), 0.0f, 0.05f);
    const auto pts = randomScan(rng, origin, 800, 2.0f);
    const double max_range = scan % 3 == 2 ? 1.2 : -1.0;
    ASSERT_TRUE(insertColorBoth(cmap, *coracle, pts, origin, colorsOf(150 + scan, pts.size()),
                                max_range, scan % 4 == 3))
        << tracePathName(path) << " colour scan " << scan;
    ASSERT_TRUE(insertStampedBoth(smap, soracle, pts, origin, 6000 + scan, max_range, false))
        << tracePathName(path) << " stamped scan " << scan;
  }
  expectSameRays(cmap, *coracle, Payload::kColor);
  expectSameRays(smap, soracle, Payload::kStamp);
}

INSTANTIATE_TEST_SUITE_P(Paths, PayloadRtScan,
                         ::testing::Values(ScanRays::kRayQuery, ScanRays::kRayTracingPipeline),
                         [](const ::testing::TestParamInfo<ScanRays>& info) {
                           return std::string(tracePathName(info.param));
                         });

// A scan with queries in the same command stream: the lookups and rays see the scan's colours
// and stamps (the fold runs before them).
TEST(PayloadFeatures, QueriesAfterTheScanSeeItsColoursAndStamps) {
  OCTOVK_REQUIRE_CONTEXT(ctx);
  const MapParams params = withResolution(0.1);
  ColorMap cmap(ctx, params);
  auto coracle = makeColorOracle(params);
  StampedMap smap(ctx, params);
  StampedOracle soracle(params);
  std::mt19937 rng(45);
  for (std::uint32_t scan = 0; scan < 3; ++scan) {
    const Eigen::Vector3f origin(0.1f * static_cast<float>(scan), 0.0f, 0.0f);
    const auto pts = randomScan(rng, origin, 700, 1.5f);
    const auto colors = colorsOf(160 + scan, pts.size());
    std::vector<Ray> rays;
    for (std::size_t i = 0; i < 100; ++i) rays.push_back(Ray{origin, pts[i] - origin});
    coracle->insertPointCloud(toPointcloud(pts), toPoint(origin));
    for (std::size_t i = 0; i < pts.size(); ++i)
      coracle->averageNodeColor(pts[i].x(), pts[i].y(), pts[i].z(), colors[i].r, colors[i].g,
                                colors[i].b);
    soracle.setScanTime(7000 + scan);
    soracle.insertPointCloud(toPointcloud(pts), toPoint(origin));
    QueryResults cres, sres;
    (void)cmap.insertPointCloud(pts, origin, {.colors = colors}, {pts, rays}, cres);
    (void)smap.insertPointCloud(pts, origin, {.stamp = 7000 + scan}, {pts, rays}, sres);
    ASSERT_EQ(cres.lookups.size(), pts.size());
    ASSERT_EQ(sres.lookups.size(), pts.size());
    std::size_t wrong_c = 0, wrong_s = 0;
    for (std::size_t i = 0; i < pts.size(); ++i) {
      const auto* c = coracle->search(toPoint(pts[i]));
      const auto* t = soracle.search(toPoint(pts[i]));
      wrong_c += cres.lookups[i].payload != (c ? payloadOf(*c) : 0u);
      wrong_s += sres.lookups[i].payload != (t ? payloadOf(*t) : 0u);
    }
    EXPECT_EQ(wrong_c, 0u) << "scan " << scan << ": lookups with a stale colour";
    EXPECT_EQ(wrong_s, 0u) << "scan " << scan << ": lookups with a stale stamp";
    std::size_t wrong_rays = 0;
    std::string first;
    for (std::size_t i = 0; i < rays.size(); ++i) {
      octomap::point3d end;
      const bool hit = coracle->castRay(toPoint(rays[i].origin), toPoint(rays[i].direction), end);
      const auto* n = hit ? coracle->search(end) : nullptr;
      const std::uint32_t want = n ? payloadOf(*n) : 0u;
      if (cres.rays[i].hit == hit && cres.rays[i].payload == want) continue;
      if (wrong_rays++ == 0)
        first = "ray " + std::to_string(i) + ": OctoMap hit " + std::to_string(hit) + " colour " +
                payloadText(Payload::kColor, want) + "; octovk hit " +
                std::to_string(cres.rays[i].hit) + " payload " +
                payloadText(Payload::kColor, cres.rays[i].payload);
    }
    EXPECT_EQ(wrong_rays, 0u) << "scan " << scan
                              << ": rays' hit colours differ; the first: " << first;
  }
}

// The distance field of a colour or stamped map equals the plain map's of the same scans (the
// payload is no obstacle), built from scratch and after an update() that follows a scan.
TEST(PayloadFeatures, DistanceFieldOnPayloadMaps) {
  OCTOVK_REQUIRE_CONTEXT(ctx);
  const MapParams params = withResolution(0.1);
  OccupancyMap plain(ctx, params);
  ColorMap cmap(ctx, params);
  StampedMap smap(ctx, params);
  std::mt19937 rng(47);
  auto scan = [&](std::uint32_t i) {
    const Eigen::Vector3f origin(0.1f * static_cast<float>(i), 0.0f, 0.0f);
    const auto pts = randomScan(rng, origin, 600, 1.5f);
    (void)plain.insertPointCloud(pts, origin);
    (void)cmap.insertPointCloud(pts, origin, colorsOf(170 + i, pts.size()));
    (void)smap.insertPointCloud(pts, origin, 8000 + i);
  };
  for (std::uint32_t i = 0; i < 3; ++i) scan(i);
  const Eigen::Vector3f lo(-1.0f, -1.0f, -0.5f), hi(1.0f, 1.0f, 0.5f);
  DistanceField fp(plain, lo, hi), fc(cmap, lo, hi), fs(smap, lo, hi);
  const auto want = fp.download().squared_cells;
  std::size_t obstacles = 0;
  for (const std::uint32_t d : want) obstacles += d == 0;
  EXPECT_GT(obstacles, 10u);
  EXPECT_EQ(fc.download().squared_cells, want) << "colour map";
  EXPECT_EQ(fs.download().squared_cells, want) << "stamped map";
  scan(3);
  fp.update();
  fc.update();
  fs.update();
  const auto again = fp.download().squared_cells;
  EXPECT_EQ(fc.download().squared_cells, again) << "colour map after update";
  EXPECT_EQ(fs.download().squared_cells, again) << "stamped map after update";
}

// ---- files: writeMapFile's .ot equals ColorOcTree::write / OcTreeStamped::write
// -------------------

::testing::AssertionResult sameBytes(const std::string& want, const std::string& got) {
  if (want == got) return ::testing::AssertionSuccess();
  const auto diff = std::mismatch(want.begin(), want.end(), got.begin(), got.end());
  const auto at = static_cast<std::size_t>(diff.first - want.begin());
  return ::testing::AssertionFailure()
         << "OctoMap wrote " << want.size() << " bytes, octovk " << got.size()
         << "; first difference at byte " << at << " (OctoMap's header: "
         << want.substr(0, std::min<std::size_t>(want.find("data\n") + 5, 120)) << ")";
}

TEST(PayloadFiles, OtBytesEqualOctoMapWrite) {
  OCTOVK_REQUIRE_CONTEXT(ctx);
  for (ColorFold fold : {ColorFold::kAverage, ColorFold::kIntegrate}) {
    ColorScene c = colorScene(ctx, 0.1, 16, fold);
    std::stringstream want;
    c.oracle->write(want);
    const std::string path = tmpPath("payload_oracle_color." + std::to_string(::getpid()) + ".ot");
    writeMapFile(c.map, path);
    EXPECT_TRUE(sameBytes(want.str(), fileBytes(path)))
        << "ColorOcTree .ot, " << (fold == ColorFold::kAverage ? "averaged" : "integrated");
    std::remove(path.c_str());
  }
  {
    StampedScene s = stampedScene(ctx, 0.1, 17);
    std::stringstream want;
    s.oracle->write(want);
    const std::string path = tmpPath("payload_oracle_stamp." + std::to_string(::getpid()) + ".ot");
    writeMapFile(s.map, path);
    EXPECT_TRUE(sameBytes(want.str(), fileBytes(path))) << "OcTreeStamped .ot";
    std::remove(path.c_str());
    std::remove((path + ".stamps").c_str());
  }
}

// Files in the middle of a run: OctoMap's ColorOcTree .ot read by octovk (readMapFile, taken
// over by ColorMap) and octovk's stamped .ot with its stamps read back, then more scans into
// both, equal to OctoMap's going on with its own tree; the files written at the end equal
// OctoMap's bytes.
TEST(PayloadFiles, ReadMidRunThenScanOn) {
  OCTOVK_REQUIRE_CONTEXT(ctx);
  const MapParams params = withResolution(0.1);
  const float res = 0.1f;
  const Eigen::Vector3f origin(0.5f * res, 0.5f * res, 0.5f * res);
  const auto wall = thickWall(res, -4, 4);
  const std::string stem = tmpPath("payload_oracle_mid." + std::to_string(::getpid()));
  {
    ColorMap first(ctx, params);
    auto oracle = makeColorOracle(params);
    for (std::size_t rep = 0; rep < 6; ++rep)
      ASSERT_TRUE(insertColorBoth(first, *oracle, wall, origin, colorsOf(180 + rep, wall.size()),
                                  -1.0, false));
    ASSERT_TRUE(oracle->write(stem + ".color.ot"));
    ColorMap map(readMapFile(ctx, stem + ".color.ot"));
    ASSERT_TRUE(samePayloadTree(*oracle, map.download(), Payload::kColor)) << "read back";
    const auto half = thickWall(res, -4, 0);
    for (std::size_t rep = 0; rep < 2; ++rep)
      ASSERT_TRUE(insertColorBoth(map, *oracle, half, origin, colorsOf(190 + rep, half.size()),
                                  -1.0, false))
          << "after the read, scan " << rep;
    std::stringstream want;
    oracle->write(want);
    writeMapFile(map, stem + ".color2.ot");
    EXPECT_TRUE(sameBytes(want.str(), fileBytes(stem + ".color2.ot")));
    std::remove((stem + ".color.ot").c_str());
    std::remove((stem + ".color2.ot").c_str());
  }
  {
    StampedMap first(ctx, params);
    StampedOracle oracle(params);
    for (std::uint32_t rep = 0; rep < 6; ++rep)
      ASSERT_TRUE(insertStampedBoth(first, oracle, rep < 3 ? wall : thickWall(res, -4, 0), origin,
                                    200 + rep));
    writeMapFile(first, stem + ".stamp.ot");
    StampedMap map(readMapFile(ctx, stem + ".stamp.ot"));
    ASSERT_TRUE(samePayloadTree(oracle, map.download(), Payload::kStamp)) << "read back";
    oracle.degradeOutdated(210, 5);
    map.degradeOutdated(210, 5);
    ASSERT_TRUE(insertStampedBoth(map, oracle, wall, origin, 211)) << "after the read";
    std::stringstream want;
    oracle.write(want);
    writeMapFile(map, stem + ".stamp2.ot");
    EXPECT_TRUE(sameBytes(want.str(), fileBytes(stem + ".stamp2.ot")));
    for (const char* f : {".stamp.ot", ".stamp.ot.stamps", ".stamp2.ot", ".stamp2.ot.stamps"})
      std::remove((stem + f).c_str());
  }
}

}  // namespace
}  // namespace octovk::test
