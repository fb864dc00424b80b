// Scans through ray tracing (MapParams::scan_rays, `octovk integrate --rays rt`) against
// OctoMap, through ray queries and through a ray-tracing pipeline (ScanRays::kRayQuery,
// kRayTracingPipeline; --rays rt-query, rt-pipeline): the same tree, node by node and log-odds
// bits included, after every scan, while later scans cross regions that earlier ones clamped free
// (which the traced rays jump over); max range on and off, discretize on and off, rays along axes
// and through cell corners, points outside the map and NaN; the program's files byte-identical to
// --rays walk and to graph2tree; a device without ray tracing refusing it.
//
// On a device without a path its tests are skipped with the reason, and fail where the run
// expects ray tracing (OCTOVK_EXPECT_RAY_QUERY, the Mesa 25 step of CI: its lavapipe has both).
#include <gtest/gtest.h>

#include <cmath>
#include <cstring>
#include <limits>
#include <random>
#include <string>
#include <tuple>
#include <vector>

#include "caller_buffer.hpp"
#include "cli_support.hpp"
#include "octovk/octomap_io.hpp"
#include "octovk/octovk.hpp"
#include "octovk/vulkan_interop.hpp"
#include "rt_paths.hpp"
#include "test_support.hpp"

namespace octovk {
namespace {

MapParams rtParams(double resolution, ScanRays path) {
  MapParams params = test::withResolution(resolution);
  params.scan_rays = path;
  return params;
}

using test::tracePathName;
const auto kTracePaths = ::testing::Values(ScanRays::kRayQuery, ScanRays::kRayTracingPipeline);

// A scan that keeps its origin near `centre` and reaches walls at about `radius`: repeated, it
// clamps the space between free (5 misses from 0 reach clamping_min), so later scans cross
// clamped-free leaves, partly pruned into large nodes, next to free leaves not clamped yet.
std::vector<Eigen::Vector3f> roomScan(std::mt19937& rng, const Eigen::Vector3f& origin,
                                      std::size_t n, float radius) {
  std::vector<Eigen::Vector3f> pts = test::randomScan(rng, origin, n, radius);
  // Points on the room's walls (x = +-radius), so occupied cells recur scan after scan.
  std::uniform_real_distribution<float> u(-0.6f * radius, 0.6f * radius);
  for (std::size_t i = 0; i < n / 4; ++i)
    pts.emplace_back(i % 2 ? radius : -radius, u(rng), u(rng));
  return pts;
}

// ---- the traced path against OctoMap, after every scan ----

class RtScanOracle : public ::testing::TestWithParam<std::tuple<double, bool, ScanRays>> {};

TEST_P(RtScanOracle, SameTreeAfterEveryScanWhileRaysCrossClampedFreeSpace) {
  OCTOVK_REQUIRE_CONTEXT(ctx);
  const auto [max_range, discretize, path] = GetParam();
  OCTOVK_REQUIRE_TRACE_PATH(ctx, path);
  const MapParams params = rtParams(0.1, path);
  OccupancyMap map(ctx, params);
  MapParams walk_params = params;
  walk_params.scan_rays = ScanRays::kWalk;
  OccupancyMap walk(ctx, walk_params);  // OctoMap's free-cell counts, to see the skipping
  octomap::OcTree oracle = test::makeOracle(params);
  std::mt19937 rng(17);
  std::size_t skipped_later = 0;
  for (int scan = 0; scan < 12; ++scan) {
    const Eigen::Vector3f origin(0.05f + 0.03f * static_cast<float>(scan % 3),
                                 -0.02f * static_cast<float>(scan % 4), 0.01f);
    const auto pts = roomScan(rng, origin, 1500, 2.5f);
    ScanStats rt;
    ASSERT_TRUE(test::insertBoth(map, oracle, pts, origin, max_range, discretize, &rt))
        << "scan " << scan;
    const ScanStats w =
        walk.insertPointCloud(pts, origin, {.max_range_m = max_range, .discretize = discretize});
    EXPECT_EQ(rt.occupied_cells, w.occupied_cells) << "scan " << scan;
    EXPECT_EQ(rt.skipped_outside, w.skipped_outside);
    EXPECT_EQ(rt.skipped_nonfinite, w.skipped_nonfinite);
    EXPECT_LE(rt.free_cells, w.free_cells) << "scan " << scan;
    EXPECT_GT(rt.device.scan_build_ms + rt.device.scan_trace_ms, 0.0);
    if (scan >= 6) skipped_later += w.free_cells - rt.free_cells;
  }
  // The later scans crossed clamped-free leaves and left their cells out.
  EXPECT_GT(skipped_later, 1000u);
}

INSTANTIATE_TEST_SUITE_P(MaxRangeAndDiscretize, RtScanOracle,
                         ::testing::Combine(::testing::Values(-1.0, 1.7), ::testing::Bool(),
                                            kTracePaths),
                         [](const auto& info) {
                           return std::string(std::get<0>(info.param) < 0 ? "NoMaxRange"
                                                                          : "MaxRange") +
                                  (std::get<1>(info.param) ? "Discretize" : "") + "_" +
                                  tracePathName(std::get<2>(info.param));
                         });

// The other traced-scan tests, on each path.
class RtScan : public ::testing::TestWithParam<ScanRays> {};

// Rays along the axes, the face and space diagonals, from an origin on a cell corner and from
// one on a cell edge, scan after scan (the first scans clamp the rays' cells free, the later
// ones, longer and shorter, cross them and end inside them).
TEST_P(RtScan, RaysAlongAxesAndThroughCorners) {
  OCTOVK_REQUIRE_CONTEXT(ctx);
  const ScanRays path = GetParam();
  OCTOVK_REQUIRE_TRACE_PATH(ctx, path);
  const MapParams params = rtParams(0.1, path);
  for (const Eigen::Vector3f& origin :
       {Eigen::Vector3f(0.0f, 0.0f, 0.0f), Eigen::Vector3f(0.2f, 0.3f, 0.05f)}) {
    OccupancyMap map(ctx, params);
    octomap::OcTree oracle = test::makeOracle(params);
    for (int scan = 0; scan < 9; ++scan) {
      const float length = 1.0f + 0.35f * static_cast<float>(scan % 4);
      std::vector<Eigen::Vector3f> pts;
      for (int dx = -1; dx <= 1; ++dx)
        for (int dy = -1; dy <= 1; ++dy)
          for (int dz = -1; dz <= 1; ++dz) {
            if (!dx && !dy && !dz) continue;
            const Eigen::Vector3f d(static_cast<float>(dx), static_cast<float>(dy),
                                    static_cast<float>(dz));
            pts.push_back(origin + d.normalized() * length);
            pts.push_back(origin + d * length * 0.5f);  // corners of cells on the diagonals
          }
      ASSERT_TRUE(test::insertBoth(map, oracle, pts, origin, scan % 3 == 2 ? 1.2 : -1.0, false))
          << "origin (" << origin.transpose() << ") scan " << scan;
    }
  }
}

// NaN and infinite points are skipped and counted as the walk does; points outside the map give
// no occupied cell and rays reaching them no free cells; a sensor outside the map gives nothing.
// OctoMap gets the finite points.
TEST_P(RtScan, NonFinitePointsAndPointsOutsideTheMap) {
  OCTOVK_REQUIRE_CONTEXT(ctx);
  const ScanRays path = GetParam();
  OCTOVK_REQUIRE_TRACE_PATH(ctx, path);
  const MapParams params = rtParams(0.1, path);  // the map spans +-3276.8 m
  OccupancyMap map(ctx, params);
  MapParams walk_params = params;
  walk_params.scan_rays = ScanRays::kWalk;
  OccupancyMap walk(ctx, walk_params);
  octomap::OcTree oracle = test::makeOracle(params);
  std::mt19937 rng(5);
  const float nan = std::numeric_limits<float>::quiet_NaN();
  const float inf = std::numeric_limits<float>::infinity();
  for (int scan = 0; scan < 8; ++scan) {
    const bool outside_sensor = scan == 5;
    const Eigen::Vector3f origin =
        outside_sensor ? Eigen::Vector3f(4000.0f, 0.0f, 0.0f) : Eigen::Vector3f(0.05f, 0.1f, 0.0f);
    std::vector<Eigen::Vector3f> finite =
        roomScan(rng, Eigen::Vector3f(0.05f, 0.1f, 0.0f), 800, 2.0f);
    finite.emplace_back(5000.0f, 0.0f, 0.0f);
    finite.emplace_back(0.0f, -3300.0f, 1.0f);
    std::vector<Eigen::Vector3f> pts = finite;
    pts.emplace_back(nan, 0.0f, 0.0f);
    pts.emplace_back(1.0f, inf, 0.0f);
    pts.emplace_back(0.5f, 0.5f, -inf);
    oracle.insertPointCloud(test::toPointcloud(finite), test::toPoint(origin), -1.0, false, false);
    const ScanStats rt = map.insertPointCloud(pts, origin);
    const ScanStats w = walk.insertPointCloud(pts, origin);
    EXPECT_EQ(rt.skipped_nonfinite, 3u);
    EXPECT_EQ(rt.skipped_nonfinite, w.skipped_nonfinite);
    EXPECT_EQ(rt.skipped_outside, w.skipped_outside);
    EXPECT_GE(rt.skipped_outside, 2u);  // the two points outside the map
    auto ours = toOcTree(map);
    ASSERT_TRUE(test::sameTree(oracle, *ours)) << "scan " << scan;
  }
}

// Scans submitted back to back (three in flight): each builds its structure in its own
// submission from the tree the earlier ones left, and the node pool grows on the way.
TEST_P(RtScan, StreamedScansMatchOctoMap) {
  OCTOVK_REQUIRE_CONTEXT(ctx);
  const ScanRays path = GetParam();
  OCTOVK_REQUIRE_TRACE_PATH(ctx, path);
  const MapParams params = rtParams(0.05, path);
  OccupancyMap map(ctx, params);
  octomap::OcTree oracle = test::makeOracle(params);
  std::mt19937 rng(23);
  for (int scan = 0; scan < 16; ++scan) {
    const Eigen::Vector3f origin(0.4f * static_cast<float>(scan / 4), 0.02f, 0.03f);
    const auto pts = roomScan(rng, origin, 1200, 2.0f);
    oracle.insertPointCloud(test::toPointcloud(pts), test::toPoint(origin), 3.0, false, false);
    map.submitPointCloud(pts, origin, {.max_range_m = 3.0});
  }
  map.flush();
  const auto stats = map.takeScanStats();
  ASSERT_EQ(stats.size(), 16u);
  EXPECT_EQ(stats.back().nodes, oracle.size());
  auto ours = toOcTree(map);
  EXPECT_TRUE(test::sameTree(oracle, *ours));
}

// The other ways a scan comes in take the same traced path after their own first passes: depth
// images unprojected on the device (uint16 and float), and points and pixels in a caller's
// Vulkan buffer. Repeated from nearby poses in one room, so the later ones cross clamped-free
// space; after every scan the tree equals OctoMap's for the same points (the depth images'
// points as unprojectDepthImage gives them, which the depth-image tests hold to the formula).
TEST_P(RtScan, DepthImagesAndCallerBuffersMatchOctoMap) {
  OCTOVK_REQUIRE_CONTEXT(ctx);
  const ScanRays path = GetParam();
  OCTOVK_REQUIRE_TRACE_PATH(ctx, path);
  const MapParams params = rtParams(0.05, path);
  OccupancyMap map(ctx, params);
  MapParams walk_params = params;
  walk_params.scan_rays = ScanRays::kWalk;
  OccupancyMap walk(ctx, walk_params);  // OctoMap's free-cell counts, to see the skipping
  octomap::OcTree oracle = test::makeOracle(params);
  const VulkanHandles vk = vulkanHandles(ctx);
  ASSERT_NE(vk.device, VK_NULL_HANDLE);

  DepthImage cam;
  cam.width = 48;
  cam.height = 36;
  cam.fx = cam.fy = 40.0f;
  cam.cx = 23.5f;
  cam.cy = 17.5f;
  // The depth of a box-shaped room (walls at x = +-1.6, y = +-1.1, z = 2.8 in the camera frame),
  // in metres, with a hole every 13th pixel.
  std::vector<float> metres(std::size_t{cam.width} * cam.height);
  for (std::uint32_t v = 0; v < cam.height; ++v)
    for (std::uint32_t u = 0; u < cam.width; ++u) {
      const float dx = std::abs((static_cast<float>(u) - cam.cx) / cam.fx);
      const float dy = std::abs((static_cast<float>(v) - cam.cy) / cam.fy);
      float z = 2.8f;
      if (dx > 1e-6f) z = std::min(z, 1.6f / dx);
      if (dy > 1e-6f) z = std::min(z, 1.1f / dy);
      const std::size_t i = std::size_t{v} * cam.width + u;
      metres[i] = i % 13 == 0 ? 0.0f : z + 0.003f * static_cast<float>(i % 7);
    }
  std::vector<std::uint16_t> raw(metres.size());
  for (std::size_t i = 0; i < metres.size(); ++i)
    raw[i] = static_cast<std::uint16_t>(std::lround(metres[i] * 1000.0f));
  test::CallerBuffer pixel_buffer(vk, raw.size() * sizeof(std::uint16_t));
  std::memcpy(pixel_buffer.data(), raw.data(), raw.size() * sizeof(std::uint16_t));
  std::mt19937 rng(29);
  const std::vector<Eigen::Vector3f> cloud = roomScan(rng, Eigen::Vector3f::Zero(), 1500, 2.0f);
  test::CallerBuffer point_buffer(vk, cloud.size() * sizeof(Eigen::Vector3f));
  std::memcpy(point_buffer.data(), cloud.data(), cloud.size() * sizeof(Eigen::Vector3f));

  std::size_t skipped_later = 0;
  for (int scan = 0; scan < 12; ++scan) {
    Pose pose;
    pose.rotation =
        Eigen::AngleAxisf(0.05f * static_cast<float>(scan % 5), Eigen::Vector3f::UnitY());
    pose.translation = Eigen::Vector3f(0.02f * static_cast<float>(scan % 3), 0.01f, -0.03f);
    const double max_range = scan % 4 == 3 ? 2.2 : -1.0;
    std::vector<Eigen::Vector3f> points;
    ScanStats stats;
    switch (scan % 3) {
      case 0:  // float metres from host memory
        cam.encoding = DepthImage::Encoding::kFloat32;
        cam.depth_scale = 1.0f;
        cam.depths = std::span<const float>(metres);
        points = unprojectDepthImage(cam);
        stats = map.insertDepthImage(cam, pose, {.max_range_m = max_range});
        break;
      case 1:  // uint16 millimetres from a caller's buffer
        cam.encoding = DepthImage::Encoding::kUint16;
        cam.depth_scale = 1000.0f;
        cam.depths = std::span<const std::uint16_t>(raw);
        points = unprojectDepthImage(cam);
        cam.depths = {};  // from the device buffer only
        stats = insertDepthImageOnDevice(map, pixel_buffer.range(), cam, pose,
                                         {.max_range_m = max_range});
        break;
      default:  // points from a caller's buffer
        points = cloud;
        stats = insertPointCloudOnDevice(map, point_buffer.range(),
                                         static_cast<std::uint32_t>(cloud.size()),
                                         Eigen::Vector3f::Zero(), pose, {.max_range_m = max_range});
        break;
    }
    oracle.insertPointCloud(test::toPointcloud(points), test::toPoint(Eigen::Vector3f::Zero()),
                            test::toPose6D(pose), max_range, false, false);
    EXPECT_GT(stats.device.scan_build_ms + stats.device.scan_trace_ms, 0.0) << "scan " << scan;
    EXPECT_EQ(stats.nodes, oracle.size()) << "scan " << scan;
    auto ours = toOcTree(map);
    ASSERT_TRUE(test::sameTree(oracle, *ours)) << "scan " << scan;
    const ScanStats w =
        walk.insertPointCloud(points, Eigen::Vector3f::Zero(), pose, {.max_range_m = max_range});
    EXPECT_EQ(stats.occupied_cells, w.occupied_cells) << "scan " << scan;
    EXPECT_LE(stats.free_cells, w.free_cells) << "scan " << scan;
    if (scan >= 6) skipped_later += w.free_cells - stats.free_cells;
  }
  // The later scans crossed clamped-free space and left its cells out.
  EXPECT_GT(skipped_later, 1000u);
}

INSTANTIATE_TEST_SUITE_P(Paths, RtScan, kTracePaths,
                         [](const auto& info) { return std::string(tracePathName(info.param)); });

// ---- refusal ----

// Without a way to trace rays (a device that has neither, or a Context that does not enable
// them) the traced scans are refused when the map is made, naming the cause and the fix, as each
// forced path is where it is missing; so is a map under a memory cap. The walk stays the default.
TEST(RtScanRefused, WithoutRayTracingOrUnderACap) {
  OCTOVK_REQUIRE_CONTEXT(ctx);
  EXPECT_EQ(MapParams{}.scan_rays, ScanRays::kWalk);
  ContextOptions options;
  options.enable_ray_query = false;
  auto plain = Context::create(options);
  ASSERT_TRUE(plain) << plain.error().what();
  Context& no_rt = *plain.value();
  ASSERT_FALSE(no_rt.device().ray_query_enabled);
  std::size_t refusals = 0;
  for (Context* c : {&ctx, &no_rt}) {
    for (const ScanRays asked :
         {ScanRays::kRayTracing, ScanRays::kRayQuery, ScanRays::kRayTracingPipeline}) {
      const bool runs =
          c == &ctx && (asked == ScanRays::kRayTracing
                            ? test::hasTracePath(*c, CastRayBackend::kRayQuery) ||
                                  test::hasTracePath(*c, CastRayBackend::kRayTracingPipeline)
                            : test::hasTracePath(*c, static_cast<CastRayBackend>(asked)));
      if (runs) continue;
      ++refusals;
      try {
        OccupancyMap refused(*c, rtParams(0.1, asked));
        ADD_FAILURE() << tracePathName(asked) << " accepted without it";
      } catch (const Error& e) {
        EXPECT_EQ(e.code(), ErrorCode::kMissingFeature);
        const std::string what = e.what();
        EXPECT_NE(what.find("scan_rays"), std::string::npos) << what;
        EXPECT_NE(what.find("ScanRays::kWalk"), std::string::npos) << what;
        EXPECT_NE(what.find("--rays walk"), std::string::npos) << what;
      }
    }
  }
  EXPECT_GE(refusals, 3u);  // no_rt refuses all three
  MapParams capped = rtParams(0.1, ScanRays::kRayTracing);
  capped.max_device_bytes = 64u << 20;
  EXPECT_THROW(OccupancyMap(ctx, capped), Error);
  MapParams bad = capped;
  bad.scan_rays = static_cast<ScanRays>(7);
  EXPECT_NE(bad.validate().find("scan_rays"), std::string::npos);
}

// ---- the program ----

// A small scan graph: a sensor turning and moving through a room, scans repeated so that later
// ones cross space clamped free.
std::string writeRoomGraph(const test::Scratch& dir) {
  const std::string path = dir / "room.graph";
  test::QuietCout quiet;  // OctoMap's writer reports every scan
  writeScanGraph(path, 10, [](std::size_t i) {
    std::mt19937 rng(static_cast<unsigned>(100 + i));
    GraphScan scan;
    scan.points_sensor = roomScan(rng, Eigen::Vector3f::Zero(), 1000, 2.5f);
    scan.T_world_sensor.translation =
        Eigen::Vector3f(0.1f * static_cast<float>(i % 3), 0.05f, 0.3f);
    scan.T_world_sensor.rotation = Eigen::Quaternionf(
        Eigen::AngleAxisf(0.2f * static_cast<float>(i), Eigen::Vector3f::UnitZ()));
    return scan;
  });
  return path;
}

// --rays rt-query and --rays rt-pipeline (where the device has each) write graph2tree's files,
// byte for byte, as --rays walk does.
TEST(RtScanCli, RaysRtWritesTheSameFilesAsWalkAndGraph2tree) {
  OCTOVK_REQUIRE_CONTEXT(ctx);
  std::vector<std::string> traced;
  for (const ScanRays path : {ScanRays::kRayQuery, ScanRays::kRayTracingPipeline}) {
    if (test::hasTracePath(ctx, static_cast<CastRayBackend>(path)))
      traced.push_back(path == ScanRays::kRayQuery ? "rt-query" : "rt-pipeline");
    else if (test::rayQueryExpected())
      ADD_FAILURE() << "OCTOVK_EXPECT_RAY_QUERY is set but device '" << ctx.device().name
                    << "' has no " << tracePathName(path) << " path";
  }
  if (traced.empty()) GTEST_SKIP() << "device '" << ctx.device().name << "' traces no rays";
  test::Scratch dir("rt_scan");
  const std::string graph = writeRoomGraph(dir);
  for (const std::string max_range : {"-1", "2"}) {
    const test::RunResult walk =
        test::runOctovk({"integrate", graph, "-o", dir / "walk.bt", "-o", dir / "walk.ot", "-r",
                         "0.05", "-m", max_range, "-q", "--rays", "walk"},
                        dir.dir());
    ASSERT_EQ(walk.exit_code, 0) << walk.err;
    const bool g2t_here = !OCTOVK_PATH(OCTOVK_GRAPH2TREE).empty();
    if (!g2t_here && test::runningInCi()) ADD_FAILURE() << "graph2tree missing under CI";
    if (g2t_here) {
      const test::RunResult g2t =
          test::runShell(test::quote(OCTOVK_PATH(OCTOVK_GRAPH2TREE)) + " -i " + test::quote(graph) +
                             " -o " + test::quote(dir / "g2t.bt") + " -res 0.05 -m " + max_range,
                         dir.dir());
      ASSERT_EQ(g2t.exit_code, 0) << g2t.err;
    }
    for (const std::string& rays : traced) {
      const test::RunResult rt =
          test::runOctovk({"integrate", graph, "-o", dir / "rt.bt", "-o", dir / "rt.ot", "-r",
                           "0.05", "-m", max_range, "-q", "--rays", rays},
                          dir.dir());
      ASSERT_EQ(rt.exit_code, 0) << rt.err;
      const std::string what = "--rays " + rays + " -m " + max_range;
      EXPECT_EQ(test::readFile(dir / "rt.bt"), test::readFile(dir / "walk.bt")) << what;
      EXPECT_EQ(test::readFile(dir / "rt.ot"), test::readFile(dir / "walk.ot")) << what;
      if (!g2t_here) continue;
      EXPECT_EQ(test::readFile(dir / "rt.bt"), test::readFile(dir / "g2t.bt")) << what;
      EXPECT_EQ(test::readFile(dir / "rt.ot"), test::readFile(dir / "g2t.bt.ot")) << what;
    }
  }
}

// --help tells of --rays; a bad value is a usage error; without ray queries --rays rt fails with
// the library's reason and leaves no file.
TEST(RtScanCli, RaysOptionHelpAndErrors) {
  OCTOVK_REQUIRE_CONTEXT(ctx);
  test::Scratch dir("rt_scan");
  const test::RunResult help = test::runOctovk({"integrate", "--help"}, dir.dir());
  EXPECT_EQ(help.exit_code, 0);
  EXPECT_NE(help.out.find("--rays walk|rt|rt-query|rt-pipeline"), std::string::npos) << help.out;
  EXPECT_NE(help.out.find("(default: walk)"), std::string::npos) << help.out;
  const std::string graph = writeRoomGraph(dir);
  const test::RunResult bad =
      test::runOctovk({"integrate", graph, "-o", dir / "x.bt", "--rays", "bvh"}, dir.dir());
  EXPECT_NE(bad.exit_code, 0);
  EXPECT_NE(bad.err.find("--rays walk"), std::string::npos) << bad.err;
  EXPECT_FALSE(test::fs::exists(dir / "x.bt"));
  // Each path the device lacks is refused with the library's reason, and no file is left.
  for (const ScanRays path : {ScanRays::kRayQuery, ScanRays::kRayTracingPipeline}) {
    if (test::hasTracePath(ctx, static_cast<CastRayBackend>(path))) continue;
    const bool query = path == ScanRays::kRayQuery;
    const test::RunResult refused =
        test::runOctovk({"integrate", graph, "-o", dir / "y.bt", "--rays",
                         query ? "rt-query" : "rt-pipeline", "-q"},
                        dir.dir());
    EXPECT_NE(refused.exit_code, 0);
    EXPECT_NE(refused.err.find(query ? "no ray queries" : "no ray-tracing pipelines"),
              std::string::npos)
        << refused.err;
    EXPECT_FALSE(test::fs::exists(dir / "y.bt"));
  }
}

// `octovk devices` names the ways each device traces rays, and the way castRay (and --rays rt)
// takes on the selected one: ray queries first, then the pipeline, else the walk.
TEST(RtScanCli, DevicesNamesTheRayTracingPathsAndTheOneUsed) {
  OCTOVK_REQUIRE_CONTEXT(ctx);
  test::Scratch dir("rt_scan");
  const test::RunResult r = test::runOctovk({"devices"}, dir.dir());
  ASSERT_EQ(r.exit_code, 0) << r.err;
  const bool query = test::hasTracePath(ctx, CastRayBackend::kRayQuery);
  const bool pipeline = test::hasTracePath(ctx, CastRayBackend::kRayTracingPipeline);
  const std::string offers = query && pipeline ? "ray queries and ray-tracing pipelines"
                             : query           ? "ray queries"
                             : pipeline        ? "ray-tracing pipelines"
                                               : "no ray tracing";
  const std::string listed = std::to_string(ctx.device().index) + ": " + ctx.device().name;
  const std::size_t line = r.out.find(listed);
  ASSERT_NE(line, std::string::npos) << r.out;
  EXPECT_NE(r.out.substr(line, r.out.find('\n', line) - line).find(offers), std::string::npos)
      << r.out;
  const char* used = query      ? "castRay: ray tracing through ray queries"
                     : pipeline ? "castRay: ray tracing through a ray-tracing pipeline"
                                : "castRay: compute walk";
  EXPECT_NE(r.out.find(used), std::string::npos) << r.out;
}

}  // namespace
}  // namespace octovk
