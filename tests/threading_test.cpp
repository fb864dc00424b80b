// The threading contract (include/octovk/octovk.hpp, Context): maps sharing one Context are used
// from different threads at once and each equals the same scans inserted serially, and OctoMap;
// queries on one map run while another map inserts. Under OCTOVK_VALIDATION the layer's
// threading check sees every call (any message fails the test); scripts/tsan.sh runs these tests
// under ThreadSanitizer. Also the lifetime rules: a map outlives its Context, a moved-from map
// throws.
#include <octomap/octomap.h>

#include <atomic>
#include <exception>
#include <random>
#include <thread>

#include "test_support.hpp"

namespace octovk {
namespace {

using test::randomScan;

struct Scan {
  std::vector<Eigen::Vector3f> points;
  Eigen::Vector3f origin;
  double max_range = -1.0;
};

// Thread `t`'s own scans: different seeds, origins and ranges per thread.
std::vector<Scan> scansOf(int t, int count) {
  std::mt19937 rng(static_cast<unsigned>(100 + t));
  std::vector<Scan> scans;
  for (int i = 0; i < count; ++i) {
    Scan s;
    s.origin = Eigen::Vector3f(0.3f * static_cast<float>(t), 0.11f * static_cast<float>(i % 5),
                               -0.05f * static_cast<float>(i % 3));
    s.points = randomScan(rng, s.origin, 600 + 150 * static_cast<std::size_t>(i % 4), 2.5f);
    s.max_range = i % 3 == 1 ? 1.8 : -1.0;
    scans.push_back(std::move(s));
  }
  return scans;
}

std::vector<Eigen::Vector3f> probePoints(int t) {
  std::mt19937 rng(static_cast<unsigned>(7 + t));
  std::uniform_real_distribution<float> u(-3.0f, 3.0f);
  std::vector<Eigen::Vector3f> points(2000);
  for (auto& p : points) p = Eigen::Vector3f(u(rng), u(rng), u(rng));
  return points;
}

std::vector<Ray> probeRays(int t) {
  std::mt19937 rng(static_cast<unsigned>(31 + t));
  std::uniform_real_distribution<float> u(-1.0f, 1.0f);
  std::vector<Ray> rays(1000);
  for (auto& r : rays) {
    r.origin = Eigen::Vector3f(0.3f * static_cast<float>(t), 0.0f, 0.0f);
    r.direction = Eigen::Vector3f(u(rng), u(rng), u(rng));
    r.max_range_m = 4.0;
  }
  return rays;
}

// What a thread's map gives, for comparison after the threads joined.
struct Outcome {
  std::string ot_bytes;
  std::vector<Lookup> lookups;
  std::vector<RayHit> hits;
  std::string error;  // an exception's message, if one ended the thread
};

// Thread `t`'s whole job on one map: half its scans blocking, half submitted, then queries and
// the map as OctoMap bytes.
Outcome mapJob(Context& ctx, const MapParams& params, int t) {
  Outcome out;
  try {
    OccupancyMap map(ctx, params);
    const std::vector<Scan> scans = scansOf(t, 12);
    for (std::size_t i = 0; i < scans.size(); ++i) {
      const Scan& s = scans[i];
      if (i % 2 == 0)
        map.insertPointCloud(s.points, s.origin, {.max_range_m = s.max_range});
      else
        map.submitPointCloud(s.points, s.origin, {.max_range_m = s.max_range});
    }
    map.flush();
    out.lookups = map.search(probePoints(t));
    out.hits = map.castRays(probeRays(t));
    out.ot_bytes = test::otBytes(*toOcTree(map));
  } catch (const std::exception& e) {
    out.error = e.what();
  }
  return out;
}

bool sameLookups(const std::vector<Lookup>& a, const std::vector<Lookup>& b) {
  if (a.size() != b.size()) return false;
  for (std::size_t i = 0; i < a.size(); ++i)
    if (a[i].state != b[i].state ||
        test::floatBits(a[i].log_odds) != test::floatBits(b[i].log_odds) ||
        a[i].depth != b[i].depth)
      return false;
  return true;
}

bool sameHits(const std::vector<RayHit>& a, const std::vector<RayHit>& b) {
  if (a.size() != b.size()) return false;
  for (std::size_t i = 0; i < a.size(); ++i)
    if (a[i].hit != b[i].hit || a[i].end != b[i].end) return false;
  return true;
}

// A Context of this test's own, so that the passes are built lazily by the threads themselves
// (the shared one of the other tests has them already); validation messages fail the test.
std::unique_ptr<Context> freshContext(std::string* why) {
  ContextOptions options;
  options.on_validation_message = [](const std::string& message) {
    ADD_FAILURE() << "Vulkan validation " << message;
  };
  auto result = Context::create(options);
  if (!result) {
    *why = result.error().what();
    return nullptr;
  }
  return std::move(result.value());
}

#define REQUIRE_FRESH_CONTEXT(ctx)                                            \
  std::string why_;                                                           \
  std::unique_ptr<Context> ctx = freshContext(&why_);                         \
  if (!ctx) {                                                                 \
    if (test::runningInCi()) FAIL() << "no Vulkan device under CI: " << why_; \
    GTEST_SKIP() << "no Vulkan device: " << why_;                             \
  }

TEST(Threading, FourMapsOnFourThreadsEqualSerialAndOctoMap) {
  REQUIRE_FRESH_CONTEXT(ctx);
  constexpr int kThreads = 4;
  const MapParams params = test::withResolution(0.05);
  std::vector<Outcome> outcomes(kThreads);
  std::vector<std::thread> threads;
  std::atomic<int> ready{0};
  for (int t = 0; t < kThreads; ++t)
    threads.emplace_back([&, t] {
      ready.fetch_add(1);
      while (ready.load() < kThreads) std::this_thread::yield();  // start together
      outcomes[t] = mapJob(*ctx, params, t);
    });
  for (std::thread& th : threads) th.join();

  for (int t = 0; t < kThreads; ++t) {
    SCOPED_TRACE("thread " + std::to_string(t));
    ASSERT_EQ(outcomes[t].error, "");
    // The same job alone, on the same Context.
    const Outcome serial = mapJob(*ctx, params, t);
    ASSERT_EQ(serial.error, "");
    EXPECT_TRUE(outcomes[t].ot_bytes == serial.ot_bytes) << ".ot bytes differ from the serial run";
    EXPECT_TRUE(sameLookups(outcomes[t].lookups, serial.lookups));
    EXPECT_TRUE(sameHits(outcomes[t].hits, serial.hits));
    // And OctoMap's tree of the same scans.
    octomap::OcTree oracle = test::makeOracle(params);
    for (const Scan& s : scansOf(t, 12))
      oracle.insertPointCloud(test::toPointcloud(s.points), test::toPoint(s.origin), s.max_range);
    EXPECT_TRUE(outcomes[t].ot_bytes == test::otBytes(oracle)) << ".ot bytes differ from OctoMap";
  }
}

TEST(Threading, QueriesOnOneMapWhileAnotherInserts) {
  REQUIRE_FRESH_CONTEXT(ctx);
  const MapParams params = test::withResolution(0.1);
  OccupancyMap queried(*ctx, params);
  for (const Scan& s : scansOf(0, 6))
    queried.insertPointCloud(s.points, s.origin, {.max_range_m = s.max_range});
  const std::vector<Eigen::Vector3f> points = probePoints(0);
  const std::vector<Ray> rays = probeRays(0);
  const std::vector<Lookup> lookups = queried.search(points);
  const std::vector<RayHit> hits = queried.castRays(rays);

  std::atomic<bool> inserting{true};
  Outcome inserted;
  std::thread writer([&] {
    inserted = mapJob(*ctx, params, 1);
    inserting.store(false);
  });
  int rounds = 0, wrong = 0;
  std::string error;
  try {
    // At least a few rounds, and on until the other thread is done.
    for (; inserting.load() || rounds < 3; ++rounds) {
      if (!sameLookups(queried.search(points), lookups)) ++wrong;
      if (!sameHits(queried.castRays(rays), hits)) ++wrong;
    }
  } catch (const std::exception& e) {
    error = e.what();
  }
  writer.join();
  EXPECT_EQ(error, "");
  EXPECT_EQ(wrong, 0) << "of " << rounds << " query rounds";
  ASSERT_EQ(inserted.error, "");
  const Outcome serial = mapJob(*ctx, params, 1);
  EXPECT_TRUE(inserted.ot_bytes == serial.ot_bytes);
}

// Each map keeps the device alive: the Context may go first.
TEST(Threading, MapOutlivesItsContext) {
  REQUIRE_FRESH_CONTEXT(ctx);
  const MapParams params = test::withResolution(0.1);
  auto map = std::make_unique<OccupancyMap>(*ctx, params);
  octomap::OcTree oracle = test::makeOracle(params);
  const std::vector<Scan> scans = scansOf(2, 4);
  map->insertPointCloud(scans[0].points, scans[0].origin, {.max_range_m = scans[0].max_range});
  ctx.reset();
  for (std::size_t i = 1; i < scans.size(); ++i) {
    map->submitPointCloud(scans[i].points, scans[i].origin, {.max_range_m = scans[i].max_range});
  }
  map->flush();
  for (const Scan& s : scans)
    oracle.insertPointCloud(test::toPointcloud(s.points), test::toPoint(s.origin), s.max_range);
  EXPECT_TRUE(test::sameTree(oracle, *toOcTree(*map)));
  EXPECT_EQ(map->search(probePoints(2)).size(), 2000u);
  map.reset();  // the device goes with the last map
}

TEST(Threading, MovedFromMapThrowsAndTakesAnAssignedMap) {
  OCTOVK_REQUIRE_CONTEXT(ctx);
  const MapParams params = test::withResolution(0.1);
  OccupancyMap a(ctx, params);
  const Scan s = scansOf(3, 1)[0];
  a.insertPointCloud(s.points, s.origin);
  OccupancyMap b(std::move(a));
  EXPECT_GT(b.nodeCount(), 0u);
  try {
    a.insertPointCloud(s.points, s.origin);  // NOLINT(bugprone-use-after-move): the point
    ADD_FAILURE() << "a moved-from map accepted a scan";
  } catch (const Error& e) {
    EXPECT_EQ(e.code(), ErrorCode::kInvalidArgument);
    EXPECT_NE(std::string(e.what()).find("moved from"), std::string::npos) << e.what();
  }
  EXPECT_THROW(a.nodeCount(), Error);
  EXPECT_THROW(a.search(probePoints(3)), Error);
  EXPECT_THROW(toOcTree(a), Error);
  EXPECT_EQ(a.scansInFlight(), 0u);  // the noexcept observers answer as for an empty map
  a = OccupancyMap(ctx, params);
  a.insertPointCloud(s.points, s.origin);
  EXPECT_EQ(a.nodeCount(), b.nodeCount());
}

}  // namespace
}  // namespace octovk
