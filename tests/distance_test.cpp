// The distance field (octovk/distance.hpp) against the brute-force minimum over every occupied
// cell, cell for cell, and against dynamicEDT3D's DynamicEDTOctomap (Debian's
// libdynamicedt3d-dev) on the same maps; queries, updates after scans, bad input, the cap.
#include "octovk/distance.hpp"

#include <dynamicEDT3D/dynamicEDTOctomap.h>
#include <octomap/octomap.h>

#include <chrono>
#include <cmath>
#include <cstdlib>
#include <cstring>
#include <limits>
#include <optional>
#include <random>
#include <regex>
#include <thread>

#include "caller_buffer.hpp"
#include "octovk/vulkan_interop.hpp"
#include "test_support.hpp"
#include "vk/fault_injection.hpp"

namespace octovk {
namespace {

using test::toPoint;

constexpr std::uint32_t kNone = DistanceSample::kNoObstacleCells;

struct Box {
  Eigen::Vector3f min, max;
};

/// The box's cells as DynamicEDTOctomap numbers them, and which are obstacles in `tree`.
struct BruteField {
  std::array<std::uint32_t, 3> min_key{}, size{};
  std::vector<std::uint32_t> squared;  // brute-force minimum, kNone without obstacles
  std::vector<char> occupied;
};

BruteField bruteForce(const octomap::OcTree& tree, const Box& box, bool unknown_occupied) {
  BruteField b;
  const octomap::OcTreeKey lo = tree.coordToKey(toPoint(box.min));
  const octomap::OcTreeKey hi = tree.coordToKey(toPoint(box.max));
  for (int a = 0; a < 3; ++a) {
    b.min_key[a] = lo[a];
    b.size[a] = static_cast<std::uint32_t>(hi[a] - lo[a] + 1);
  }
  const std::size_t n = std::size_t{b.size[0]} * b.size[1] * b.size[2];
  b.occupied.assign(n, 0);
  std::vector<std::array<int, 3>> sites;
  for (std::uint32_t z = 0; z < b.size[2]; ++z)
    for (std::uint32_t y = 0; y < b.size[1]; ++y)
      for (std::uint32_t x = 0; x < b.size[0]; ++x) {
        const octomap::OcTreeKey k(static_cast<std::uint16_t>(lo[0] + x),
                                   static_cast<std::uint16_t>(lo[1] + y),
                                   static_cast<std::uint16_t>(lo[2] + z));
        const octomap::OcTreeNode* node = tree.search(k);
        const bool occ = node ? tree.isNodeOccupied(node) : unknown_occupied;
        if (occ) {
          b.occupied[x + b.size[0] * (y + std::size_t{b.size[1]} * z)] = 1;
          sites.push_back({int(x), int(y), int(z)});
        }
      }
  b.squared.assign(n, kNone);
  for (std::uint32_t z = 0; z < b.size[2]; ++z)
    for (std::uint32_t y = 0; y < b.size[1]; ++y)
      for (std::uint32_t x = 0; x < b.size[0]; ++x) {
        std::uint32_t best = kNone;
        for (const auto& s : sites) {
          const int dx = s[0] - int(x), dy = s[1] - int(y), dz = s[2] - int(z);
          best = std::min(best, static_cast<std::uint32_t>(dx * dx + dy * dy + dz * dz));
        }
        b.squared[x + b.size[0] * (y + std::size_t{b.size[1]} * z)] = best;
      }
  return b;
}

/// The field equals the brute force cell for cell, and each nearest cell is an obstacle at
/// that squared distance.
::testing::AssertionResult sameAsBruteForce(const DistanceField::Grid& g, const BruteField& b) {
  if (g.size != b.size || g.min_key != b.min_key)
    return ::testing::AssertionFailure()
           << "box differs: " << g.size[0] << "x" << g.size[1] << "x" << g.size[2] << " vs "
           << b.size[0] << "x" << b.size[1] << "x" << b.size[2];
  for (std::size_t i = 0; i < b.squared.size(); ++i) {
    if (g.squared_cells[i] != b.squared[i])
      return ::testing::AssertionFailure()
             << "cell " << i << ": squared distance " << g.squared_cells[i] << ", brute force "
             << b.squared[i];
    if (b.squared[i] == kNone) {
      if (g.nearest[i] != kNone)
        return ::testing::AssertionFailure()
               << "cell " << i << " names an obstacle in an empty box";
      continue;
    }
    const std::uint32_t s = g.nearest[i];
    if (s >= b.squared.size() || !b.occupied[s])
      return ::testing::AssertionFailure()
             << "cell " << i << ": nearest cell " << s << " is not an obstacle";
    const auto coord = [&](std::size_t c) {
      return std::array<long, 3>{long(c % b.size[0]), long((c / b.size[0]) % b.size[1]),
                                 long(c / (std::size_t{b.size[0]} * b.size[1]))};
    };
    const auto p = coord(i), q = coord(s);
    const long d2 = (p[0] - q[0]) * (p[0] - q[0]) + (p[1] - q[1]) * (p[1] - q[1]) +
                    (p[2] - q[2]) * (p[2] - q[2]);
    if (d2 != long(b.squared[i]))
      return ::testing::AssertionFailure() << "cell " << i << ": nearest cell " << s << " is at "
                                           << d2 << ", not " << b.squared[i];
  }
  return ::testing::AssertionSuccess();
}

/// Builds the octovk map from `tree`, the field over `box`, and checks it against brute force.
::testing::AssertionResult fieldMatches(Context& ctx, const octomap::OcTree& tree, const Box& box,
                                        bool unknown_occupied) {
  MapParams params = test::withResolution(tree.getResolution());
  OccupancyMap map(ctx, params);
  fromOcTree(map, tree);
  DistanceField field(map, box.min, box.max,
                      {.max_distance_m = 1.0f, .treat_unknown_as_occupied = unknown_occupied});
  return sameAsBruteForce(field.download(), bruteForce(tree, box, unknown_occupied));
}

octomap::OcTree randomTree(double resolution, unsigned seed, int scans) {
  octomap::OcTree tree(resolution);
  std::mt19937 rng(seed);
  std::uniform_real_distribution<float> u(-0.5f, 0.5f);
  for (int s = 0; s < scans; ++s) {
    const Eigen::Vector3f origin(u(rng), u(rng), u(rng));
    tree.insertPointCloud(test::toPointcloud(test::randomScan(rng, origin, 300, 1.6f)),
                          toPoint(origin));
  }
  return tree;
}

const Box kSmallBox{{-1.0f, -1.2f, -0.6f}, {1.3f, 1.0f, 0.7f}};

TEST(DistanceField, RandomMapsEqualBruteForceUnknownOffAndOn) {
  OCTOVK_REQUIRE_CONTEXT(ctx);
  for (unsigned seed : {1u, 2u, 3u}) {
    const octomap::OcTree tree = randomTree(0.1, seed, 3);
    EXPECT_TRUE(fieldMatches(ctx, tree, kSmallBox, false)) << "seed " << seed;
    EXPECT_TRUE(fieldMatches(ctx, tree, kSmallBox, true)) << "seed " << seed << ", unknown on";
  }
}

TEST(DistanceField, OneObstacleEmptyBoxAndObstaclesOnlyOutside) {
  OCTOVK_REQUIRE_CONTEXT(ctx);
  octomap::OcTree tree(0.1);
  tree.updateNode(octomap::point3d(0.05f, 0.05f, 0.05f), true);
  // One obstacle in the box.
  EXPECT_TRUE(fieldMatches(ctx, tree, {{-0.8f, -0.5f, -0.4f}, {0.9f, 0.6f, 0.5f}}, false));
  // A box without obstacles: every cell has none.
  octomap::OcTree empty(0.1);
  {
    OccupancyMap map(ctx, test::withResolution(0.1));
    DistanceField field(map, {-0.5f, -0.5f, -0.5f}, {0.5f, 0.5f, 0.5f},
                        {.treat_unknown_as_occupied = false});
    const DistanceField::Grid g = field.download();
    EXPECT_EQ(g.squared_cells, std::vector<std::uint32_t>(g.squared_cells.size(), kNone));
    const auto s = field.distances(std::vector<Eigen::Vector3f>{{0.0f, 0.0f, 0.0f}});
    EXPECT_EQ(s[0].squared_cells, kNone);
    EXPECT_EQ(s[0].distance_m, field.options().max_distance_m);
    EXPECT_TRUE(std::isnan(s[0].obstacle.x()));
  }
  // The obstacle lies outside the box: it does not count (as in DynamicEDTOctomap).
  const Box outside{{0.3f, 0.3f, 0.3f}, {1.0f, 0.9f, 0.8f}};
  EXPECT_TRUE(fieldMatches(ctx, tree, outside, false));
  EXPECT_EQ(bruteForce(tree, outside, false).squared.front(), kNone);
}

TEST(DistanceField, PrunedLeavesCountAsEachOfTheirCells) {
  OCTOVK_REQUIRE_CONTEXT(ctx);
  octomap::OcTree tree(0.05);
  // An 8 x 8 x 8 cube of occupied cells, aligned to a depth-13 node: pruned to one leaf.
  for (int x = 0; x < 8; ++x)
    for (int y = 0; y < 8; ++y)
      for (int z = 0; z < 8; ++z)
        tree.updateNode(octomap::OcTreeKey(static_cast<octomap::key_type>(32768 + x),
                                           static_cast<octomap::key_type>(32768 + y),
                                           static_cast<octomap::key_type>(32768 + z)),
                        true, true);
  tree.updateInnerOccupancy();
  tree.prune();
  unsigned depth = 0;
  for (auto it = tree.begin_leafs(); it != tree.end_leafs(); ++it) depth = it.getDepth();
  ASSERT_EQ(depth, 13u) << "the cube should be one pruned leaf";
  // The box cuts the cube.
  EXPECT_TRUE(fieldMatches(ctx, tree, {{0.1f, -0.3f, 0.12f}, {0.9f, 0.3f, 0.6f}}, false));
  EXPECT_TRUE(fieldMatches(ctx, tree, {{0.1f, -0.3f, 0.12f}, {0.9f, 0.3f, 0.6f}}, true));
}

TEST(DistanceField, Geb079EqualsBruteForce) {
  OCTOVK_REQUIRE_CONTEXT(ctx);
  const std::string path = OCTOVK_PATH(OCTOVK_OCTOMAP_DATA_DIR) + "/geb079.bt";
  octomap::OcTree tree(0.1);
  ASSERT_TRUE(tree.readBinary(path)) << path;
  const Box box{{-2.0f, -1.5f, -0.3f}, {1.5f, 1.5f, 1.2f}};
  EXPECT_TRUE(fieldMatches(ctx, tree, box, false));
  EXPECT_TRUE(fieldMatches(ctx, tree, box, true));
}

TEST(DistanceField, ScanGraphMapEqualsBruteForce) {
  OCTOVK_REQUIRE_CONTEXT(ctx);
  const std::string path = OCTOVK_PATH(OCTOVK_OCTOMAP_DATA_DIR) + "/spherical_scan.graph";
  const std::vector<GraphScan> scans = readScanGraph(path);
  ASSERT_FALSE(scans.empty());
  OccupancyMap map(ctx, test::withResolution(0.1));
  for (const GraphScan& s : scans)
    map.insertPointCloud(s.points_sensor, graph2treeSensorOrigin(s.T_world_sensor),
                         s.T_world_sensor);
  const std::unique_ptr<octomap::OcTree> tree = toOcTree(map);
  const Box box{{-1.5f, -1.5f, -0.8f}, {1.5f, 1.2f, 0.8f}};
  DistanceField field(map, box.min, box.max, {.treat_unknown_as_occupied = false});
  EXPECT_TRUE(sameAsBruteForce(field.download(), bruteForce(*tree, box, false)));
}

// dynamicEDT3D on the same map and box: counts how many cells agree (squared distances, capped
// at its maxDist_squared) and checks, for every disagreement, that octovk's value is the brute
// force's (and so dynamicEDT3D's is not).
// `rule`: the unknown-space rule given to both; none: the field's default, and dynamicEDT3D told
// to treat unknown cells as occupied (the default must be that, the safe rule).
void compareWithDynamicEdt(Context& ctx, octomap::OcTree& tree, const Box& box,
                           std::optional<bool> rule, float max_distance, const char* name) {
  MapParams params = test::withResolution(tree.getResolution());
  OccupancyMap map(ctx, params);
  fromOcTree(map, tree);
  const bool unknown = rule.value_or(true);
  DistanceFieldOptions options{.max_distance_m = max_distance};
  if (rule) options.treat_unknown_as_occupied = *rule;
  DistanceField field(map, box.min, box.max, options);
  const DistanceField::Grid g = field.download();
  const BruteField b = bruteForce(tree, box, unknown);
  ASSERT_TRUE(sameAsBruteForce(g, b));
  DynamicEDTOctomap edt(max_distance, &tree, toPoint(box.min), toPoint(box.max), unknown);
  edt.update();
  const auto cap = static_cast<std::uint32_t>(edt.getSquaredMaxDistCells());
  std::size_t agree = 0, differ = 0, edt_too_far = 0;
  for (std::uint32_t z = 0; z < g.size[2]; ++z)
    for (std::uint32_t y = 0; y < g.size[1]; ++y)
      for (std::uint32_t x = 0; x < g.size[0]; ++x) {
        const std::size_t i = x + g.size[0] * (y + std::size_t{g.size[1]} * z);
        const octomap::point3d p =
            tree.keyToCoord(octomap::OcTreeKey(static_cast<std::uint16_t>(g.min_key[0] + x),
                                               static_cast<std::uint16_t>(g.min_key[1] + y),
                                               static_cast<std::uint16_t>(g.min_key[2] + z)));
        const auto theirs = static_cast<std::uint32_t>(edt.getSquaredDistanceInCells(p));
        const std::uint32_t ours = std::min(g.squared_cells[i], cap);
        if (theirs == ours) {
          ++agree;
          continue;
        }
        ++differ;
        // octovk's is the exact minimum (checked above); dynamicEDT3D's propagation found a
        // farther obstacle (never a nearer one: there is none).
        ASSERT_EQ(std::min(b.squared[i], cap), ours);
        ASSERT_GT(theirs, ours) << "dynamicEDT3D reports a nearer obstacle than exists at cell "
                                << i;
        ++edt_too_far;
      }
  std::cout << "[dynamicEDT3D] " << name << ": " << agree << " of " << (agree + differ)
            << " cells agree; " << differ << " differ, in each octovk's is the brute-force "
            << "minimum and dynamicEDT3D's larger (" << edt_too_far << ")\n";
  ::testing::Test::RecordProperty(std::string(name) + "_agree", static_cast<int>(agree));
  ::testing::Test::RecordProperty(std::string(name) + "_differ", static_cast<int>(differ));
  EXPECT_EQ(agree + differ, b.squared.size());
}

TEST(DistanceField, AgainstDynamicEdtOctomap) {
  OCTOVK_REQUIRE_CONTEXT(ctx);
  for (unsigned seed : {4u, 5u}) {
    octomap::OcTree tree = randomTree(0.1, seed, 3);
    compareWithDynamicEdt(ctx, tree, kSmallBox, false, 1.0f,
                          ("random" + std::to_string(seed)).c_str());
    compareWithDynamicEdt(ctx, tree, kSmallBox, true, 0.6f,
                          ("random" + std::to_string(seed) + "_unknown").c_str());
  }
  const std::string path = OCTOVK_PATH(OCTOVK_OCTOMAP_DATA_DIR) + "/geb079.bt";
  octomap::OcTree geb(0.1);
  ASSERT_TRUE(geb.readBinary(path)) << path;
  compareWithDynamicEdt(ctx, geb, {{-2.0f, -1.5f, -0.3f}, {1.5f, 1.5f, 1.2f}}, false, 2.0f,
                        "geb079");
  compareWithDynamicEdt(ctx, geb, {{-5.0f, -4.0f, -0.5f}, {3.0f, 3.0f, 1.5f}}, false, 6.0f,
                        "geb079_large");
}

// Issue 30.5: a field over space the map never saw must not read as clearance. By default unknown
// cells are obstacles (dynamicEDT3D's treatUnknownAsOccupied = true): the field equals
// dynamicEDT3D so told, and a cell no sensor saw reads 0; only the explicit rule reads it free.
TEST(DistanceField, UnknownSpaceIsAnObstacleByDefaultAsDynamicEdtTreatsIt) {
  OCTOVK_REQUIRE_CONTEXT(ctx);
  EXPECT_TRUE(DistanceFieldOptions{}.treat_unknown_as_occupied);
  octomap::OcTree tree = randomTree(0.1, 6, 2);
  const Box box{{-1.2f, -1.2f, -0.6f}, {1.4f, 1.1f, 0.9f}};
  compareWithDynamicEdt(ctx, tree, box, std::nullopt, 0.6f, "random6_default");
  // A cell of the box the map does not know, away from every known one.
  OccupancyMap map(ctx, test::withResolution(0.1));
  fromOcTree(map, tree);
  const Eigen::Vector3f unseen(1.35f, 1.05f, 0.85f);
  ASSERT_EQ(tree.search(toPoint(unseen)), nullptr) << "the test needs an unknown cell there";
  DistanceField safe(map, box.min, box.max, {.max_distance_m = 0.6f});
  DistanceField optimistic(map, box.min, box.max,
                           {.max_distance_m = 0.6f, .treat_unknown_as_occupied = false});
  const std::vector<Eigen::Vector3f> at{unseen};
  EXPECT_EQ(safe.distances(at)[0].distance_m, 0.0f);
  EXPECT_EQ(safe.distances(at)[0].squared_cells, 0u);
  EXPECT_GT(optimistic.distances(at)[0].distance_m, 0.0f);
  DynamicEDTOctomap edt(0.6f, &tree, toPoint(box.min), toPoint(box.max), true);
  edt.update();
  EXPECT_EQ(edt.getDistance(toPoint(unseen)), 0.0f);
}

// Issue 30.5: without a box the field covers the map's bounds (OctoMap's getMetricMin/Max: every
// leaf's cells) and one cell around them, whose unknown cells bound the distances at the edge.
TEST(DistanceField, DefaultBoxIsTheMapsBoundsAndOneCellAround) {
  OCTOVK_REQUIRE_CONTEXT(ctx);
  octomap::OcTree tree(0.1);
  std::mt19937 rng(12);
  const Eigen::Vector3f origin(0.2f, -0.1f, 0.05f);
  tree.insertPointCloud(test::toPointcloud(test::randomScan(rng, origin, 60, 0.6f)),
                        toPoint(origin));
  OccupancyMap map(ctx, test::withResolution(0.1));
  fromOcTree(map, tree);
  const DistanceField field(map, {.max_distance_m = 0.5f});
  double lo[3], hi[3];
  tree.getMetricMin(lo[0], lo[1], lo[2]);
  tree.getMetricMax(hi[0], hi[1], hi[2]);
  Box box;
  for (int a = 0; a < 3; ++a) {
    const std::uint32_t first = tree.coordToKey(lo[a] + 0.05) - 1u;
    const std::uint32_t last = tree.coordToKey(hi[a] - 0.05) + 1u;
    EXPECT_EQ(field.minKey()[a], first) << "axis " << a;
    EXPECT_EQ(field.size()[a], last - first + 1u) << "axis " << a;
    box.min[a] = static_cast<float>(tree.keyToCoord(static_cast<octomap::key_type>(first)));
    box.max[a] = static_cast<float>(tree.keyToCoord(static_cast<octomap::key_type>(last)));
  }
  EXPECT_TRUE(field.options().treat_unknown_as_occupied);
  const BruteField b = bruteForce(tree, box, true);
  EXPECT_TRUE(sameAsBruteForce(field.download(), b));
  // The ring around the bounds is unknown: every cell of the box's faces is an obstacle.
  EXPECT_EQ(b.occupied.front(), 1);
  EXPECT_EQ(b.occupied.back(), 1);
  OccupancyMap empty(ctx, test::withResolution(0.1));
  try {
    DistanceField f(empty);
    ADD_FAILURE() << "a field over the bounds of an empty map was built";
  } catch (const Error& e) {
    EXPECT_EQ(e.code(), ErrorCode::kInvalidArgument) << e.what();
    EXPECT_NE(std::string(e.what()).find("give a box"), std::string::npos) << e.what();
  }
}

TEST(DistanceField, UpdateAfterScansEqualsFromScratch) {
  OCTOVK_REQUIRE_CONTEXT(ctx);
  MapParams params = test::withResolution(0.1);
  OccupancyMap map(ctx, params);
  const DistanceFieldOptions options{.max_distance_m = 0.8f, .treat_unknown_as_occupied = false};
  DistanceField field(map, kSmallBox.min, kSmallBox.max, options);
  std::mt19937 rng(7);
  std::uniform_real_distribution<float> u(-0.4f, 0.4f);
  for (int s = 0; s < 4; ++s) {
    const Eigen::Vector3f origin(u(rng), u(rng), u(rng));
    map.insertPointCloud(test::randomScan(rng, origin, 250, 1.5f), origin);
    if (s % 2 == 1) map.submitPointCloud(test::randomScan(rng, origin, 100, 1.2f), origin);
    field.update();  // sees the submitted scan too
    DistanceField scratch(map, kSmallBox.min, kSmallBox.max, options);
    const DistanceField::Grid a = field.download(), b = scratch.download();
    EXPECT_EQ(a.squared_cells, b.squared_cells) << "after scan " << s;
    EXPECT_TRUE(sameAsBruteForce(a, bruteForce(*toOcTree(map), kSmallBox, false)));
  }
  EXPECT_GT(field.lastUpdateMs(), 0.0);
}

/// The field equals one built from scratch on the map as it is now, cell for cell (squared
/// distances and nearest cells: each line's answer is a function of its input, so an update
/// that redid only the changed lines leaves the same arrays as a build).
::testing::AssertionResult sameAsScratch(OccupancyMap& map, const DistanceField& field,
                                         const Box& box, const DistanceFieldOptions& options) {
  const DistanceField scratch(map, box.min, box.max, options);
  const DistanceField::Grid a = field.download(), b = scratch.download();
  if (a.squared_cells != b.squared_cells)
    return ::testing::AssertionFailure() << "squared distances differ from a fresh build";
  if (a.nearest != b.nearest)
    return ::testing::AssertionFailure() << "nearest cells differ from a fresh build";
  return ::testing::AssertionSuccess();
}

const char* kindName(DistanceField::UpdateKind kind) {
  switch (kind) {
    case DistanceField::UpdateKind::kBuild:
      return "build";
    case DistanceField::UpdateKind::kFromTree:
      return "from the tree";
    case DistanceField::UpdateKind::kFromChanges:
      return "from the change set";
  }
  return "?";
}

// Updates from the change set (small changes) and from the tree (large ones, clearBox, keepBox),
// with unknown counted as occupied or not: after each, equal to a fresh build and to brute force.
TEST(DistanceField, IncrementalUpdatesEqualFromScratch) {
  OCTOVK_REQUIRE_CONTEXT(ctx);
  using Kind = DistanceField::UpdateKind;
  for (const bool unknown : {false, true}) {
    SCOPED_TRACE(unknown ? "unknown occupied" : "unknown free");
    OccupancyMap map(ctx, test::withResolution(0.05));  // 46 x 44 x 26 cells: 2,288 words
    std::mt19937 rng(unknown ? 21 : 20);
    std::uniform_real_distribution<float> u(-0.4f, 0.4f);
    map.insertPointCloud(test::randomScan(rng, Eigen::Vector3f::Zero(), 400, 1.5f),
                         Eigen::Vector3f::Zero());
    const DistanceFieldOptions options{.max_distance_m = 0.8f,
                                       .treat_unknown_as_occupied = unknown};
    DistanceField field(map, kSmallBox.min, kSmallBox.max, options);
    EXPECT_EQ(field.lastUpdateKind(), Kind::kBuild);
    EXPECT_FALSE(map.isChangeDetectionEnabled());  // a field only built leaves the map alone
    field.update();                                // turns change detection on
    EXPECT_EQ(field.lastUpdateKind(), Kind::kFromTree);
    EXPECT_TRUE(map.isChangeDetectionEnabled());
    bool saw_changes = false, saw_tree = false;
    for (int s = 0; s < 8; ++s) {
      const Eigen::Vector3f origin(u(rng), u(rng), u(rng));
      // Small scans (a few short rays) and large ones, some submitted without waiting.
      const bool small = s % 3 != 2;
      const auto scan = test::randomScan(rng, origin, small ? 6 : 800, small ? 0.4f : 1.5f);
      if (s % 2 == 1)
        map.submitPointCloud(scan, origin);
      else
        map.insertPointCloud(scan, origin);
      field.update();
      SCOPED_TRACE(std::string("after scan ") + std::to_string(s) + ", an update " +
                   kindName(field.lastUpdateKind()));
      if (small) {
        EXPECT_EQ(field.lastUpdateKind(), Kind::kFromChanges);
      }
      saw_changes |= field.lastUpdateKind() == Kind::kFromChanges;
      saw_tree |= field.lastUpdateKind() == Kind::kFromTree;
      EXPECT_EQ(map.numChangesDetected(), 0u);  // the field turned it on: it empties the set
      EXPECT_TRUE(sameAsScratch(map, field, kSmallBox, options));
    }
    EXPECT_TRUE(saw_changes);
    EXPECT_TRUE(saw_tree);  // the large scans note more keys than reading the tree costs
    // clearBox is not in the change set: the next update reads the tree.
    map.clearBox({-0.3f, -0.3f, -0.3f}, {0.3f, 0.2f, 0.25f});
    field.update();
    EXPECT_EQ(field.lastUpdateKind(), Kind::kFromTree);
    EXPECT_TRUE(sameAsScratch(map, field, kSmallBox, options));
    EXPECT_TRUE(sameAsBruteForce(field.download(), bruteForce(*toOcTree(map), kSmallBox, unknown)));
    // keepBox deletes nodes, and deletions are not in the change set either.
    map.keepBox({-0.5f, -0.4f, -0.35f}, {0.25f, 0.3f, 0.2f});
    field.update();
    EXPECT_EQ(field.lastUpdateKind(), Kind::kFromTree);
    EXPECT_TRUE(sameAsScratch(map, field, kSmallBox, options));
    EXPECT_TRUE(sameAsBruteForce(field.download(), bruteForce(*toOcTree(map), kSmallBox, unknown)));
  }
}

// A user who reads the change set: the field never empties it; a key that flipped and flipped
// back after an update (gone from the set, still in its slot) is read again; the user's reset,
// and change detection turned off, make the next update read the tree. The last field to go
// leaves change detection as the user set it.
TEST(DistanceField, IncrementalUpdatesBesideAUserOfTheChangeSet) {
  OCTOVK_REQUIRE_CONTEXT(ctx);
  using Kind = DistanceField::UpdateKind;
  OccupancyMap map(ctx, test::withResolution(0.05));
  map.enableChangeDetection(true);
  std::mt19937 rng(30);
  map.insertPointCloud(test::randomScan(rng, Eigen::Vector3f::Zero(), 400, 1.5f),
                       Eigen::Vector3f::Zero());
  const DistanceFieldOptions options{.max_distance_m = 0.8f};
  {
    DistanceField field(map, kSmallBox.min, kSmallBox.max, options);
    const std::size_t noted = map.numChangesDetected();
    EXPECT_GT(noted, 0u);
    field.update();  // the set is the user's: left as it is
    EXPECT_EQ(map.numChangesDetected(), noted);
    map.resetChangeDetection();  // the user read it (or the set would outgrow the box's words)
    field.update();
    EXPECT_EQ(field.lastUpdateKind(), Kind::kFromTree);
    // One cell made occupied, then free again over later updates (each from the change set).
    const Eigen::Vector3f origin(0.02f, 0.03f, 0.01f), end(0.52f, 0.03f, 0.01f);
    const std::vector<Eigen::Vector3f> hit{end};
    for (int i = 0; i < 3; ++i) {
      map.insertPointCloud(hit, origin);
      field.update();
      EXPECT_EQ(field.lastUpdateKind(), Kind::kFromChanges);
      EXPECT_TRUE(sameAsScratch(map, field, kSmallBox, options)) << "hit " << i;
    }
    const std::vector<Eigen::Vector3f> beyond{Eigen::Vector3f(0.92f, 0.03f, 0.01f)};
    for (int i = 0; i < 8; ++i) {  // the ray through `end` clears it again, one update at a time
      map.insertPointCloud(beyond, origin);
      field.update();
      EXPECT_EQ(field.lastUpdateKind(), Kind::kFromChanges);
      EXPECT_TRUE(sameAsScratch(map, field, kSmallBox, options)) << "miss " << i;
    }
    map.resetChangeDetection();
    map.insertPointCloud(hit, origin);
    field.update();
    EXPECT_EQ(field.lastUpdateKind(), Kind::kFromTree);  // the user's reset dropped keys
    EXPECT_TRUE(sameAsScratch(map, field, kSmallBox, options));
    map.insertPointCloud(beyond, origin);
    field.update();
    EXPECT_EQ(field.lastUpdateKind(), Kind::kFromChanges);
    EXPECT_TRUE(sameAsScratch(map, field, kSmallBox, options));
    map.enableChangeDetection(false);
    map.insertPointCloud(hit, origin);
    field.update();
    EXPECT_EQ(field.lastUpdateKind(), Kind::kFromTree);  // scans no longer noted
    EXPECT_TRUE(sameAsScratch(map, field, kSmallBox, options));
    EXPECT_FALSE(map.isChangeDetectionEnabled());  // the user's choice stands
  }
  EXPECT_FALSE(map.isChangeDetectionEnabled());
  // A map whose fields turned change detection on gets it off again, memory included.
  OccupancyMap other(ctx, test::withResolution(0.05));
  const std::size_t before = other.deviceBytes();
  {
    DistanceField field(other, kSmallBox.min, kSmallBox.max, options);
    field.update();
    EXPECT_TRUE(other.isChangeDetectionEnabled());
  }
  EXPECT_FALSE(other.isChangeDetectionEnabled());
  EXPECT_EQ(other.deviceBytes(), before);
}

TEST(DistanceField, QueriesAnswerFromTheField) {
  OCTOVK_REQUIRE_CONTEXT(ctx);
  const octomap::OcTree tree = randomTree(0.1, 9, 3);
  OccupancyMap map(ctx, test::withResolution(0.1));
  fromOcTree(map, tree);
  const float max_d = 0.5f;
  DistanceField field(map, kSmallBox.min, kSmallBox.max,
                      {.max_distance_m = max_d, .treat_unknown_as_occupied = false});
  const DistanceField::Grid g = field.download();
  std::mt19937 rng(11);
  std::uniform_real_distribution<float> u(-1.6f, 1.6f), ur(0.0f, 0.3f);
  std::vector<Eigen::Vector4f> spheres;
  for (int i = 0; i < 5000; ++i) spheres.emplace_back(u(rng), u(rng), u(rng), ur(rng));
  spheres.emplace_back(std::numeric_limits<float>::quiet_NaN(), 0.0f, 0.0f, 0.0f);
  spheres.emplace_back(1e9f, 0.0f, 0.0f, 0.0f);
  const std::vector<DistanceSample> got = field.clearances(spheres);
  ASSERT_EQ(got.size(), spheres.size());
  std::size_t inside = 0, capped = 0, on_obstacle = 0;
  for (std::size_t i = 0; i < spheres.size(); ++i) {
    const Eigen::Vector4f& s = spheres[i];
    const DistanceSample& r = got[i];
    std::array<long, 3> c{};
    bool in = true;
    for (int a = 0; a < 3; ++a) {
      std::uint32_t k = 0;
      in = in && std::isfinite(s[a]) && std::abs(s[a]) < 1e6f;
      if (!in) break;
      k = tree.coordToKey(s[a]);
      c[a] = long(k) - long(g.min_key[a]);
      in = c[a] >= 0 && c[a] < long(g.size[a]);
    }
    if (!in) {
      EXPECT_FALSE(r.inside()) << i;
      EXPECT_EQ(r.distance_m, DistanceSample::kOutside);
      EXPECT_EQ(r.gradient, Eigen::Vector3f::Zero());
      continue;
    }
    ++inside;
    const std::size_t cell = c[0] + g.size[0] * (c[1] + std::size_t{g.size[1]} * c[2]);
    ASSERT_EQ(r.squared_cells, g.squared_cells[cell]) << i;
    if (r.squared_cells == kNone) continue;
    const double metres = std::sqrt(double(r.squared_cells)) * 0.1;
    const float d = std::min(static_cast<float>(metres), max_d);
    EXPECT_EQ(r.distance_m, d - s[3]) << i;
    const std::uint32_t o = g.nearest[cell];
    const std::array<long, 3> oc{long(o % g.size[0]), long((o / g.size[0]) % g.size[1]),
                                 long(o / (std::size_t{g.size[0]} * g.size[1]))};
    for (int a = 0; a < 3; ++a)
      EXPECT_EQ(r.obstacle[a], static_cast<float>(tree.keyToCoord(
                                   static_cast<octomap::key_type>(g.min_key[a] + oc[a]))));
    if (r.squared_cells == 0 || static_cast<float>(metres) >= max_d) {
      EXPECT_EQ(r.gradient, Eigen::Vector3f::Zero()) << i;
      ++(r.squared_cells == 0 ? on_obstacle : capped);
    } else {
      for (int a = 0; a < 3; ++a)
        EXPECT_EQ(r.gradient[a],
                  static_cast<float>(double(c[a] - oc[a]) / std::sqrt(double(r.squared_cells))));
      EXPECT_NEAR(r.gradient.norm(), 1.0f, 1e-5f);
    }
  }
  EXPECT_GT(inside, 1000u);
  EXPECT_GT(capped, 0u);
  EXPECT_GT(on_obstacle, 0u);
  // distances() is clearances() with radius 0.
  std::vector<Eigen::Vector3f> points;
  for (const auto& s : spheres) points.push_back(s.head<3>());
  const std::vector<DistanceSample> at = field.distances(points);
  for (std::size_t i = 0; i < points.size(); ++i) {
    if (got[i].inside() && got[i].squared_cells != kNone) {
      EXPECT_EQ(at[i].distance_m - spheres[i][3], got[i].distance_m) << i;
    }
  }
}

// distancesOnDevice between a caller's buffers: it waits for the caller's semaphore before it
// reads the spheres (a producer thread writes them, then signals), and signals the caller's
// timeline once the results are written, which a consumer's own submission waits for on the
// device; what the consumer copied equals the host API's answers, field for field.
TEST(DistanceField, DistancesOnDeviceWaitAndSignalAndEqualTheHostApi) {
  OCTOVK_REQUIRE_CONTEXT(ctx);
  const octomap::OcTree tree = randomTree(0.1, 13, 3);
  OccupancyMap map(ctx, test::withResolution(0.1));
  fromOcTree(map, tree);
  DistanceField field(map, kSmallBox.min, kSmallBox.max, {.max_distance_m = 0.6f});
  std::mt19937 rng(17);
  std::uniform_real_distribution<float> u(-1.5f, 1.5f), ur(0.0f, 0.2f);
  std::vector<Eigen::Vector4f> spheres;
  for (int i = 0; i < 777; ++i) spheres.emplace_back(u(rng), u(rng), u(rng), ur(rng));
  spheres.emplace_back(std::numeric_limits<float>::quiet_NaN(), 0.0f, 0.0f, 0.0f);
  const std::vector<DistanceSample> want = field.clearances(spheres);

  const VulkanHandles vk = vulkanHandles(ctx);
  // The producer's timeline and the consumer's, as a perception stack would have them. The
  // producer is a submission on the same device that writes the spheres, then signals 1; the
  // call waits for 1 on the device. (The scans' interop test shows the wait holds a call back
  // until a later host signal; here a host signal racing the blocked call trips the Khronos
  // validation layer of Debian bookworm, 1.3.239, which then reports
  // UNASSIGNED-VkSemaphore-state-timeout, "most likely a validation bug".)
  test::DeviceConsumer producer(ctx, vk), consumer(ctx, vk);
  const std::size_t in_bytes = spheres.size() * sizeof(Eigen::Vector4f);
  const std::size_t out_bytes = spheres.size() * sizeof(gpu::DistanceResult);
  test::CallerBuffer staged(vk, in_bytes), in(vk, in_bytes), out(vk, out_bytes),
      copy(vk, out_bytes);
  // `in` is outside every box until the producer's copy: a read before it answers kOutside.
  std::vector<float> far(spheres.size() * 4, 1e9f);
  std::memcpy(in.data(), far.data(), in_bytes);
  std::memcpy(staged.data(), spheres.data(), in_bytes);
  std::memset(out.data(), 0, out_bytes);
  std::memset(copy.data(), 0, out_bytes);
  producer.produceThenSignal(staged, in, in_bytes, 1);
  distancesOnDevice(field, in.range(), static_cast<std::uint32_t>(spheres.size()), out.range(),
                    WaitSemaphore{producer.timeline(), 1}, SignalSemaphore{consumer.timeline(), 2});
  producer.finishProducer();
  consumer.copyAfter(out, copy, out_bytes, 2);
  const auto* got = static_cast<const gpu::DistanceResult*>(copy.data());
  std::size_t inside = 0, with_gradient = 0;
  for (std::size_t i = 0; i < spheres.size(); ++i) {
    const DistanceSample& w = want[i];
    ASSERT_EQ(got[i].squared_cells, w.squared_cells) << i;
    EXPECT_EQ(got[i].distance, w.distance_m) << i;
    const Eigen::Vector3f obstacle(got[i].obstacle_x, got[i].obstacle_y, got[i].obstacle_z);
    const Eigen::Vector3f gradient(got[i].gradient_x, got[i].gradient_y, got[i].gradient_z);
    for (int a = 0; a < 3; ++a) {
      if (std::isnan(w.obstacle[a]))
        EXPECT_TRUE(std::isnan(obstacle[a])) << i;
      else
        EXPECT_EQ(obstacle[a], w.obstacle[a]) << i;
    }
    EXPECT_EQ(gradient, w.gradient) << i;
    inside += w.inside();
    with_gradient += !gradient.isZero();
  }
  EXPECT_GT(inside, 150u);  // the box is about a quarter of the points' cube
  EXPECT_GT(with_gradient, 50u);
  EXPECT_FALSE(want.back().inside());

  // A batch of none still signals the value the caller waits for.
  distancesOnDevice(field, in.range(), 0, out.range(), {}, SignalSemaphore{consumer.timeline(), 3});
  consumer.copyAfter(out, copy, out_bytes, 3);
  // A misaligned offset is refused before anything is submitted.
  if (vk.offset_alignment > 1) {
    BufferRange misaligned = in.range();
    misaligned.offset = 4;
    EXPECT_THROW(distancesOnDevice(field, misaligned, 1, out.range()), Error);
  }
}

TEST(DistanceField, BadInputIsRefusedAndNothingChanges) {
  OCTOVK_REQUIRE_CONTEXT(ctx);
  OccupancyMap map(ctx, test::withResolution(0.1));
  const std::size_t before = map.deviceBytes();
  const auto refused = [&](const Eigen::Vector3f& lo, const Eigen::Vector3f& hi,
                           DistanceFieldOptions o, const char* words) {
    try {
      DistanceField f(map, lo, hi, o);
      ADD_FAILURE() << "accepted: " << words;
    } catch (const Error& e) {
      EXPECT_EQ(e.code(), ErrorCode::kInvalidArgument) << e.what();
      EXPECT_NE(std::string(e.what()).find(words), std::string::npos) << e.what();
    }
    EXPECT_EQ(map.deviceBytes(), before);
  };
  const float nan = std::numeric_limits<float>::quiet_NaN();
  refused({1, 0, 0}, {0, 1, 1}, {}, "inverted along x");
  refused({0, 0, 0}, {1, 1, nan}, {}, "NaN");
  refused({0, 0, 0}, {1, 1, 1}, {.max_distance_m = 0.0f}, "max_distance_m");
  refused({0, 0, 0}, {1, 1, 1}, {.max_distance_m = nan}, "max_distance_m");
  refused({0, 0, 0}, {4000, 1, 1}, {}, "key range");
  EXPECT_EQ(map.deviceBytesByUse().distance_fields, 0u);
}

::testing::AssertionResult inUsersWords(const Error& e, std::vector<std::string> mentions);

TEST(DistanceField, CountsUnderTheMapsCapAndTooLargeIsRefused) {
  OCTOVK_REQUIRE_CONTEXT(ctx);
  MapParams params = test::withResolution(0.1);
  params.max_device_bytes = MapParams{}.minDeviceBytes() + (std::size_t{1} << 20);
  OccupancyMap map(ctx, params);
  const std::size_t before = map.deviceBytes();
  {
    DistanceField small(map, {0, 0, 0}, {1.5f, 1.5f, 1.5f});
    EXPECT_EQ(map.deviceBytesByUse().distance_fields, small.deviceBytes());
    EXPECT_EQ(map.deviceBytes(), before + small.deviceBytes());
    (void)small.distances(std::vector<Eigen::Vector3f>{{0.5f, 0.5f, 0.5f}});
    EXPECT_EQ(map.deviceBytes(), before + small.deviceBytes());
  }
  EXPECT_EQ(map.deviceBytes(), before);
  try {
    DistanceField big(map, {0, 0, 0}, {6.0f, 6.0f, 6.0f});  // 61^3 cells, 20 B each: 4.5 MB
    ADD_FAILURE() << "a field beyond the cap was built";
  } catch (const Error& e) {
    EXPECT_EQ(e.code(), ErrorCode::kOutOfDeviceMemory) << e.what();
    EXPECT_TRUE(inUsersWords(e, {"61 x 61 x 61 cells", "needs 4.4 MiB", "Shrink the box",
                                 "raise MapParams::max_device_bytes"}));
  }
  EXPECT_EQ(map.deviceBytes(), before);
  EXPECT_EQ(map.deviceBytesByUse().distance_fields, 0u);
}

// Issue 30.4: an out-of-memory names what was asked, what it needs and what to change (the box,
// the cap), with or without a cap; never a Vulkan call or a source path (those are in detail()).
::testing::AssertionResult inUsersWords(const Error& e, std::vector<std::string> mentions) {
  const std::string what = e.what();
  if (std::regex_search(what, std::regex("vk[A-Z]")) || what.find("src/") != std::string::npos ||
      what.find(".cpp") != std::string::npos)
    return ::testing::AssertionFailure() << "a Vulkan call or source path: " << what;
  if (what.find("split the scan") != std::string::npos)
    return ::testing::AssertionFailure() << "a scan's advice for a field: " << what;
  for (const std::string& m : mentions)
    if (what.find(m) == std::string::npos)
      return ::testing::AssertionFailure() << "'" << m << "' not in: " << what;
  return ::testing::AssertionSuccess();
}

TEST(DistanceField, OutOfDeviceMemorySaysTheBoxTheBytesAndWhatToChange) {
  OCTOVK_REQUIRE_CONTEXT(ctx);
  unsetenv("OCTOVK_DEBUG");  // the words a user reads (the test sets it at the end)
  OccupancyMap map(ctx, test::withResolution(0.1));
  map.insertPointCloud(std::vector<Eigen::Vector3f>{{0.5f, 0.2f, 0.1f}}, Eigen::Vector3f::Zero());
  const std::size_t before = map.deviceBytes();
  // More than the device has: refused before anything is allocated (lavapipe reports 2 GiB: the
  // box is 200 m square; a device that holds the largest field a box may have cannot refuse one).
  if (const int h = test::fieldHalfSideBeyondDevice(ctx); h > 0) {
    const auto f = static_cast<float>(h);
    try {
      DistanceField huge(map, {-f, -f, -10}, {f, f, 10});
      ADD_FAILURE() << "a field of " << test::fieldBoxCells(h) << " was built";
    } catch (const Error& e) {
      EXPECT_EQ(e.code(), ErrorCode::kOutOfDeviceMemory) << e.what();
      EXPECT_TRUE(inUsersWords(e, {test::fieldBoxCells(h), "GiB", "the device has",
                                   "Shrink the box", "MapParams::max_device_bytes is not set"}));
    }
  } else {
    std::printf("[ field    ] the device's %.1f GiB hold the largest field: no box exceeds them\n",
                static_cast<double>(ctx.device().memory_bytes) / (1u << 30));
  }
  EXPECT_EQ(map.deviceBytes(), before);
  // Each allocation of a build, of the query buffers and of a download failing as a driver out of
  // memory does: the user's words, the driver's call in detail(), the map as it was.
  std::size_t failed = 0;
  for (std::uint64_t n = 1; n < 64; ++n) {
    vk::fault::failDeviceAllocation(n);
    try {
      DistanceField f(map, {-0.5f, -0.5f, -0.5f}, {0.5f, 0.5f, 0.5f});
      (void)f.distances(std::vector<Eigen::Vector3f>(100, Eigen::Vector3f::Zero()));
      (void)f.download();
      const bool ran_whole = vk::fault::deviceAllocations() < n;
      vk::fault::failDeviceAllocation(0);
      if (ran_whole) break;
    } catch (const Error& e) {
      vk::fault::failDeviceAllocation(0);
      ++failed;
      EXPECT_EQ(e.code(), ErrorCode::kOutOfDeviceMemory) << e.what();
      EXPECT_NE(e.detail().find("VK_ERROR_OUT_OF_DEVICE_MEMORY"), std::string::npos) << e.detail();
      const std::string what = e.what();
      if (what.find("queries") != std::string::npos)
        EXPECT_TRUE(inUsersWords(e, {"100 queries", "Query fewer points"}));
      else if (what.find("download") != std::string::npos)
        EXPECT_TRUE(inUsersWords(e, {"11 x 11 x 11 cells", "distances()", "shrink the box"}));
      else
        EXPECT_TRUE(inUsersWords(e, {"11 x 11 x 11 cells", "needs", "could not allocate",
                                     "Shrink the box", "max_device_bytes"}));
    }
    EXPECT_EQ(map.deviceBytes(), before) << "allocation " << n;
  }
  EXPECT_GE(failed, 10u);  // every buffer of the build, the four query buffers, the download
  // A developer who sets OCTOVK_DEBUG gets the driver's call and the source place in what() too.
  ASSERT_EQ(setenv("OCTOVK_DEBUG", "1", 1), 0);
  vk::fault::failDeviceAllocation(1);
  try {
    DistanceField f(map, {-0.5f, -0.5f, -0.5f}, {0.5f, 0.5f, 0.5f});
    ADD_FAILURE() << "the first allocation was to fail";
  } catch (const Error& e) {
    const std::string what = e.what();
    EXPECT_NE(what.find("Shrink the box"), std::string::npos) << what;
    EXPECT_NE(what.find("VK_ERROR_OUT_OF_DEVICE_MEMORY"), std::string::npos) << what;
    EXPECT_NE(what.find("buffer.cpp"), std::string::npos) << what;
    EXPECT_EQ(e.message().find("VK_ERROR"), std::string::npos) << e.message();
  }
  vk::fault::failDeviceAllocation(0);
  unsetenv("OCTOVK_DEBUG");
}

// A query batch whose buffers the cap has no room for runs in smaller batches (it was refused,
// with the advice to split "the scan or the query batch").
TEST(DistanceField, QueriesUnderATightCapRunInSmallerBatches) {
  OCTOVK_REQUIRE_CONTEXT(ctx);
  const octomap::OcTree tree = randomTree(0.1, 9, 1);
  MapParams params = test::withResolution(0.1);
  params.max_device_bytes = MapParams{}.minDeviceBytes() + (std::size_t{1} << 20);
  OccupancyMap map(ctx, params);
  fromOcTree(map, tree);
  DistanceField field(map, kSmallBox.min, kSmallBox.max);
  std::mt19937 rng(3);
  std::uniform_real_distribution<float> u(-1.0f, 1.0f);
  std::vector<Eigen::Vector3f> points(30000);  // 96 bytes each with staging: 2.7 MiB at once
  for (auto& p : points) p = Eigen::Vector3f(u(rng), u(rng), u(rng));
  const std::vector<DistanceSample> all = field.distances(points);
  ASSERT_EQ(all.size(), points.size());
  EXPECT_LE(map.deviceBytes(), params.max_device_bytes);
  for (std::size_t i = 0; i < points.size(); i += 997) {
    const DistanceSample one = field.distances(std::span(&points[i], 1))[0];
    EXPECT_EQ(one.squared_cells, all[i].squared_cells) << i;
    EXPECT_EQ(one.distance_m, all[i].distance_m) << i;
  }
}

}  // namespace
}  // namespace octovk
