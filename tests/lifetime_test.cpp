// The contract of a call that fails and of an object's lifetime: a call that throws leaves the map
// as it was and working (a query batch larger than one binding is split, not refused; a tree with
// a NaN is refused before it reaches the device), a distance field follows its map through a move
// and refuses once the map is gone, a moved-from map has no parameters, and a forked child gets an
// error instead of a hang.
#include <sys/wait.h>
#include <unistd.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <limits>
#include <random>

#include "octovk/distance.hpp"
#include "test_support.hpp"

namespace octovk {
namespace {

using test::randomScan;

// Lookups and rays on a map, in batches far beyond one descriptor binding (forced down to 1 MiB):
// the answers equal those of small batches, and the map keeps working afterwards. Before, the
// batch grew the query buffers past the binding, failed, and every later query failed too.
TEST(QueryBatches, LargerThanOneBindingAreSplitAndTheMapKeepsWorking) {
  OCTOVK_REQUIRE_CONTEXT(ctx);
  auto small = test::contextWithBindingLimit(ctx, 1u << 20);
  ASSERT_TRUE(small) << small.error().what();
  OccupancyMap map(*small.value(), test::withResolution(0.05));
  std::mt19937 rng(5);
  const Eigen::Vector3f origin(0.05f, 0.1f, -0.2f);
  map.insertPointCloud(randomScan(rng, origin, 6000, 3.0f), origin);

  std::uniform_real_distribution<float> u(-4.0f, 4.0f);
  std::vector<Eigen::Vector3f> points(200000);  // 2.4 MB in, 3.2 MB out
  for (Eigen::Vector3f& p : points) p = {u(rng), u(rng), u(rng)};
  std::vector<Ray> rays(40000);  // beyond 1 MiB in and out
  for (Ray& r : rays) {
    r.origin = origin;
    r.direction = {u(rng), u(rng), u(rng)};
    r.max_range_m = 5.0;
    r.ignore_unknown = (&r - rays.data()) % 3 == 0;
  }
  const std::vector<Lookup> all = map.search(points);
  const std::vector<RayHit> hits = map.castRays(rays);
  ASSERT_EQ(all.size(), points.size());
  ASSERT_EQ(hits.size(), rays.size());
  constexpr std::size_t kPart = 10000;  // within the binding
  for (std::size_t i = 0; i < points.size(); i += kPart) {
    const auto part = map.search(std::span(points).subspan(i, kPart));
    for (std::size_t j = 0; j < kPart; ++j) {
      const Lookup& a = all[i + j];
      ASSERT_EQ(a.state, part[j].state) << "point " << i + j;
      ASSERT_EQ(test::floatBits(a.log_odds), test::floatBits(part[j].log_odds)) << i + j;
      ASSERT_EQ(a.depth, part[j].depth) << "point " << i + j;
    }
  }
  for (std::size_t i = 0; i < rays.size(); i += kPart) {
    const auto part = map.castRays(std::span(rays).subspan(i, kPart));
    for (std::size_t j = 0; j < kPart; ++j) {
      ASSERT_EQ(hits[i + j].hit, part[j].hit) << "ray " << i + j;
      ASSERT_EQ(hits[i + j].end, part[j].end) << "ray " << i + j;
    }
  }
  // A scan with queries is one submission: too many queries are refused before the scan, with
  // the map as it was; a batch that fits still goes with its scan.
  const std::size_t nodes = map.nodeCount();
  const auto scan = randomScan(rng, origin, 100, 2.0f);
  QueryResults mixed;
  try {
    map.insertPointCloud(scan, origin, {}, {.lookups = points, .rays = rays}, mixed);
    ADD_FAILURE() << "a scan with queries beyond one binding was inserted";
  } catch (const Error& e) {
    EXPECT_EQ(e.code(), ErrorCode::kInvalidArgument);
    EXPECT_NE(std::string(e.what()).find("search()"), std::string::npos) << e.what();
  }
  EXPECT_EQ(map.nodeCount(), nodes);
  map.insertPointCloud(
      scan, origin, {},
      {.lookups = std::span(points).first(100), .rays = std::span(rays).first(100)}, mixed);
  EXPECT_EQ(mixed.lookups.size(), 100u);
  EXPECT_EQ(mixed.rays.size(), 100u);
  // The leaves of a box that holds more than one binding: asked in parts, each leaf once.
  const auto key = [](const OccupancyMap::LeafBoxHost& l) {
    return std::array<std::uint32_t, 5>{test::floatBits(l.center[0]), test::floatBits(l.center[1]),
                                        test::floatBits(l.center[2]), test::floatBits(l.size),
                                        test::floatBits(l.log_odds)};
  };
  std::vector<std::array<std::uint32_t, 5>> expected, got;
  for (const auto& l : map.downloadLeafBoxes()) expected.push_back(key(l));
  for (const auto& l : map.leavesInBox({-100, -100, -100}, {100, 100, 100}, false))
    got.push_back(key(l));
  ASSERT_GT(expected.size(), (std::size_t{1} << 20) / sizeof(OccupancyMap::LeafBoxHost));
  std::sort(expected.begin(), expected.end());
  std::sort(got.begin(), got.end());
  EXPECT_EQ(got, expected);
  EXPECT_EQ(map.search(std::span(points).first(10)).size(), 10u);
  EXPECT_GT(map.nodeCount(), 1u);
}

// The documented rule is that the map outlives the field; a moved map is the same map. A field
// built on `a` follows it into `b`; once `b` is destroyed (while the moved-from `a` lives), the
// field refuses, and destroying it is safe. Before, the field's destructor used the freed map.
TEST(DistanceFieldLifetime, FollowsItsMapThroughAMoveAndRefusesOnceItIsGone) {
  OCTOVK_REQUIRE_CONTEXT(ctx);
  std::mt19937 rng(11);
  const Eigen::Vector3f origin(0, 0, 0);
  OccupancyMap a(ctx, test::withResolution(0.2));
  a.insertPointCloud(randomScan(rng, origin, 2000, 2.0f), origin);
  const std::vector<Eigen::Vector3f> probe = {{0.5f, 0.5f, 0.5f}, {1.5f, -1.0f, 0.2f}};
  auto field =
      std::make_unique<DistanceField>(a, Eigen::Vector3f(-2, -2, -2), Eigen::Vector3f(2, 2, 2));
  const auto before = field->distances(probe);
  {
    OccupancyMap b(std::move(a));
    b.insertPointCloud(randomScan(rng, origin, 2000, 2.0f), origin);
    field->update();  // reads b: the map it was built on, moved
    const auto after = field->distances(probe);
    ASSERT_EQ(after.size(), probe.size());
    DistanceField fresh(b, Eigen::Vector3f(-2, -2, -2), Eigen::Vector3f(2, 2, 2));
    const auto expected = fresh.distances(probe);
    for (std::size_t i = 0; i < probe.size(); ++i)
      EXPECT_EQ(after[i].distance_m, expected[i].distance_m) << "point " << i;
  }
  ASSERT_EQ(before.size(), probe.size());
  try {
    field->update();
    ADD_FAILURE() << "update() on a field whose map is destroyed";
  } catch (const Error& e) {
    EXPECT_EQ(e.code(), ErrorCode::kInvalidArgument);
    EXPECT_NE(std::string(e.what()).find("destroyed"), std::string::npos) << e.what();
  }
  EXPECT_THROW((void)field->distances(probe), Error);
  field.reset();  // no use of the destroyed map
  EXPECT_THROW((void)a.nodeCount(), Error);
}

// A moved-from map throws for its parameters as for every other call: default parameters would
// pass for a real map's.
TEST(MovedFromMap, ParamsThrow) {
  OCTOVK_REQUIRE_CONTEXT(ctx);
  OccupancyMap a(ctx, test::withResolution(0.3));
  EXPECT_EQ(a.params().resolution, 0.3);
  OccupancyMap b(std::move(a));
  EXPECT_EQ(b.params().resolution, 0.3);
  try {
    (void)a.params();  // NOLINT(bugprone-use-after-move): the call under test
    ADD_FAILURE() << "params() on a moved-from map";
  } catch (const Error& e) {
    EXPECT_EQ(e.code(), ErrorCode::kInvalidArgument);
  }
}

// upload() refuses a tree with a NaN or infinite log-odds (a .ot written from it would be one that
// no reader takes), and the map stays as it was.
TEST(Upload, RefusesLogOddsThatAreNotFinite) {
  OCTOVK_REQUIRE_CONTEXT(ctx);
  std::mt19937 rng(3);
  OccupancyMap map(ctx, test::withResolution(0.2));
  map.insertPointCloud(randomScan(rng, Eigen::Vector3f::Zero(), 500, 2.0f),
                       Eigen::Vector3f::Zero());
  const HostTree tree = map.download();
  for (const float bad :
       {std::numeric_limits<float>::quiet_NaN(), std::numeric_limits<float>::infinity()}) {
    HostTree broken = tree;
    broken.nodes[broken.nodes.size() / 2 + 3].log_odds = bad;
    broken.nodes[0].log_odds = bad;  // the root, which always hangs in the tree
    try {
      map.upload(broken);
      ADD_FAILURE() << "a tree with log-odds " << bad << " was uploaded";
    } catch (const Error& e) {
      EXPECT_EQ(e.code(), ErrorCode::kFormat);
      EXPECT_NE(std::string(e.what()).find("finite"), std::string::npos) << e.what();
    }
    const HostTree now = map.download();
    ASSERT_EQ(now.nodes.size(), tree.nodes.size());
    for (std::size_t i = 0; i < now.nodes.size(); ++i)
      ASSERT_EQ(test::floatBits(now.nodes[i].log_odds), test::floatBits(tree.nodes[i].log_odds));
  }
}

// In a child forked after the map was made, a call throws instead of waiting forever on driver
// threads the child does not have, and leaving the map there does not hang either.
TEST(ForkedChild, RefusesTheParentsMap) {
  OCTOVK_REQUIRE_CONTEXT(ctx);
  auto map = std::make_unique<OccupancyMap>(ctx, test::withResolution(0.2));
  std::mt19937 rng(9);
  map->insertPointCloud(randomScan(rng, Eigen::Vector3f::Zero(), 300, 2.0f),
                        Eigen::Vector3f::Zero());
  const pid_t child = fork();
  ASSERT_NE(child, -1);
  if (child == 0) {
    alarm(60);  // a hang ends in SIGALRM, which the parent sees
    int code = 1;
    try {
      (void)map->nodeCount();
    } catch (const Error& e) {
      code = e.code() == ErrorCode::kInvalidArgument &&
                     std::string(e.what()).find("fork") != std::string::npos
                 ? 2
                 : 3;
    }
    try {
      OccupancyMap other(ctx, test::withResolution(0.2));
      code = 4;  // a map on the parent's device was made
    } catch (const Error&) {
    }
    map.reset();  // must not wait on the device
    _exit(code);
  }
  int status = 0;
  ASSERT_EQ(waitpid(child, &status, 0), child);
  ASSERT_TRUE(WIFEXITED(status)) << "the child was killed by signal "
                                 << (WIFSIGNALED(status) ? WTERMSIG(status) : 0);
  EXPECT_EQ(WEXITSTATUS(status), 2) << "1: no error, 3: the wrong error, 4: a map was made";
  EXPECT_GT(map->nodeCount(), 1u);  // the parent's map is untouched
}

// A map, a field and their Context held by statics made before the Context, so destroyed after
// exit() ran the handlers a driver registered while starting (NVIDIA's tears itself down in its
// own: such destructors then crashed): they leave the device to the end of the process, and the
// process exits with its status. In a fresh process (gtest's threadsafe death test re-runs this
// program), so the driver starts there.
TEST(ProcessExit, StaticsOutliveTheDriversExitHandlers) {
  OCTOVK_REQUIRE_CONTEXT(ctx);
  (void)ctx;  // the child makes its own
  ::testing::FLAGS_gtest_death_test_style = "threadsafe";
  const auto run = [] {
    static std::unique_ptr<Context> context;  // destructors registered before the driver's
    static std::unique_ptr<OccupancyMap> map;
    static std::unique_ptr<DistanceField> field;
    auto made = Context::create();
    if (!made) std::_Exit(3);
    context = std::move(made.value());
    map = std::make_unique<OccupancyMap>(*context, test::withResolution(0.2));
    std::mt19937 rng(4);
    map->insertPointCloud(randomScan(rng, Eigen::Vector3f::Zero(), 300, 2.0f),
                          Eigen::Vector3f::Zero());
    field = std::make_unique<DistanceField>(*map, Eigen::Vector3f(-1, -1, -1),
                                            Eigen::Vector3f(1, 1, 1));
    std::exit(map->nodeCount() > 1 ? 0 : 4);
  };
  EXPECT_EXIT(run(), ::testing::ExitedWithCode(0), "");
}

}  // namespace
}  // namespace octovk
