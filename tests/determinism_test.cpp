// Determinism and stress (issue 8, item 6): inputs that would expose a race or an order
// dependence between invocations on a real GPU.
//
// - Determinism*: the same scans into two fresh maps give the same device state, and a scan's
//   points in any order give the same map (and OctoMap's).
// - Stress*: many rays or points on very few cells or bricks, one scan that outgrows every
//   per-scan set and the node pool at once, and long scan sequences from moving origins, each
//   compared with OctoMap node by node (log-odds bits included) after every scan.
#include <octomap/octomap.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdint>
#include <limits>
#include <ostream>
#include <string>

#include "test_support.hpp"

namespace octovk {
namespace {

using test::floatBits;

// Leaves above the finest depth: pruned groups of 8 equal cells.
std::size_t prunedLeaves(const octomap::OcTree& tree) {
  std::size_t pruned = 0;
  for (auto it = tree.begin_leafs(), end = tree.end_leafs(); it != end; ++it)
    if (it.getDepth() < 16) ++pruned;
  return pruned;
}
using test::insertBoth;
using test::LeafTuple;
using test::makeOracle;
using test::sameTree;
using test::withResolution;

// ---- everything the public API shows of a map ---------------------------------------------------
//
// Compared between two maps that got the same scans:
// - toOcTree(): the .ot bytes (OcTree::write: every node, log-odds bits) and the .bt bytes
//   (writeBinaryConst), and the files writeMapFile() writes (.ot, and .bt = OctoMap's
//   writeBinary: max-likelihood, pruned);
// - nodeCount(), leafCount(), deviceBytes(), poolBytes() (the buffer sizes follow from how the
//   sets and the pool grew, which must not depend on scheduling);
// - the leaf boxes of downloadLeafBoxes() and of leavesInBox() (all, and occupied only), as
//   sorted multisets of (centre, size, log-odds) bits;
// - download() (the raw node pool): root flag, number of pool slots in use (bump pointer * 8),
//   and the tree that hangs from the root walked depth first in child order - each node's
//   log-odds bits and child mask - with the number of blocks it reaches;
// - search() on a set of probe points and castRays() on a set of probe rays (every field);
// - each scan's ScanStats: points, skipped counts, free / occupied / aborted cells, nodes and
//   cell-set attempts.
// Not compared:
// - the raw pool bytes slot by slot and the order of downloadLeafBoxes(): the n-th entry of the
//   scan's second set takes the n-th free block, and entries are numbered by atomicAdd, so on a
//   GPU which block a node's children get (and thereby the order of the leaf boxes) depends on
//   scheduling by design. The pool is compared up to that renumbering (the walk above). Whether
//   the raw bytes happened to match as well is recorded as the test property raw_pool_identical;
// - free blocks' stale contents (not part of the tree);
// - ScanStats::wall_ms and the device stage times.

struct Probes {
  std::vector<Eigen::Vector3f> points;
  std::vector<Ray> rays;
  Eigen::Vector3f box_min, box_max;
};

// Lookups at the scan's end points, halfway to them and at random points around; rays from the
// origin towards end points and beyond them, and from random points in random directions.
Probes makeProbes(const std::vector<Eigen::Vector3f>& scan, const Eigen::Vector3f& origin,
                  unsigned seed) {
  Probes p;
  std::mt19937 rng(seed);
  std::uniform_real_distribution<float> u(-1.0f, 1.0f);
  Eigen::Vector3f lo = origin, hi = origin;
  for (std::size_t i = 0; i < scan.size(); i += std::max<std::size_t>(1, scan.size() / 400)) {
    const Eigen::Vector3f& q = scan[i];
    if (!q.allFinite() || q.cwiseAbs().maxCoeff() > 1000.0f) continue;
    lo = lo.cwiseMin(q);
    hi = hi.cwiseMax(q);
    p.points.push_back(q);
    p.points.push_back(0.5f * (q + origin));
    Ray r;
    r.origin = origin;
    r.direction = q - origin;
    // Unknown space counts as free for some (those get a max range: a ray through unknown
    // space would otherwise walk to the map's border).
    r.ignore_unknown = i % 2 == 0;
    r.max_range_m = i % 3 == 0 && !r.ignore_unknown ? -1.0 : 1.5 * (q - origin).norm();
    p.rays.push_back(r);
  }
  const Eigen::Vector3f extent = hi - lo;
  for (int i = 0; i < 200; ++i) {
    const Eigen::Vector3f t(u(rng), u(rng), u(rng));
    const Eigen::Vector3f q = 0.5f * (lo + hi) + 0.6f * t.cwiseProduct(extent);
    p.points.push_back(q);
    Ray r;
    r.origin = q;
    r.direction = Eigen::Vector3f(u(rng), u(rng), u(rng));
    r.ignore_unknown = i % 4 == 1;
    r.max_range_m = i % 2 && !r.ignore_unknown ? -1.0 : 2.0;
    p.rays.push_back(r);
  }
  p.box_min = lo + 0.25f * extent;
  p.box_max = hi - 0.25f * extent;
  return p;
}

using Word2 = std::array<std::uint32_t, 2>;
using Word4 = std::array<std::uint32_t, 4>;

struct Snapshot {
  std::string ot, bt, ot_file, bt_file;
  std::size_t node_count = 0, leaf_count = 0, device_bytes = 0, pool_bytes = 0;
  bool root_exists = false;
  std::size_t pool_slots = 0, reachable_blocks = 0;
  std::vector<Word2> walk;  // depth first from the root: log-odds bits, child mask
  std::vector<LeafTuple> leaves, box_leaves, box_occupied;
  std::vector<Word4> lookups;  // state, log-odds bits, depth
  std::vector<Word4> rays;     // hit, end x, y, z bits
  HostTree raw;
};

std::vector<LeafTuple> sortedLeaves(const std::vector<OccupancyMap::LeafBoxHost>& boxes) {
  std::vector<LeafTuple> out;
  for (const auto& b : boxes)
    out.push_back({floatBits(b.center[0]), floatBits(b.center[1]), floatBits(b.center[2]),
                   floatBits(b.size), floatBits(b.log_odds)});
  std::sort(out.begin(), out.end());
  return out;
}

Snapshot snapshot(OccupancyMap& map, const Probes& probes, const std::string& tag) {
  Snapshot s;
  const auto tree = toOcTree(map);
  s.ot = test::otBytes(*tree);
  s.bt = test::btBytes(*tree);
  const std::string ot_path = test::tmpPath("determinism_" + tag + ".ot");
  const std::string bt_path = test::tmpPath("determinism_" + tag + ".bt");
  writeMapFile(map, ot_path);
  writeMapFile(map, bt_path);
  s.ot_file = test::fileBytes(ot_path);
  s.bt_file = test::fileBytes(bt_path);
  s.node_count = map.nodeCount();
  s.leaf_count = map.leafCount();
  s.device_bytes = map.deviceBytes();
  s.pool_bytes = map.poolBytes();
  s.leaves = sortedLeaves(map.downloadLeafBoxes());
  s.box_leaves = sortedLeaves(map.leavesInBox(probes.box_min, probes.box_max, false));
  s.box_occupied = sortedLeaves(map.leavesInBox(probes.box_min, probes.box_max, true));
  s.raw = map.download();
  s.root_exists = s.raw.root_exists;
  s.pool_slots = s.raw.nodes.size();
  if (s.root_exists) {
    struct Walk {
      const HostTree& t;
      Snapshot& s;
      void operator()(std::uint32_t n) {
        const HostTree::Node& node = t.nodes.at(n);
        s.walk.push_back({floatBits(node.log_odds), node.mask});
        if (node.mask == 0) return;
        ++s.reachable_blocks;
        for (std::uint32_t i = 0; i < 8; ++i)
          if (node.mask & (1u << i)) (*this)(node.children * 8 + i);
      }
    };
    Walk{s.raw, s}(0);
  }
  for (const Lookup& l : map.search(probes.points))
    s.lookups.push_back({static_cast<std::uint32_t>(l.state), floatBits(l.log_odds), l.depth, 0});
  for (const RayHit& h : map.castRays(probes.rays))
    s.rays.push_back(
        {h.hit ? 1u : 0u, floatBits(h.end.x()), floatBits(h.end.y()), floatBits(h.end.z())});
  return s;
}

template <class V>
::testing::AssertionResult sameVector(const char* what, const V& a, const V& b) {
  if (a.size() != b.size())
    return ::testing::AssertionFailure() << what << ": " << a.size() << " vs " << b.size();
  const auto [ia, ib] = std::mismatch(a.begin(), a.end(), b.begin());
  if (ia != a.end())
    return ::testing::AssertionFailure()
           << what << ": first difference at " << (ia - a.begin()) << " of " << a.size();
  return ::testing::AssertionSuccess();
}

::testing::AssertionResult sameSnapshot(const Snapshot& a, const Snapshot& b) {
  auto fail = [] { return ::testing::AssertionFailure(); };
  if (a.node_count != b.node_count)
    return fail() << "nodeCount " << a.node_count << " vs " << b.node_count;
  if (a.leaf_count != b.leaf_count)
    return fail() << "leafCount " << a.leaf_count << " vs " << b.leaf_count;
  if (a.device_bytes != b.device_bytes)
    return fail() << "deviceBytes " << a.device_bytes << " vs " << b.device_bytes;
  if (a.pool_bytes != b.pool_bytes)
    return fail() << "poolBytes " << a.pool_bytes << " vs " << b.pool_bytes;
  if (a.root_exists != b.root_exists) return fail() << "root_exists differs";
  if (a.pool_slots != b.pool_slots)
    return fail() << "download(): pool slots in use " << a.pool_slots << " vs " << b.pool_slots;
  if (a.reachable_blocks != b.reachable_blocks)
    return fail() << "download(): blocks in the tree " << a.reachable_blocks << " vs "
                  << b.reachable_blocks;
  if (auto r = sameVector("download(): tree walk", a.walk, b.walk); !r) return r;
  if (a.ot != b.ot) return fail() << ".ot bytes of toOcTree differ";
  if (a.bt != b.bt) return fail() << ".bt bytes of toOcTree differ";
  if (a.ot_file != b.ot_file) return fail() << "writeMapFile .ot bytes differ";
  if (a.bt_file != b.bt_file) return fail() << "writeMapFile .bt bytes differ";
  if (auto r = sameVector("downloadLeafBoxes", a.leaves, b.leaves); !r) return r;
  if (auto r = sameVector("leavesInBox", a.box_leaves, b.box_leaves); !r) return r;
  if (auto r = sameVector("leavesInBox occupied", a.box_occupied, b.box_occupied); !r) return r;
  if (auto r = sameVector("search", a.lookups, b.lookups); !r) return r;
  if (auto r = sameVector("castRays", a.rays, b.rays); !r) return r;
  return ::testing::AssertionSuccess();
}

bool rawPoolIdentical(const HostTree& a, const HostTree& b) {
  if (a.root_exists != b.root_exists || a.nodes.size() != b.nodes.size()) return false;
  for (std::size_t i = 0; i < a.nodes.size(); ++i)
    if (floatBits(a.nodes[i].log_odds) != floatBits(b.nodes[i].log_odds) ||
        a.nodes[i].children != b.nodes[i].children || a.nodes[i].mask != b.nodes[i].mask)
      return false;
  return true;
}

::testing::AssertionResult sameStats(const ScanStats& a, const ScanStats& b) {
  const std::array<std::size_t, 8> x = {a.points,     a.skipped_nonfinite, a.skipped_outside,
                                        a.free_cells, a.occupied_cells,    a.aborted_cells,
                                        a.nodes,      a.cell_set_attempts};
  const std::array<std::size_t, 8> y = {b.points,     b.skipped_nonfinite, b.skipped_outside,
                                        b.free_cells, b.occupied_cells,    b.aborted_cells,
                                        b.nodes,      b.cell_set_attempts};
  static const char* const names[] = {"points",     "skipped_nonfinite", "skipped_outside",
                                      "free_cells", "occupied_cells",    "aborted_cells",
                                      "nodes",      "cell_set_attempts"};
  for (std::size_t i = 0; i < x.size(); ++i)
    if (x[i] != y[i])
      return ::testing::AssertionFailure()
             << "ScanStats::" << names[i] << " " << x[i] << " vs " << y[i];
  return ::testing::AssertionSuccess();
}

// ---- scenes
// --------------------------------------------------------------------------------------

// End points on the walls, floor and ceiling of a box-shaped room [-3, 3] x [-2.5, 2.5] x
// [-0.5, 2.1] seen from `origin` (inside it), in random directions.
std::vector<Eigen::Vector3f> roomScan(std::mt19937& rng, const Eigen::Vector3f& origin,
                                      std::size_t n) {
  const Eigen::Vector3f lo(-3.0f, -2.5f, -0.5f), hi(3.0f, 2.5f, 2.1f);
  std::normal_distribution<float> g(0.0f, 1.0f);
  std::vector<Eigen::Vector3f> pts;
  while (pts.size() < n) {
    Eigen::Vector3f d(g(rng), g(rng), 0.6f * g(rng));
    if (d.norm() < 1e-3f) continue;
    d.normalize();
    float t = std::numeric_limits<float>::max();
    for (int a = 0; a < 3; ++a) {
      if (d[a] > 1e-6f) t = std::min(t, (hi[a] - origin[a]) / d[a]);
      if (d[a] < -1e-6f) t = std::min(t, (lo[a] - origin[a]) / d[a]);
    }
    pts.push_back(origin + d * t);
  }
  return pts;
}

// ---- 1. the same scans into two fresh maps
// ---------------------------------------------------------

TEST(DeterminismTwoMaps, SameScansGiveIdenticalDeviceState) {
  OCTOVK_REQUIRE_CONTEXT(ctx);
  const MapParams params = withResolution(0.1);
  OccupancyMap a(ctx, params);
  OccupancyMap b(ctx, params);
  // A third map rebuilds its leaf boxes at the end of every scan instead of on demand.
  OccupancyMap c(ctx, params);
  c.setLeafBoxesEveryScan(true);
  octomap::OcTree oracle = makeOracle(params);
  std::mt19937 rng(8061);
  const float nan = std::numeric_limits<float>::quiet_NaN();
  const float inf = std::numeric_limits<float>::infinity();

  struct Step {
    Eigen::Vector3f origin;
    double max_range;
    bool discretize;
    std::size_t points;
  };
  const std::vector<Step> steps = {
      {{0.013f, -0.021f, 0.4f}, -1.0, false, 6000},  // first scan: every block is new
      {{0.013f, -0.021f, 0.4f}, -1.0, false, 6000},  // the same origin: existing leaves
      {{0.6f, 0.3f, 0.9f}, -1.0, true, 6000},        // discretize
      {{-0.8f, 0.2f, 0.1f}, 1.2, false, 6000},       // max range, across earlier free space
      {{0.013f, -0.021f, 0.4f}, -1.0, false, 6000},
  };
  bool raw_identical = true;
  for (std::size_t i = 0; i < steps.size(); ++i) {
    SCOPED_TRACE("scan " + std::to_string(i));
    const Step& st = steps[i];
    auto pts = roomScan(rng, st.origin, st.points);
    // Points that are skipped (and counted): NaN, inf, outside the map. Not with discretize,
    // where OctoMap's unchecked key conversion wraps them into bogus cells (docs/library.md,
    // limits).
    if (!st.discretize) {
      pts.emplace_back(nan, 0.0f, 0.0f);
      pts.emplace_back(1.0f, inf, 0.0f);
      pts.emplace_back(5000.0f, 0.0f, 0.0f);
    }
    oracle.insertPointCloud(test::toPointcloud(pts), test::toPoint(st.origin), st.max_range, false,
                            st.discretize);
    const ScanOptions options{.max_range_m = st.max_range, .discretize = st.discretize};
    const ScanStats sa = a.insertPointCloud(pts, st.origin, options);
    const ScanStats sb = b.insertPointCloud(pts, st.origin, options);
    const ScanStats sc = c.insertPointCloud(pts, st.origin, options);
    ASSERT_TRUE(sameStats(sa, sb));
    ASSERT_TRUE(sameStats(sa, sc));
    EXPECT_EQ(sa.nodes, oracle.size());
    if (!st.discretize) {
      EXPECT_EQ(sa.skipped_nonfinite, 2u);
      EXPECT_EQ(sa.skipped_outside, st.max_range < 0 ? 1u : 0u);  // else clipped to max range
    }
    const Probes probes = makeProbes(pts, st.origin, 100 + static_cast<unsigned>(i));
    const Snapshot ta = snapshot(a, probes, "a");
    const Snapshot tb = snapshot(b, probes, "b");
    const Snapshot tc = snapshot(c, probes, "c");
    // The probes see something: occupied and free cells, hits, leaves in the box.
    const auto states = [&](std::uint32_t state) {
      return std::count_if(ta.lookups.begin(), ta.lookups.end(),
                           [&](const Word4& l) { return l[0] == state; });
    };
    EXPECT_GT(states(static_cast<std::uint32_t>(CellState::kOccupied)), 0);
    EXPECT_GT(states(static_cast<std::uint32_t>(CellState::kFree)), 0);
    EXPECT_GT(std::count_if(ta.rays.begin(), ta.rays.end(), [](const Word4& r) { return r[0]; }),
              0);
    EXPECT_FALSE(ta.box_leaves.empty());
    ASSERT_TRUE(sameSnapshot(ta, tb));
    ASSERT_TRUE(sameSnapshot(ta, tc));
    raw_identical = raw_identical && rawPoolIdentical(ta.raw, tb.raw);
    // And it is OctoMap's map.
    ASSERT_TRUE(sameTree(oracle, *toOcTree(a)));
    ASSERT_TRUE(test::sameLeaves(oracle, a));
    EXPECT_EQ(ta.walk.size(), oracle.size());
  }
  RecordProperty("raw_pool_identical", raw_identical ? 1 : 0);
}

// ---- 2. the points of a scan in any order
// --------------------------------------------------------

// A scan whose points share cells in every way: random rays, several end points on one ray
// (near end cells crossed by far rays: occupied wins), many points in one cell, duplicates.
std::vector<Eigen::Vector3f> conflictScan(std::mt19937& rng, const Eigen::Vector3f& origin) {
  std::uniform_real_distribution<float> u(-1.0f, 1.0f);
  auto pts = test::randomScan(rng, origin, 2500, 2.0f);
  for (int i = 0; i < 300; ++i) {
    Eigen::Vector3f d(u(rng), u(rng), u(rng));
    if (d.norm() < 1e-3f) continue;
    d.normalize();
    for (float r : {0.35f, 0.6f, 0.85f, 1.3f}) pts.push_back(origin + d * r);
  }
  std::uniform_real_distribution<float> jitter(0.001f, 0.049f);
  for (int i = 0; i < 800; ++i)
    pts.emplace_back(0.7f + jitter(rng), -0.4f + jitter(rng), 0.3f + jitter(rng));
  for (int i = 0; i < 400; ++i) pts.push_back(pts[static_cast<std::size_t>(i) * 7]);
  return pts;
}

void shuffledScansGiveTheSameMap(Context& ctx, bool discretize) {
  const MapParams params = withResolution(0.05);
  std::mt19937 rng(4242);
  const Eigen::Vector3f o1(0.01f, 0.02f, 0.03f), o2(0.31f, -0.18f, 0.12f);
  // The first scan, 6 times, builds a map with clamped (after 5 misses), pruned free space near
  // the sensor; the second, from another origin, updates, creates and expands nodes in it, and
  // skips clamped cells (early abort).
  const auto first = conflictScan(rng, o1);
  const auto second = conflictScan(rng, o2);

  octomap::OcTree oracle = makeOracle(params);
  OccupancyMap reference(ctx, params);
  for (int rep = 0; rep < 6; ++rep)
    ASSERT_TRUE(insertBoth(reference, oracle, first, o1, -1.0, discretize)) << "first " << rep;
  const std::string first_ot = test::otBytes(*toOcTree(reference));
  ScanStats ref_stats;
  ASSERT_TRUE(insertBoth(reference, oracle, second, o2, -1.0, discretize, &ref_stats));
  EXPECT_GT(ref_stats.aborted_cells, 0u);
  const auto ref_tree = toOcTree(reference);
  const std::string ref_ot = test::otBytes(*ref_tree), ref_bt = test::btBytes(*ref_tree);

  // Permutations with fixed seeds, and the reversed order.
  for (unsigned seed : {1u, 2u, 3u, 4u, 0u}) {
    SCOPED_TRACE("permutation seed " + std::to_string(seed) + (seed == 0 ? " (reversed)" : ""));
    auto shuffled = [&](std::vector<Eigen::Vector3f> v, unsigned salt) {
      if (seed == 0) {
        std::reverse(v.begin(), v.end());
      } else {
        std::mt19937 g(seed * 1000 + salt);
        std::shuffle(v.begin(), v.end(), g);
      }
      return v;
    };
    OccupancyMap map(ctx, params);
    for (int rep = 0; rep < 6; ++rep)
      map.insertPointCloud(shuffled(first, static_cast<unsigned>(rep)), o1,
                           {.discretize = discretize});
    EXPECT_TRUE(test::otBytes(*toOcTree(map)) == first_ot)
        << ".ot bytes after the shuffled first scans differ from the unshuffled map";
    const auto pts = shuffled(second, 7);
    ASSERT_NE(pts, second);
    const ScanStats stats = map.insertPointCloud(pts, o2, {.discretize = discretize});
    EXPECT_TRUE(sameStats(ref_stats, stats));
    const auto tree = toOcTree(map);
    EXPECT_TRUE(test::otBytes(*tree) == ref_ot) << ".ot bytes differ from the unshuffled map";
    EXPECT_TRUE(test::btBytes(*tree) == ref_bt) << ".bt bytes differ from the unshuffled map";
    ASSERT_TRUE(sameTree(oracle, *tree));
    EXPECT_TRUE(test::sameLeaves(oracle, map));
  }
}

// The tests below run with and without discretize: Suite.Test/Plain and Suite.Test/Discretize
// (instantiated without a prefix, so the names stay inside the Determinism* / Stress* filters).
std::string discretizeName(const ::testing::TestParamInfo<bool>& info) {
  return info.param ? "Discretize" : "Plain";
}

class DeterminismPointOrder : public ::testing::TestWithParam<bool> {};

TEST_P(DeterminismPointOrder, ShuffledScansGiveTheSameMap) {
  OCTOVK_REQUIRE_CONTEXT(ctx);
  shuffledScansGiveTheSameMap(ctx, GetParam());
}

INSTANTIATE_TEST_SUITE_P(, DeterminismPointOrder, ::testing::Bool(), discretizeName);

// ---- 3. many rays on few cells
// ---------------------------------------------------------------------

// 20,000 points inside 3 cells: two neighbours, one of them on the rays to a third behind it
// (free and occupied in the same scan), every ray through the same cells near the sensor.
void twentyThousandPointsInThreeCells(Context& ctx, bool discretize) {
  const MapParams params = withResolution(0.05);
  OccupancyMap map(ctx, params);
  octomap::OcTree oracle = makeOracle(params);
  std::mt19937 rng(303);
  std::uniform_real_distribution<float> jitter(0.0005f, 0.0495f);
  const Eigen::Vector3f origin(0.021f, 0.017f, 0.033f);
  // Cell corners: (0.5, 0, 0) and its +y neighbour, and (1.0, 0, 0) behind the first one.
  const std::array<Eigen::Vector3f, 3> cells = {Eigen::Vector3f(0.5f, 0.0f, 0.0f),
                                                Eigen::Vector3f(0.5f, 0.05f, 0.0f),
                                                Eigen::Vector3f(1.0f, 0.0f, 0.0f)};
  for (int scan = 0; scan < 4; ++scan) {
    std::vector<Eigen::Vector3f> pts;
    for (int i = 0; i < 20000; ++i)
      pts.push_back(cells[static_cast<std::size_t>(i % 3)] +
                    Eigen::Vector3f(jitter(rng), jitter(rng), jitter(rng)));
    ScanStats stats;
    ASSERT_TRUE(insertBoth(map, oracle, pts, origin, -1.0, discretize, &stats)) << "scan " << scan;
    EXPECT_EQ(stats.occupied_cells, 3u);
    EXPECT_GT(stats.free_cells, 5u);
  }
  // The first cell is on rays to the third, and occupied wins: it holds 4 hits.
  const octomap::OcTreeNode* n =
      oracle.search(test::toPoint(cells[0] + Eigen::Vector3f::Constant(0.025f)));
  ASSERT_NE(n, nullptr);
  EXPECT_FLOAT_EQ(n->getLogOdds(), std::min(4 * octomap::logodds(0.7), octomap::logodds(0.971)));
}

// 20,000 long rays (about 160-200 cells) in a cone of half-angle 2 degrees: thousands of rays
// cross each cell near the sensor.
void denseConeOfLongRays(Context& ctx, bool discretize) {
  const MapParams params = withResolution(0.05);
  OccupancyMap map(ctx, params);
  octomap::OcTree oracle = makeOracle(params);
  std::mt19937 rng(404);
  std::uniform_real_distribution<float> u(-1.0f, 1.0f);
  std::uniform_real_distribution<float> len(8.0f, 10.0f);
  const Eigen::Vector3f origin(0.012f, -0.004f, 0.027f);
  const Eigen::Vector3f axis = Eigen::Vector3f(1.0f, 0.4f, 0.2f).normalized();
  const float spread = std::tan(2.0f * 3.14159265f / 180.0f);
  // Six scans: from the sixth on, the cells near the sensor are clamped (5 misses) and skipped.
  for (int scan = 0; scan < 6; ++scan) {
    std::vector<Eigen::Vector3f> pts;
    while (pts.size() < 20000) {
      const Eigen::Vector3f off(u(rng), u(rng), u(rng));
      const Eigen::Vector3f perp = off - off.dot(axis) * axis;
      pts.push_back(origin + (axis + spread * perp).normalized() * len(rng));
    }
    ScanStats stats;
    ASSERT_TRUE(insertBoth(map, oracle, pts, origin, -1.0, discretize, &stats)) << "scan " << scan;
    EXPECT_GT(stats.free_cells, 1000u);
    if (scan == 5) {
      EXPECT_GT(stats.aborted_cells, 0u);
    }
  }
  EXPECT_TRUE(test::sameLeaves(oracle, map));
}

// All end points in one brick of 4x4x4 cells ([0, 0.4)^3 at 0.1 m: keys 32768..32771), with the
// sensor inside the brick (every ray stays in it) or outside.
void allPointsInOneBrick(Context& ctx, bool discretize) {
  const MapParams params = withResolution(0.1);
  std::mt19937 rng(505);
  std::uniform_real_distribution<float> in(0.001f, 0.399f);
  for (const Eigen::Vector3f& origin :
       {Eigen::Vector3f(0.05f, 0.15f, 0.25f), Eigen::Vector3f(-1.3f, 0.7f, 0.2f)}) {
    SCOPED_TRACE("origin " + std::to_string(origin.x()));
    OccupancyMap map(ctx, params);
    octomap::OcTree oracle = makeOracle(params);
    for (int scan = 0; scan < 6; ++scan) {
      std::vector<Eigen::Vector3f> pts;
      // About 50 points per cell; every other scan only in the brick's lower half (z < 0.2),
      // so cells there are hit twice as often and clamp first.
      for (int i = 0; i < 3000; ++i)
        pts.emplace_back(in(rng), in(rng), scan % 2 ? 0.5f * in(rng) : in(rng));
      ScanStats stats;
      ASSERT_TRUE(insertBoth(map, oracle, pts, origin, -1.0, discretize, &stats))
          << "scan " << scan;
      EXPECT_LE(stats.occupied_cells, 64u);
      EXPECT_GT(stats.occupied_cells, 20u);
    }
    // Repeated hits clamp whole groups of 8 cells: they prune.
    EXPECT_GT(prunedLeaves(oracle), 0u);
  }
}

class StressFewCells : public ::testing::TestWithParam<bool> {};

TEST_P(StressFewCells, TwentyThousandPointsInThreeCells) {
  OCTOVK_REQUIRE_CONTEXT(ctx);
  twentyThousandPointsInThreeCells(ctx, GetParam());
}

TEST_P(StressFewCells, DenseConeOfLongRays) {
  OCTOVK_REQUIRE_CONTEXT(ctx);
  denseConeOfLongRays(ctx, GetParam());
}

TEST_P(StressFewCells, AllPointsInOneBrick) {
  OCTOVK_REQUIRE_CONTEXT(ctx);
  allPointsInOneBrick(ctx, GetParam());
}

INSTANTIATE_TEST_SUITE_P(, StressFewCells, ::testing::Bool(), discretizeName);

// ---- 4. one scan that outgrows every set and the pool -------------------------------------------

// MapParams has no initial-capacity fields (only max_nodes, a limit). A fresh map starts with a
// node pool of 1024 blocks (8192 nodes), a cell set of 2^12 brick slots (full at 3/4) with a cell
// list of 4 cells per slot (16,384), and a second set of 2^12 entries (full at 3/4): the
// kInitial* constants of src/map/occupancy_map.cpp. A scan's first guess is 4 brick slots per
// point, so a scan of few points (here 814) that touches many cells starts with those sizes. A
// full set or list makes the cell set (and the second set, when smaller) grow 4x and the ray
// pass run again; then the pool grows before the tree passes.
//
// growthScan() was measured (with a temporary printout of each attempt's counters, octovk at
// commit ffecb41) to outgrow each of them in its first call:
//   attempt 1, 2^12 slots: 3,073 bricks fill the cell set (and 17,574 cells the cell list);
//   attempt 2, 2^14 slots: the cell list alone (about 232,000 cells in 10,035 bricks);
//   attempt 3, 2^16 slots: the second set alone (73,201 new blocks);
//   attempt 4: succeeds, and the pool grows from 1024 to 73,203 blocks.
// The assertions below check the sizes that force this from the public API (cells, blocks in the
// tree, attempts, pool bytes).
std::vector<Eigen::Vector3f> growthScan(std::mt19937& rng, const Eigen::Vector3f& origin) {
  std::uniform_real_distribution<float> u(-1.0f, 1.0f);
  std::vector<Eigen::Vector3f> pts;
  // Long sparse rays, 160-240 cells each: 4-6 cells in each brick they cross.
  while (pts.size() < 30) {
    Eigen::Vector3f d(u(rng), u(rng), u(rng));
    if (d.norm() < 1e-3f) continue;
    pts.push_back(origin + d.normalized() * (10.0f + 2.0f * u(rng)));
  }
  // A bundle of 28 x 28 rays of 20 m, one cell apart at 10 m and two at their end: up to 10 m
  // they fill whole bricks (many cells per brick), beyond it they touch every group of 2x2x2
  // cells of each brick (a new block for each).
  for (int j = 0; j < 28; ++j)
    for (int k = 0; k < 28; ++k)
      pts.push_back(origin + Eigen::Vector3f(-20.0f, -1.4f + 0.1f * static_cast<float>(j) + 0.026f,
                                             -1.4f + 0.1f * static_cast<float>(k) + 0.042f));
  return pts;
}

void oneScanOutgrowsEverySetAndThePool(Context& ctx, bool discretize) {
  const MapParams params = withResolution(0.05);
  OccupancyMap map(ctx, params);
  octomap::OcTree oracle = makeOracle(params);
  const std::size_t pool_bytes = map.poolBytes();
  const std::size_t device_bytes = map.deviceBytes();
  std::mt19937 rng(606);
  const Eigen::Vector3f origin(0.011f, 0.023f, -0.017f);
  const auto pts = growthScan(rng, origin);
  ScanStats stats;
  ASSERT_TRUE(insertBoth(map, oracle, pts, origin, -1.0, discretize, &stats));
  // The scan's own sizes against the fresh map's capacities.
  EXPECT_LT(pts.size() * 4, 4096u);  // first guess: the initial cell set
  // More cells than the cell list holds even after the cell set grew twice (2^14 x 4).
  EXPECT_GT(stats.free_cells + stats.occupied_cells, 65536u);
  EXPECT_GT(stats.nodes, 8192u);  // the initial pool
  const HostTree raw = map.download();
  std::size_t blocks = 0;  // blocks in the tree = entries of the second set in this scan
  for (const auto& n : raw.nodes)
    if (n.mask) ++blocks;
  // More than the second set holds at 2^16 entries (full at 3/4).
  EXPECT_GT(blocks, 49152u);
  // The sets grew (the ray pass ran again at least once per growth), and the pool and the
  // scratch buffers grew.
  EXPECT_GE(stats.cell_set_attempts, 3u);
  EXPECT_GT(map.poolBytes(), pool_bytes);
  EXPECT_GT(map.deviceBytes(), device_bytes);
  EXPECT_TRUE(test::sameLeaves(oracle, map));

  // The grown map keeps working: the same scan again (early abort, clamping), then another one
  // that grows the pool again from a different origin.
  ASSERT_TRUE(insertBoth(map, oracle, pts, origin, -1.0, discretize, &stats)) << "again";
  const std::size_t grown = map.poolBytes();
  const Eigen::Vector3f other(4.0f, -3.0f, 1.0f);
  ASSERT_TRUE(insertBoth(map, oracle, growthScan(rng, other), other, -1.0, discretize, &stats))
      << "from another origin";
  EXPECT_GT(map.poolBytes(), grown);
  EXPECT_TRUE(test::sameLeaves(oracle, map));
}

class StressGrowth : public ::testing::TestWithParam<bool> {};

TEST_P(StressGrowth, OneScanOutgrowsEverySetAndThePool) {
  OCTOVK_REQUIRE_CONTEXT(ctx);
  oneScanOutgrowsEverySetAndThePool(ctx, GetParam());
}

INSTANTIATE_TEST_SUITE_P(, StressGrowth, ::testing::Bool(), discretizeName);

// ---- 5. long sequences from moving origins
// ----------------------------------------------------------

// 15 scans of a room from a sensor moving on a loop (it passes its earlier positions, so free
// space is clamped, pruned and expanded again), compared with OctoMap after every scan.
void fifteenScansFromMovingOrigins(Context& ctx, bool discretize, double max_range) {
  const MapParams params = withResolution(0.08);
  OccupancyMap map(ctx, params);
  octomap::OcTree oracle = makeOracle(params);
  std::mt19937 rng(707 + (discretize ? 1u : 0u) + (max_range > 0 ? 2u : 0u));
  std::size_t aborted = 0;
  for (int scan = 0; scan < 15; ++scan) {
    const float a = 2.0f * 3.14159265f * static_cast<float>(scan % 5) / 5.0f;
    const Eigen::Vector3f origin(1.5f * std::cos(a) + 0.003f * static_cast<float>(scan),
                                 1.2f * std::sin(a), 0.8f + 0.05f * static_cast<float>(scan % 3));
    const auto pts = roomScan(rng, origin, 2500);
    ScanStats stats;
    ASSERT_TRUE(insertBoth(map, oracle, pts, origin, max_range, discretize, &stats))
        << "after scan " << scan << " from (" << origin.transpose() << ")";
    ASSERT_EQ(map.nodeCount(), oracle.size());
    aborted += stats.aborted_cells;
  }
  EXPECT_GT(aborted, 0u);
  EXPECT_TRUE(test::sameLeaves(oracle, map));
  EXPECT_GT(prunedLeaves(oracle), 0u);
}

// Plain, with discretize, and with a max range (without discretize).
struct SequenceMode {
  const char* name;
  bool discretize;
  double max_range;
};

// What googletest prints for the parameter (ctest's test names carry it): its name.
void PrintTo(const SequenceMode& mode, std::ostream* os) { *os << mode.name; }

class StressSequence : public ::testing::TestWithParam<SequenceMode> {};

TEST_P(StressSequence, FifteenScansFromMovingOrigins) {
  OCTOVK_REQUIRE_CONTEXT(ctx);
  fifteenScansFromMovingOrigins(ctx, GetParam().discretize, GetParam().max_range);
}

INSTANTIATE_TEST_SUITE_P(, StressSequence,
                         ::testing::Values(SequenceMode{"Plain", false, -1.0},
                                           SequenceMode{"Discretize", true, -1.0},
                                           SequenceMode{"MaxRange", false, 2.0}),
                         [](const ::testing::TestParamInfo<SequenceMode>& info) {
                           return std::string(info.param.name);
                         });

}  // namespace
}  // namespace octovk
