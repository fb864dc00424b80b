// Queries against OctoMap on the same maps: point lookups (search), castRay and the leaves of a
// bounding box must give exactly OctoMap's answers.
#include <octomap/octomap.h>

#include <algorithm>
#include <cmath>
#include <cstring>
#include <tuple>

#include "caller_buffer.hpp"
#include "gpu/gpu_types.h"
#include "octovk/vulkan_interop.hpp"
#include "rt_paths.hpp"
#include "test_support.hpp"

namespace octovk {
namespace {

struct Built {
  std::unique_ptr<OccupancyMap> map;
  std::unique_ptr<octomap::OcTree> tree;
  octomap::OcTree& oracle() { return *tree; }
};

// A map from a few random scans in a room-sized region, the same in both.
Built buildMap(Context& ctx, double resolution, unsigned seed,
               CastRayBackend backend = CastRayBackend::kWalk) {
  Built b;
  MapParams params;
  params.resolution = resolution;
  params.cast_ray_backend = backend;
  b.map = std::make_unique<OccupancyMap>(ctx, params);
  b.tree = std::make_unique<octomap::OcTree>(resolution);  // OctoMap's defaults, as params
  std::mt19937 rng(seed);
  std::uniform_real_distribution<float> u(-1.0f, 1.0f);
  for (int scan = 0; scan < 4; ++scan) {
    const Eigen::Vector3f origin(0.3f * static_cast<float>(scan), 0.1f, 0.0f);
    std::vector<Eigen::Vector3f> pts;
    for (int i = 0; i < 800; ++i) {
      Eigen::Vector3f d(u(rng), u(rng), 0.3f * u(rng));
      if (d.norm() < 1e-3f) continue;
      pts.push_back(origin + d.normalized() * (1.5f + 0.5f * u(rng)));
    }
    b.map->insertPointCloud(pts, origin);
    b.oracle().insertPointCloud(test::toPointcloud(pts),
                                octomap::point3d(origin.x(), origin.y(), origin.z()));
  }
  return b;
}

std::vector<Ray> randomRays(std::mt19937& rng, double resolution, std::size_t n) {
  std::uniform_real_distribution<float> u(-1.0f, 1.0f);
  std::vector<Ray> rays;
  const float r = static_cast<float>(resolution);
  for (std::size_t i = 0; i < n; ++i) {
    Ray ray;
    switch (i % 6) {
      case 0:  // from inside free space, random direction
        ray.origin = {0.2f * u(rng), 0.2f * u(rng), 0.1f * u(rng)};
        ray.direction = {u(rng), u(rng), u(rng)};
        break;
      case 1:  // along an axis
        ray.origin = {0.1f * u(rng), 0.1f * u(rng), 0.0f};
        ray.direction =
            Eigen::Vector3f::Unit(static_cast<int>(i / 6 % 3)) * (u(rng) < 0 ? -1.f : 1.f);
        break;
      case 2:  // from a voxel border, along a diagonal
        ray.origin = {r * std::round(5 * u(rng)), r * std::round(5 * u(rng)), 0.0f};
        ray.direction = {1.0f, u(rng) < 0 ? -1.0f : 1.0f, 0.0f};
        break;
      case 3:  // starting in unknown space outside the scanned region
        ray.origin = {5.0f * u(rng), 5.0f * u(rng), 2.0f + u(rng)};
        ray.direction = {u(rng), u(rng), u(rng)};
        break;
      case 4:  // with a max range
        ray.origin = {0.1f * u(rng), 0.1f * u(rng), 0.0f};
        ray.direction = {u(rng), u(rng), 0.2f * u(rng)};
        ray.max_range_m = 0.5 + std::abs(u(rng));
        break;
      default:  // outward from the scanned region, where unknown space follows
        ray.origin = {0.0f, 0.0f, 0.0f};
        ray.direction = {u(rng), u(rng), 0.5f * u(rng)};
        break;
    }
    ray.ignore_unknown = (i / 2) % 2 == 1;
    if (ray.direction.norm() < 1e-3f) ray.direction = Eigen::Vector3f::UnitX();
    rays.push_back(ray);
  }
  return rays;
}

class Queries : public ::testing::TestWithParam<std::tuple<double, unsigned>> {};

TEST_P(Queries, LookupsEqualOctoMapSearch) {
  OCTOVK_REQUIRE_CONTEXT(ctx);
  const auto [resolution, seed] = GetParam();
  Built b = buildMap(ctx, resolution, seed);
  std::mt19937 rng(seed + 100);
  std::uniform_real_distribution<float> u(-2.2f, 2.2f);
  std::vector<Eigen::Vector3f> pts;
  for (int i = 0; i < 3000; ++i) pts.emplace_back(u(rng), u(rng), 0.2f * u(rng));
  pts.emplace_back(std::nanf(""), 0.0f, 0.0f);
  pts.emplace_back(1e9f, 0.0f, 0.0f);
  const auto got = b.map->search(pts);
  ASSERT_EQ(got.size(), pts.size());
  std::size_t known = 0;
  for (std::size_t i = 0; i < pts.size(); ++i) {
    const octomap::OcTreeNode* node = b.oracle().search(pts[i].x(), pts[i].y(), pts[i].z());
    if (!node) {
      EXPECT_EQ(got[i].state, CellState::kUnknown) << "point " << i;
      continue;
    }
    ++known;
    const CellState want =
        b.oracle().isNodeOccupied(node) ? CellState::kOccupied : CellState::kFree;
    EXPECT_EQ(got[i].state, want) << "point " << i;
    EXPECT_EQ(got[i].log_odds, node->getLogOdds()) << "point " << i;
  }
  EXPECT_GT(known, pts.size() / 10);  // the test looks at mapped space, not only unknown
}

using test::tracePathName;

// castRay on each backend: the walk, and ray tracing through ray queries and through a
// ray-tracing pipeline where the device has them (see OCTOVK_REQUIRE_TRACE_PATH: skipped with
// the reason elsewhere, failed where expected).
#define OCTOVK_REQUIRE_BACKEND(ctx, backend) \
  if ((backend) != CastRayBackend::kWalk) OCTOVK_REQUIRE_TRACE_PATH(ctx, backend)
const auto kBackends = ::testing::Values(CastRayBackend::kWalk, CastRayBackend::kRayQuery,
                                         CastRayBackend::kRayTracingPipeline);
const auto kTracePaths =
    ::testing::Values(CastRayBackend::kRayQuery, CastRayBackend::kRayTracingPipeline);

class CastRays : public ::testing::TestWithParam<std::tuple<double, unsigned, CastRayBackend>> {};

TEST_P(CastRays, EqualOctoMap) {
  OCTOVK_REQUIRE_CONTEXT(ctx);
  const auto [resolution, seed, backend] = GetParam();
  OCTOVK_REQUIRE_BACKEND(ctx, backend);
  Built b = buildMap(ctx, resolution, seed, backend);
  EXPECT_EQ(b.map->castRayInfo().backend, backend);
  std::mt19937 rng(seed + 200);
  const auto rays = randomRays(rng, resolution, 3000);
  const auto got = b.map->castRays(rays);
  ASSERT_EQ(got.size(), rays.size());
  std::size_t hits = 0;
  for (std::size_t i = 0; i < rays.size(); ++i) {
    const Ray& r = rays[i];
    octomap::point3d end(r.origin.x(), r.origin.y(), r.origin.z());
    const bool hit =
        b.oracle().castRay(octomap::point3d(r.origin.x(), r.origin.y(), r.origin.z()),
                           octomap::point3d(r.direction.x(), r.direction.y(), r.direction.z()), end,
                           r.ignore_unknown, r.max_range_m);
    hits += hit;
    EXPECT_EQ(got[i].hit, hit) << "ray " << i;
    EXPECT_EQ(got[i].end.x(), end.x()) << "ray " << i;
    EXPECT_EQ(got[i].end.y(), end.y()) << "ray " << i;
    EXPECT_EQ(got[i].end.z(), end.z()) << "ray " << i;
  }
  EXPECT_GT(hits, rays.size() / 10);
  EXPECT_LT(hits, rays.size());
}

INSTANTIATE_TEST_SUITE_P(Maps, CastRays,
                         ::testing::Combine(::testing::Values(0.1, 0.05, 0.2),
                                            ::testing::Values(1u, 2u), kBackends),
                         [](const auto& info) {
                           return std::string(tracePathName(std::get<2>(info.param))) + "_res" +
                                  std::to_string(static_cast<int>(std::get<0>(info.param) * 100)) +
                                  "_seed" + std::to_string(std::get<1>(info.param));
                         });

TEST_P(Queries, LeavesInBoxEqualOctoMapIterator) {
  OCTOVK_REQUIRE_CONTEXT(ctx);
  const auto [resolution, seed] = GetParam();
  Built b = buildMap(ctx, resolution, seed);
  using Leaf = std::tuple<float, float, float, float, float>;
  for (bool occupied_only : {false, true}) {
    const Eigen::Vector3f lo(-1.0f, -0.7f, -0.3f), hi(0.9f, 1.3f, 0.25f);
    std::vector<Leaf> want;
    for (auto it = b.oracle().begin_leafs_bbx(octomap::point3d(lo.x(), lo.y(), lo.z()),
                                              octomap::point3d(hi.x(), hi.y(), hi.z())),
              end = b.oracle().end_leafs_bbx();
         it != end; ++it) {
      if (occupied_only && !b.oracle().isNodeOccupied(*it)) continue;
      const octomap::point3d c = it.getCoordinate();
      want.emplace_back(c.x(), c.y(), c.z(), static_cast<float>(it.getSize()), it->getLogOdds());
    }
    std::vector<Leaf> got;
    for (const auto& l : b.map->leavesInBox(lo, hi, occupied_only))
      got.emplace_back(l.center[0], l.center[1], l.center[2], l.size, l.log_odds);
    std::sort(want.begin(), want.end());
    std::sort(got.begin(), got.end());
    EXPECT_GT(want.size(), 10u);
    EXPECT_EQ(got, want) << (occupied_only ? "occupied only" : "all leaves");
  }
  // A corner outside the map: no leaves, as OctoMap's iterator.
  EXPECT_TRUE(b.map->leavesInBox(Eigen::Vector3f(-1e6f, 0, 0), Eigen::Vector3f(1, 1, 1)).empty());
}

TEST(QueriesAfterScan, SameCommandStreamAnswersOnTheUpdatedMap) {
  OCTOVK_REQUIRE_CONTEXT(ctx);
  Built b = buildMap(ctx, 0.1, 7);
  std::vector<Eigen::Vector3f> pts;
  for (int i = 0; i < 200; ++i)
    pts.emplace_back(2.5f, -1.0f + 0.01f * static_cast<float>(i), 0.05f);
  const Eigen::Vector3f origin(0.0f, 0.0f, 0.05f);
  std::vector<Ray> rays{{origin, {1.0f, 0.0f, 0.0f}, -1.0, false}};
  std::vector<Eigen::Vector3f> lookups{{2.5f, 0.0f, 0.05f}, {1.0f, 0.0f, 0.05f}};
  QueryResults results;
  b.map->insertPointCloud(pts, origin, ScanOptions{}, {lookups, rays}, results);
  b.oracle().insertPointCloud(test::toPointcloud(pts),
                              octomap::point3d(origin.x(), origin.y(), origin.z()));
  ASSERT_EQ(results.lookups.size(), 2u);
  ASSERT_EQ(results.rays.size(), 1u);
  for (std::size_t i = 0; i < lookups.size(); ++i) {
    const auto* node = b.oracle().search(lookups[i].x(), lookups[i].y(), lookups[i].z());
    ASSERT_NE(node, nullptr);
    EXPECT_EQ(results.lookups[i].log_odds, node->getLogOdds());
  }
  EXPECT_EQ(results.lookups[0].state, CellState::kOccupied);
  octomap::point3d end;
  const bool hit =
      b.oracle().castRay(octomap::point3d(0, 0, 0.05f), octomap::point3d(1, 0, 0), end);
  EXPECT_EQ(results.rays[0].hit, hit);
  EXPECT_EQ(results.rays[0].end.x(), end.x());
}

// The situations of OctoMap's own ray-casting test, answered on the device and compared with
// OctoMap on the same map.
std::vector<Eigen::Vector3f> sphereDirections(int n) {
  std::vector<Eigen::Vector3f> dirs;
  for (int i = 0; i < n; ++i) {
    const double theta = M_PI * (i + 0.5) / n;
    for (int j = 0; j < n; ++j) {
      const double phi = 2.0 * M_PI * j / n;
      dirs.emplace_back(static_cast<float>(std::sin(theta) * std::cos(phi)),
                        static_cast<float>(std::sin(theta) * std::sin(phi)),
                        static_cast<float>(std::cos(theta)));
    }
  }
  return dirs;
}

::testing::AssertionResult sameAsOctoMap(const octomap::OcTree& tree, const std::vector<Ray>& rays,
                                         const std::vector<RayHit>& got) {
  for (std::size_t i = 0; i < rays.size(); ++i) {
    const Ray& r = rays[i];
    octomap::point3d end(r.origin.x(), r.origin.y(), r.origin.z());
    const bool hit =
        tree.castRay(octomap::point3d(r.origin.x(), r.origin.y(), r.origin.z()),
                     octomap::point3d(r.direction.x(), r.direction.y(), r.direction.z()), end,
                     r.ignore_unknown, r.max_range_m);
    auto same = [](float a, float b) { return a == b || (std::isnan(a) && std::isnan(b)); };
    if (hit != got[i].hit || !same(end.x(), got[i].end.x()) || !same(end.y(), got[i].end.y()) ||
        !same(end.z(), got[i].end.z()))
      return ::testing::AssertionFailure()
             << "ray " << i << ": OctoMap " << hit << " (" << end << "), octovk " << got[i].hit
             << " (" << got[i].end.transpose() << ")";
  }
  return ::testing::AssertionSuccess();
}

class RayCastingScenarios : public ::testing::TestWithParam<CastRayBackend> {};

TEST_P(RayCastingScenarios, SphereOfRadius2FromItsCentre) {
  OCTOVK_REQUIRE_CONTEXT(ctx);
  const CastRayBackend backend = GetParam();
  OCTOVK_REQUIRE_BACKEND(ctx, backend);
  MapParams params;
  params.resolution = 0.05;
  params.cast_ray_backend = backend;
  OccupancyMap map(ctx, params);
  octomap::OcTree tree(0.05);
  const Eigen::Vector3f origin(0.01f, 0.01f, 0.02f);
  const auto dirs = sphereDirections(300);
  std::vector<Eigen::Vector3f> pts;
  for (const auto& d : dirs) pts.push_back(origin + 2.0f * d);
  map.insertPointCloud(pts, origin);
  tree.insertPointCloud(test::toPointcloud(pts),
                        octomap::point3d(origin.x(), origin.y(), origin.z()));

  std::vector<Ray> rays;
  for (const auto& d : sphereDirections(120)) rays.push_back({origin, d, 3.0, false});
  const auto got = map.castRays(rays);
  EXPECT_TRUE(sameAsOctoMap(tree, rays, got));
  double mean = 0;
  std::size_t hits = 0;
  for (const auto& h : got) {
    hits += h.hit;
    mean += (h.end - origin).norm();
  }
  EXPECT_EQ(hits, rays.size());  // every ray hits the sphere
  EXPECT_NEAR(mean / static_cast<double>(rays.size()), 2.0, 0.05);
}

TEST_P(RayCastingScenarios, CubeWithAnOccupiedWallAndAFloor) {
  OCTOVK_REQUIRE_CONTEXT(ctx);
  const CastRayBackend backend = GetParam();
  OCTOVK_REQUIRE_BACKEND(ctx, backend);
  const double res = 0.1;
  const float half = static_cast<float>(res / 2);
  octomap::OcTree tree(res);
  // Free inside a cube, its +x face occupied, and a few occupied floor cells below the origin.
  for (int ix = 0; ix < 20; ++ix)
    for (int iy = 0; iy < 20; ++iy)
      for (int iz = 0; iz < 20; ++iz) {
        const float x = -0.95f + static_cast<float>(ix * res);
        const float y = -0.95f + static_cast<float>(iy * res);
        const float z = -0.95f + static_cast<float>(iz * res);
        tree.updateNode(octomap::point3d(x, y, z), x >= 0.9f);
      }
  for (float fx : {half, 3 * half, -half, -3 * half})
    tree.updateNode(octomap::point3d(fx, half, -half), true);
  MapParams params;
  params.resolution = res;
  params.cast_ray_backend = backend;
  OccupancyMap map(ctx, params);
  fromOcTree(map, tree);

  const Eigen::Vector3f o = Eigen::Vector3f::Zero();
  std::vector<Ray> rays = {
      {o, {0.95f, 0.95f, 0.95f}, -1.0, false},           // the corner
      {o, {1.0f, 0.0f, 0.0f}, -1.0, false},              // the wall
      {{half, half, 0.5f}, {0, 0, -1.0f}, -1.0, false},  // the floor
      {o, {0.0f, 1.0f, 0.0f}, -1.0, false},              // into unknown space: stops there
      {o, {0.0f, 1.0f, 0.0f}, -1.0, true},               // ignoring unknown: up to the map's border
      {o, {-1.0f, 0.0f, 0.0f}, -1.0, true},              // the other border
      {o, {-1.0f, 0.0f, 0.0f}, 0.9, true},               // stopped by max range in free space
  };
  const auto got = map.castRays(rays);
  EXPECT_TRUE(sameAsOctoMap(tree, rays, got));
  EXPECT_TRUE(got[0].hit);
  EXPECT_TRUE(got[1].hit);
  EXPECT_NEAR((got[1].end - o).norm(), 1.0, res / 2);
  EXPECT_TRUE(got[2].hit);
  EXPECT_FLOAT_EQ(got[2].end.z(), -half);
  EXPECT_FALSE(got[3].hit);
  EXPECT_FALSE(got[4].hit);
  EXPECT_FLOAT_EQ(got[4].end.y(), static_cast<float>(32768 * res - res / 2));
  EXPECT_FALSE(got[5].hit);
  EXPECT_FLOAT_EQ(got[5].end.x(), static_cast<float>(-32767 * res - res / 2));
  EXPECT_FALSE(got[6].hit);
  EXPECT_NEAR((got[6].end - o).norm(), 0.9, res);
  const auto at_end = map.search(std::vector<Eigen::Vector3f>{got[6].end, got[3].end});
  EXPECT_EQ(at_end[0].state, CellState::kFree);
  EXPECT_EQ(at_end[1].state, CellState::kUnknown);
}

TEST_P(RayCastingScenarios, BadQueriesHaveDefinedResults) {
  OCTOVK_REQUIRE_CONTEXT(ctx);
  const CastRayBackend backend = GetParam();
  OCTOVK_REQUIRE_BACKEND(ctx, backend);
  Built b = buildMap(ctx, 0.1, 11, backend);
  const float nan = std::nanf("");
  std::vector<Ray> rays = {
      {{nan, 0, 0}, {1, 0, 0}, -1.0, false},   // NaN origin
      {{0, 0, 0}, {0, 0, 0}, -1.0, true},      // zero direction
      {{1e7f, 0, 0}, {1, 0, 0}, -1.0, false},  // origin outside the map
      {{0, 0, 0}, {nan, 1, 0}, -1.0, false},   // NaN direction
  };
  const auto got = b.map->castRays(rays);
  ASSERT_EQ(got.size(), rays.size());
  // NaN components compare as OctoMap's arithmetic makes them (a NaN direction component simply
  // never steps); the results equal OctoMap's, `end` included where OctoMap sets it.
  EXPECT_TRUE(sameAsOctoMap(b.oracle(), rays, got));
  EXPECT_FALSE(got[0].hit);
  EXPECT_FALSE(got[1].hit);
  EXPECT_FALSE(got[2].hit);
  EXPECT_EQ(got[2].end.x(), 1e7f);  // `end` untouched by OctoMap: the origin
  const auto looked = b.map->search(std::vector<Eigen::Vector3f>{{nan, 0, 0}, {1e7f, 0, 0}});
  EXPECT_EQ(looked[0].state, CellState::kUnknown);
  EXPECT_EQ(looked[1].state, CellState::kUnknown);
}

// A map of large nodes, where castRay crosses whole free or unknown nodes at once: two free
// cubes of 64^3 cells (pruned into two nodes), a few occupied cells and an occupied wall in one
// (which splits it into nodes of every size), everything else unknown up to the map's border.
octomap::OcTree largeNodeMap(double resolution) {
  octomap::OcTree tree(resolution);
  const int lo = 32768 - 64;
  for (int x = lo; x < 32768 + 64; ++x)
    for (int y = lo; y < 32768; ++y)
      for (int z = lo; z < 32768; ++z)
        tree.updateNode(
            octomap::OcTreeKey(static_cast<octomap::key_type>(x), static_cast<octomap::key_type>(y),
                               static_cast<octomap::key_type>(z)),
            false);
  for (const auto& [x, y, z] : {std::tuple{32770, 32740, 32750}, std::tuple{32800, 32710, 32766},
                                std::tuple{32831, 32767, 32704}, std::tuple{32790, 32750, 32720}})
    tree.updateNode(
        octomap::OcTreeKey(static_cast<octomap::key_type>(x), static_cast<octomap::key_type>(y),
                           static_cast<octomap::key_type>(z)),
        true);
  for (int y = lo + 16; y < 32768 - 16; ++y)  // an occupied wall on the block's +x face
    for (int z = lo + 16; z < 32768 - 16; ++z)
      tree.updateNode(octomap::OcTreeKey(32768 + 63, static_cast<octomap::key_type>(y),
                                         static_cast<octomap::key_type>(z)),
                      true);
  return tree;
}

std::vector<Ray> largeNodeRays(double resolution, unsigned seed) {
  std::mt19937 rng(seed);
  std::uniform_real_distribution<float> u(-1.0f, 1.0f);
  const float r = static_cast<float>(resolution);
  const float inside_x = 64 * r, inside_yz = 32 * r;  // half extents of the free block
  const Eigen::Vector3f centre(0.0f, -inside_yz, -inside_yz);
  const std::vector<Eigen::Vector3f> dirs = {{1, 0, 0},
                                             {-1, 0, 0},
                                             {0, 1, 0},
                                             {0, -1, 0},
                                             {0, 0, 1},
                                             {0, 0, -1},
                                             {1, 1, 0},
                                             {-1, 1, 0},
                                             {1, 1, 1},
                                             {-1, -1, 1},
                                             {1, -1, -1},
                                             {1, 2, 3},
                                             {1, 1e-6f, 0},
                                             {-1e-7f, 1, 1e-7f},
                                             {3, 1, 0},
                                             {1e-30f, 1e-30f, 0},
                                             {1e30f, -2e30f, 1e29f}};
  std::vector<Ray> rays;
  for (int i = 0; i < 1800; ++i) {
    Ray ray;
    ray.ignore_unknown = (i / 3) % 2 == 0;
    switch (i % 6) {
      case 0:  // inside the free block, any direction
        ray.origin =
            centre + Eigen::Vector3f(inside_x * u(rng), inside_yz * u(rng), inside_yz * u(rng));
        ray.direction = {u(rng), u(rng), u(rng)};
        break;
      case 1:  // from a cell corner, along axes, face and space diagonals (ties of tMax)
        ray.origin = {r * std::round(40 * u(rng)), r * std::round(-32 + 30 * u(rng)),
                      r * std::round(-32 + 30 * u(rng))};
        ray.direction = dirs[static_cast<std::size_t>(i / 6) % dirs.size()];
        break;
      case 2:  // from a cell centre, max range at or next to a cell centre's distance
      {
        const int k = 1 + static_cast<int>(std::abs(u(rng)) * 120);
        const int axis = (i / 6) % 3;
        ray.origin = {r * (std::round(20 * u(rng)) + 0.5f),
                      -r * (std::round(30 + 20 * u(rng)) + 0.5f),
                      -r * (std::round(30 + 20 * u(rng)) + 0.5f)};
        ray.direction = Eigen::Vector3f::Unit(axis) * (u(rng) < 0 ? -1.0f : 1.0f);
        if (i % 12 == 2) ray.direction += Eigen::Vector3f(0.0f, 1e-3f * u(rng), 1e-3f * u(rng));
        const double d = static_cast<double>(static_cast<float>(k) * r);
        const int pick = (i / 18) % 3;
        ray.max_range_m = pick == 0   ? d
                          : pick == 1 ? std::nextafter(d, 0.0)
                                      : std::nextafter(d, 1e9);
        break;
      }
      case 3:  // far out in unknown space: to the map's border when unknown is ignored
      {
        const float span = static_cast<float>(32000 * resolution);
        ray.origin = {span * u(rng), span * u(rng), span * u(rng)};
        ray.direction = i % 12 == 3 ? dirs[static_cast<std::size_t>(i / 12) % dirs.size()]
                                    : Eigen::Vector3f(u(rng), u(rng), u(rng));
        if (i % 24 == 9) ray.max_range_m = 1000.0 * std::abs(u(rng)) * resolution;
        break;
      }
      case 4:  // from the free block outward through unknown space, with a long max range
        ray.origin =
            centre + Eigen::Vector3f(inside_x * u(rng), inside_yz * u(rng), inside_yz * u(rng));
        ray.direction = {u(rng), u(rng), 0.2f * u(rng)};
        ray.max_range_m = 2000.0 * resolution * std::abs(u(rng));
        break;
      default:  // through the block from unknown space, aimed at it
      {
        const Eigen::Vector3f from =
            centre + Eigen::Vector3f(300 * r * u(rng), 300 * r * u(rng), 300 * r * u(rng));
        ray.origin = from;
        ray.direction = centre +
                        Eigen::Vector3f(inside_x * u(rng), inside_yz * u(rng), inside_yz * u(rng)) -
                        from;
        if (i % 12 == 5) ray.max_range_m = 400.0 * r * std::abs(u(rng));
        break;
      }
    }
    if (ray.direction.squaredNorm() == 0.0f) ray.direction = Eigen::Vector3f::UnitX();
    rays.push_back(ray);
  }
  return rays;
}

// Rays that spend most of their walk inside large free or unknown nodes, with max ranges and
// map borders inside them, at resolutions whose cell sizes are not powers of two.
TEST_P(RayCastingScenarios, AcrossLargeNodesEqualOctoMap) {
  OCTOVK_REQUIRE_CONTEXT(ctx);
  const CastRayBackend backend = GetParam();
  OCTOVK_REQUIRE_BACKEND(ctx, backend);
  for (const double resolution : {0.1, 0.05, 0.37}) {
    SCOPED_TRACE(resolution);
    octomap::OcTree tree = largeNodeMap(resolution);
    MapParams params;
    params.resolution = resolution;
    params.cast_ray_backend = backend;
    OccupancyMap map(ctx, params);
    fromOcTree(map, tree);
    const auto rays = largeNodeRays(resolution, 31);
    const auto got = map.castRays(rays);
    ASSERT_EQ(got.size(), rays.size());
    EXPECT_TRUE(sameAsOctoMap(tree, rays, got));
    std::size_t hits = 0, far = 0;
    for (std::size_t i = 0; i < got.size(); ++i) {
      hits += got[i].hit;
      far += (got[i].end - rays[i].origin).norm() > 1000 * resolution;
    }
    EXPECT_GT(hits, got.size() / 50);
    EXPECT_GT(far, got.size() / 10);
  }
}

// Rays through cell corners and along cell edges (ties between the axes' tMax at every step),
// from outside the mapped region, to the map's border and to the max range, on every side.
TEST_P(RayCastingScenarios, CornersEdgesAndLongRays) {
  OCTOVK_REQUIRE_CONTEXT(ctx);
  const CastRayBackend backend = GetParam();
  OCTOVK_REQUIRE_BACKEND(ctx, backend);
  Built b = buildMap(ctx, 0.1, 5, backend);
  const float r = 0.1f;
  std::vector<Ray> rays;
  for (bool ignore : {false, true})
    for (double range : {-1.0, 0.75, 4.0, 300.0}) {
      // From a cell corner along the space diagonals and face diagonals: ties at every step.
      for (int sx : {-1, 1})
        for (int sy : {-1, 1})
          for (int sz : {-1, 0, 1})
            rays.push_back({{0.0f, 0.0f, 0.0f}, {float(sx), float(sy), float(sz)}, range, ignore});
      // Along cell edges and faces, in each axis direction.
      for (int a = 0; a < 3; ++a)
        for (float s : {-1.0f, 1.0f}) {
          rays.push_back({{r, -r, 0.0f}, Eigen::Vector3f::Unit(a) * s, range, ignore});
          rays.push_back({{0.5f * r, r, 0.5f * r}, Eigen::Vector3f::Unit(a) * s, range, ignore});
        }
      // From far outside the mapped region, towards it and past it.
      for (const Eigen::Vector3f& o :
           {Eigen::Vector3f(-30.0f, 0.05f, 0.05f), Eigen::Vector3f(7.0f, -9.0f, 3.0f),
            Eigen::Vector3f(0.0f, 0.0f, -50.0f)}) {
        rays.push_back({o, -o, range, ignore});
        rays.push_back({o, -o + Eigen::Vector3f(0.3f, 0.2f, 0.0f), range, ignore});
      }
      for (const auto& d : sphereDirections(12))
        rays.push_back({{0.05f, 0.02f, 0.0f}, d, range, ignore});
    }
  const auto got = b.map->castRays(rays);
  EXPECT_TRUE(sameAsOctoMap(b.oracle(), rays, got));
}

// The ray-tracing backend, on each path (ray queries, a ray-tracing pipeline).
class RayTracingBackend : public ::testing::TestWithParam<CastRayBackend> {};

// The ray-tracing backend builds its acceleration structure lazily, from the leaf boxes, after
// scans changed them, and answers on the updated map; an empty map has no boxes at all.
TEST_P(RayTracingBackend, BuildsLazilyAfterScansAndTracesTheUpdatedMap) {
  OCTOVK_REQUIRE_CONTEXT(ctx);
  const CastRayBackend path = GetParam();
  OCTOVK_REQUIRE_TRACE_PATH(ctx, path);
  MapParams params;
  params.resolution = 0.1;
  params.cast_ray_backend = path;
  OccupancyMap map(ctx, params);
  octomap::OcTree tree(0.1);
  const Eigen::Vector3f origin(0.0f, 0.0f, 0.05f);
  std::vector<Ray> rays;
  for (const auto& d : sphereDirections(16)) {
    rays.push_back({origin, d, -1.0, false});
    rays.push_back({origin, d, -1.0, true});
    rays.push_back({origin, d, 2.5, true});
  }
  // Empty: nothing to trace (zero boxes).
  auto got = map.castRays(rays);
  EXPECT_TRUE(sameAsOctoMap(tree, rays, got));
  EXPECT_EQ(map.castRayInfo().builds, 1u);
  EXPECT_EQ(map.castRayInfo().occupied_boxes, 0u);
  std::mt19937 rng(3);
  std::uniform_real_distribution<float> u(-1.0f, 1.0f);
  for (int scan = 0; scan < 3; ++scan) {
    std::vector<Eigen::Vector3f> pts;
    for (int i = 0; i < 600; ++i) {
      Eigen::Vector3f d(u(rng), u(rng), 0.5f * u(rng));
      if (d.norm() < 1e-3f) continue;
      pts.push_back(origin + d.normalized() * (1.0f + 0.3f * static_cast<float>(scan)));
    }
    map.insertPointCloud(pts, origin);
    tree.insertPointCloud(test::toPointcloud(pts),
                          octomap::point3d(origin.x(), origin.y(), origin.z()));
    got = map.castRays(rays);
    EXPECT_TRUE(sameAsOctoMap(tree, rays, got)) << "after scan " << scan;
    const OccupancyMap::CastRayInfo info = map.castRayInfo();
    EXPECT_EQ(info.backend, path);
    EXPECT_EQ(info.builds, static_cast<std::size_t>(scan) + 2);
    std::size_t occupied = 0;
    for (auto it = tree.begin_leafs(), end = tree.end_leafs(); it != end; ++it)
      occupied += tree.isNodeOccupied(*it);
    EXPECT_EQ(info.occupied_boxes, occupied);
    EXPECT_GT(info.device_bytes, 0u);
    EXPECT_GE(info.last_build_ms, info.last_boxes_ms);
  }
  // No change: no rebuild.
  got = map.castRays(rays);
  EXPECT_EQ(map.castRayInfo().builds, 4u);
  // Reading the leaves changes nothing: no rebuild.
  EXPECT_GT(map.leafCount(), 0u);
  got = map.castRays(rays);
  EXPECT_EQ(map.castRayInfo().builds, 4u);
  // trim() drops the structure; the next castRays builds it again.
  map.trim();
  EXPECT_EQ(map.castRayInfo().device_bytes, 0u);
  got = map.castRays(rays);
  EXPECT_TRUE(sameAsOctoMap(tree, rays, got));
  EXPECT_EQ(map.castRayInfo().builds, 1u);  // counted since the last trim()
  // Another tree uploaded: the structure follows it.
  octomap::OcTree other(0.1);
  std::vector<Eigen::Vector3f> wall;
  for (int i = 0; i < 400; ++i)
    wall.emplace_back(0.8f, -1.0f + 0.005f * static_cast<float>(i), 0.05f);
  other.insertPointCloud(test::toPointcloud(wall),
                         octomap::point3d(origin.x(), origin.y(), origin.z()));
  fromOcTree(map, other);
  got = map.castRays(rays);
  EXPECT_TRUE(sameAsOctoMap(other, rays, got)) << "after an upload";
  EXPECT_EQ(map.castRayInfo().builds, 2u);
}

// Rays in a caller's buffer (castRaysOnDevice): the host does not see them, so both passes run
// over the whole batch, each skipping the other kind of ray; the answers are OctoMap's.
TEST_P(RayTracingBackend, RaysInACallersBufferEqualOctoMap) {
  OCTOVK_REQUIRE_CONTEXT(ctx);
  const CastRayBackend path = GetParam();
  OCTOVK_REQUIRE_TRACE_PATH(ctx, path);
  Built b = buildMap(ctx, 0.1, 7, path);
  std::mt19937 rng(77);
  const std::vector<Ray> rays = randomRays(rng, 0.1, 600);
  const auto n = static_cast<std::uint32_t>(rays.size());
  const VulkanHandles vk = vulkanHandles(ctx);
  ASSERT_NE(vk.device, VK_NULL_HANDLE);
  test::CallerBuffer ray_buf(vk, n * sizeof(gpu::RayQuery)), hit_buf(vk, castRaysResultBytes(n));
  auto* queries = static_cast<gpu::RayQuery*>(ray_buf.data());
  for (std::uint32_t i = 0; i < n; ++i) {
    const Ray& r = rays[i];
    queries[i] = gpu::RayQuery{r.max_range_m,
                               r.origin.x(),
                               r.origin.y(),
                               r.origin.z(),
                               r.direction.x(),
                               r.direction.y(),
                               r.direction.z(),
                               r.ignore_unknown ? 1u : 0u,
                               0u};
  }
  castRaysOnDevice(*b.map, ray_buf.range(), n, hit_buf.range());
  EXPECT_EQ(b.map->castRayInfo().backend, path);
  const auto* results = static_cast<const gpu::RayResult*>(hit_buf.data());
  std::vector<RayHit> got(n);
  for (std::uint32_t i = 0; i < n; ++i)
    got[i] = {results[i].hit != 0,
              Eigen::Vector3f(results[i].end_x, results[i].end_y, results[i].end_z)};
  EXPECT_TRUE(sameAsOctoMap(b.oracle(), rays, got));
}

// kAuto and kRayTracing take ray queries where the device has them, else a ray-tracing pipeline;
// a device without either (or a Context that does not enable them) falls back to the walk under
// kAuto and refuses kRayTracing with the reason, as it refuses kRayQuery / kRayTracingPipeline
// where it lacks that one. A memory cap does not change the choice (the structure is checked
// against it at each build: RayTracingBackend.UnderAMemoryCap).
TEST(RayTracingChoice, RayQueriesFirstThenThePipelineElseTheWalk) {
  OCTOVK_REQUIRE_CONTEXT(ctx);
  ContextOptions options;
  options.enable_ray_query = false;
  auto plain = Context::create(options);
  ASSERT_TRUE(plain) << plain.error().what();
  Context& no_rt = *plain.value();
  EXPECT_FALSE(no_rt.device().ray_query_enabled);
  // What kAuto and kRayTracing take where the Context enables ray tracing.
  const auto traced = [](Context& c) {
    if (test::hasTracePath(c, CastRayBackend::kRayQuery)) return CastRayBackend::kRayQuery;
    if (test::hasTracePath(c, CastRayBackend::kRayTracingPipeline))
      return CastRayBackend::kRayTracingPipeline;
    return CastRayBackend::kWalk;
  };
  for (Context* c : {&ctx, &no_rt}) {
    const bool enabled = c != &no_rt;  // no_rt enables neither, whatever its device offers
    const CastRayBackend want = enabled ? traced(*c) : CastRayBackend::kWalk;
    for (const CastRayBackend asked :
         {CastRayBackend::kAuto, CastRayBackend::kRayTracing, CastRayBackend::kRayQuery,
          CastRayBackend::kRayTracingPipeline}) {
      MapParams params;
      params.resolution = 0.1;
      params.cast_ray_backend = asked;
      CastRayBackend expected = want;
      if (asked == CastRayBackend::kRayQuery || asked == CastRayBackend::kRayTracingPipeline)
        expected = enabled && test::hasTracePath(*c, asked) ? asked : CastRayBackend::kWalk;
      if (asked == CastRayBackend::kAuto || expected != CastRayBackend::kWalk) {
        EXPECT_EQ(OccupancyMap(*c, params).castRayInfo().backend, expected)
            << c->device().name << ", asked " << tracePathName(asked);
        continue;
      }
      try {
        OccupancyMap refused(*c, params);
        ADD_FAILURE() << tracePathName(asked) << " accepted on " << c->device().name;
      } catch (const Error& e) {
        EXPECT_EQ(e.code(), ErrorCode::kMissingFeature);
        const std::string what = e.what();
        EXPECT_NE(what.find("kWalk"), std::string::npos) << what;
        // The path asked for by name; for kRayTracing, ray queries where the device offers them,
        // else the pipelines it offers (NVIDIA's GPUs have only those).
        const char* path = "ray queries";
        if (asked == CastRayBackend::kRayTracingPipeline ||
            (asked == CastRayBackend::kRayTracing && !c->device().ray_query &&
             c->device().ray_tracing_pipeline))
          path = "ray-tracing pipelines";
        EXPECT_NE(what.find(path), std::string::npos) << what;
      }
    }
  }
  MapParams params;
  params.resolution = 0.1;
  params.max_device_bytes = 64u << 20;
  EXPECT_EQ(OccupancyMap(ctx, params).castRayInfo().backend, traced(ctx));
}

// Under MapParams::max_device_bytes the acceleration structure counts with the query buffers:
// where it fits, castRays traces and the map stays within the cap; where it does not, kAuto
// answers with the walk (the same answers, counted in cap_fallbacks) and a forced path throws
// kOutOfDeviceMemory naming the cap, with the map unchanged. A scan releases the structure first,
// so its growth never loses room to it. Caps are derived from what uncapped maps measure.
TEST_P(RayTracingBackend, UnderAMemoryCap) {
  OCTOVK_REQUIRE_CONTEXT(ctx);
  const CastRayBackend path = GetParam();
  OCTOVK_REQUIRE_TRACE_PATH(ctx, path);
  const Eigen::Vector3f origin(0.0f, 0.0f, 0.05f);
  std::mt19937 rng(41);
  const auto scan = test::randomScan(rng, origin, 3000, 2.0f);
  const auto more = test::randomScan(rng, origin, 3000, 2.5f);
  std::vector<Ray> rays;
  for (const auto& d : sphereDirections(24)) {
    rays.push_back({origin, d, -1.0, false});
    rays.push_back({origin, d, 3.0, true});
  }
  MapParams params;
  params.resolution = 0.1;
  // What the map holds after the scans and one castRays call, with each backend.
  std::size_t walk_bytes = 0, rt_bytes = 0;
  for (const CastRayBackend backend : {CastRayBackend::kWalk, path}) {
    MapParams p = params;
    p.cast_ray_backend = backend;
    OccupancyMap probe(ctx, p);
    probe.insertPointCloud(scan, origin);
    probe.insertPointCloud(more, origin);
    (void)probe.castRays(rays);
    (backend == CastRayBackend::kWalk ? walk_bytes : rt_bytes) = probe.deviceBytes();
  }
  ASSERT_GT(rt_bytes, walk_bytes + (1u << 20)) << "the structure should take room";
  octomap::OcTree tree(0.1);
  tree.insertPointCloud(test::toPointcloud(scan), test::toPoint(origin));

  // Room for the structure: it is built, and counted.
  params.max_device_bytes = rt_bytes + (rt_bytes - walk_bytes);
  params.cast_ray_backend = path;
  {
    OccupancyMap map(ctx, params);
    map.insertPointCloud(scan, origin);
    EXPECT_TRUE(sameAsOctoMap(tree, rays, map.castRays(rays)));
    const OccupancyMap::CastRayInfo info = map.castRayInfo();
    EXPECT_EQ(info.builds, 1u);
    EXPECT_EQ(info.cap_fallbacks, 0u);
    EXPECT_GT(info.device_bytes, 0u);
    EXPECT_LE(map.deviceBytes(), params.max_device_bytes);
    EXPECT_EQ(map.deviceBytesByUse().total(), map.deviceBytes());
    // A scan drops it; the next castRays builds it again.
    map.insertPointCloud(more, origin);
    EXPECT_EQ(map.castRayInfo().device_bytes, 0u);
    octomap::OcTree both = tree;
    both.insertPointCloud(test::toPointcloud(more), test::toPoint(origin));
    EXPECT_TRUE(sameAsOctoMap(both, rays, map.castRays(rays)));
    EXPECT_EQ(map.castRayInfo().builds, 1u);  // a fresh scene counts from one
    EXPECT_LE(map.deviceBytes(), params.max_device_bytes);
  }

  // No room for it: kAuto answers with the walk, the path forced refuses and keeps the map.
  params.max_device_bytes = walk_bytes + (rt_bytes - walk_bytes) / 8;
  params.cast_ray_backend = CastRayBackend::kAuto;
  {
    OccupancyMap map(ctx, params);
    map.insertPointCloud(scan, origin);
    EXPECT_TRUE(sameAsOctoMap(tree, rays, map.castRays(rays)));
    const OccupancyMap::CastRayInfo info = map.castRayInfo();
    EXPECT_EQ(info.cap_fallbacks, 1u);
    EXPECT_EQ(info.builds, 0u);
    EXPECT_EQ(info.device_bytes, 0u);
    EXPECT_LE(map.deviceBytes(), params.max_device_bytes);
  }
  params.cast_ray_backend = path;
  {
    OccupancyMap map(ctx, params);
    map.insertPointCloud(scan, origin);
    const std::size_t nodes = map.nodeCount();
    try {
      (void)map.castRays(rays);
      ADD_FAILURE() << "a structure beyond max_device_bytes was built";
    } catch (const Error& e) {
      EXPECT_EQ(e.code(), ErrorCode::kOutOfDeviceMemory);
      const std::string what = e.what();
      for (const char* part : {"max_device_bytes", "acceleration structure", "unchanged", "kAuto"})
        EXPECT_NE(what.find(part), std::string::npos) << what;
    }
    EXPECT_EQ(map.nodeCount(), nodes);
    EXPECT_EQ(map.castRayInfo().device_bytes, 0u);
    EXPECT_LE(map.deviceBytes(), params.max_device_bytes);
    EXPECT_TRUE(test::sameTree(tree, *toOcTree(map)));
    // The map keeps working: the next scan goes in.
    map.insertPointCloud(more, origin);
    EXPECT_GT(map.nodeCount(), 0u);
  }
}

INSTANTIATE_TEST_SUITE_P(Backends, RayCastingScenarios, kBackends,
                         [](const auto& info) { return std::string(tracePathName(info.param)); });
INSTANTIATE_TEST_SUITE_P(Paths, RayTracingBackend, kTracePaths,
                         [](const auto& info) { return std::string(tracePathName(info.param)); });

INSTANTIATE_TEST_SUITE_P(Maps, Queries,
                         ::testing::Values(std::make_tuple(0.1, 1u), std::make_tuple(0.05, 2u),
                                           std::make_tuple(0.2, 3u)));

}  // namespace
}  // namespace octovk
