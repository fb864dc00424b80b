// Change detection against OctoMap: the same scans into an OcTree with enableChangeDetection(true)
// and into octovk with enableChangeDetection(true); after every scan the change sets must be
// equal, key for key and flag for flag (OctoMap's KeyBoolMap: true = the leaf was created,
// false = an existing leaf's occupancy flipped; flipped back = removed).
#include <octomap/octomap.h>

#include <algorithm>
#include <cstring>
#include <random>
#include <tuple>

#include "caller_buffer.hpp"
#include "changed_keys.hpp"
#include "octovk/vulkan_interop.hpp"
#include "test_support.hpp"

namespace octovk::test {
namespace {

::testing::AssertionResult sameChanges(const octomap::OcTree& oracle, OccupancyMap& map) {
  const std::vector<KeyFlag> expected = oracleChanges(oracle);
  const std::vector<KeyFlag> actual = ourChanges(map);
  if (map.numChangesDetected() != oracle.numChangesDetected())
    return ::testing::AssertionFailure() << "numChangesDetected " << map.numChangesDetected()
                                         << ", OctoMap " << oracle.numChangesDetected();
  if (expected == actual) return ::testing::AssertionSuccess();
  std::vector<KeyFlag> missing, extra;
  std::set_difference(expected.begin(), expected.end(), actual.begin(), actual.end(),
                      std::back_inserter(missing));
  std::set_difference(actual.begin(), actual.end(), expected.begin(), expected.end(),
                      std::back_inserter(extra));
  auto r = ::testing::AssertionFailure();
  r << expected.size() << " changed keys in OctoMap, " << actual.size() << " in octovk; "
    << missing.size() << " missing, " << extra.size() << " extra";
  const auto show = [&](const char* what, const std::vector<KeyFlag>& v) {
    if (v.empty()) return;
    const KeyFlag& k = v.front();
    r << "; first " << what << ": (" << std::get<0>(k) << ", " << std::get<1>(k) << ", "
      << std::get<2>(k) << ") " << (std::get<3>(k) ? "true" : "false");
  };
  show("missing", missing);
  show("extra", extra);
  return r;
}

// How many entries of each flag OctoMap has: the scenarios must exercise both.
std::pair<std::size_t, std::size_t> flagCounts(const octomap::OcTree& oracle) {
  std::size_t created = 0, flipped = 0;
  for (auto it = oracle.changedKeysBegin(); it != oracle.changedKeysEnd(); ++it)
    (it->second ? created : flipped)++;
  return {created, flipped};
}

struct ChangeCase {
  double resolution;
  double max_range;
  bool discretize;
  bool streamed;
};

class ChangeDetection : public ::testing::TestWithParam<ChangeCase> {};

// Scans from a sensor moving back and forth over the same ground, so that leaves are created,
// flip free and occupied and back, are pruned and expanded again.
TEST_P(ChangeDetection, SameKeysAndFlagsAsOctoMapAfterEveryScan) {
  OCTOVK_REQUIRE_CONTEXT(ctx);
  const ChangeCase c = GetParam();
  MapParams params;
  params.resolution = c.resolution;
  OccupancyMap map(ctx, params);
  octomap::OcTree oracle = makeOracle(params);
  oracle.enableChangeDetection(true);
  map.enableChangeDetection(true);
  EXPECT_TRUE(map.isChangeDetectionEnabled());
  std::mt19937 rng(17);
  std::size_t flipped_seen = 0;
  for (int scan = 0; scan < 10; ++scan) {
    SCOPED_TRACE("scan " + std::to_string(scan));
    const Eigen::Vector3f origin(0.2f * static_cast<float>(scan % 4),
                                 0.1f * static_cast<float>(scan % 3), 0.0f);
    // Alternate near and far surfaces: cells seen occupied by one scan are crossed by the next.
    const float radius = scan % 2 == 0 ? 1.2f : 2.4f;
    const std::vector<Eigen::Vector3f> pts = test::randomScan(rng, origin, 1200, radius);
    oracle.insertPointCloud(toPointcloud(pts), toPoint(origin), c.max_range, false, c.discretize);
    const ScanOptions options{.max_range_m = c.max_range, .discretize = c.discretize};
    if (c.streamed) {
      (void)map.submitPointCloud(pts, origin, options);
      if (scan % 3 != 2) continue;  // compare after every third scan, all submitted
      map.flush();
    } else {
      (void)map.insertPointCloud(pts, origin, options);
    }
    ASSERT_TRUE(sameChanges(oracle, map));
    flipped_seen = std::max(flipped_seen, flagCounts(oracle).second);
    if (scan == 5) {  // reset halfway, as a consumer does after reading the changes
      oracle.resetChangeDetection();
      map.resetChangeDetection();
      EXPECT_EQ(map.numChangesDetected(), 0u);
    }
  }
  map.flush();
  ASSERT_TRUE(sameChanges(oracle, map));
  EXPECT_TRUE(sameTree(oracle, *toOcTree(map)));
  EXPECT_GT(flagCounts(oracle).first, 100u) << "the scenario must create leaves";
  EXPECT_GT(flipped_seen, 0u) << "the scenario must flip leaves";
  if (c.resolution <= 0.05)  // the set grew past its first 4096 slots (rehash_changes) on the way
    EXPECT_GT(map.deviceBytesByUse().changes, 16u + 4096u * 16u);
  else
    EXPECT_GT(map.deviceBytesByUse().changes, std::size_t{1} << 16);
}

std::string caseName(const ::testing::TestParamInfo<ChangeCase>& info) {
  const ChangeCase& c = info.param;
  return "res" + std::to_string(static_cast<int>(std::lround(c.resolution * 1000))) + "mm" +
         (c.max_range > 0 ? "_maxrange" : "") + (c.discretize ? "_discretize" : "") +
         (c.streamed ? "_streamed" : "");
}

INSTANTIATE_TEST_SUITE_P(Cases, ChangeDetection,
                         ::testing::Values(ChangeCase{0.05, -1.0, false, false},
                                           ChangeCase{0.1, 1.5, false, false},
                                           ChangeCase{0.1, -1.0, true, false},
                                           ChangeCase{0.05, -1.0, false, true},
                                           ChangeCase{0.2, 2.0, true, true}),
                         caseName);

TEST(ChangeDetectionApi, OffByDefaultAndOffCostsNothing) {
  OCTOVK_REQUIRE_CONTEXT(ctx);
  OccupancyMap map(ctx, test::withResolution(0.1));
  EXPECT_FALSE(map.isChangeDetectionEnabled());
  const std::size_t idle = map.deviceBytesByUse().changes;
  EXPECT_LE(idle, 32u);
  std::mt19937 rng(3);
  (void)map.insertPointCloud(test::randomScan(rng, Eigen::Vector3f::Zero(), 500, 2.0f),
                             Eigen::Vector3f::Zero());
  EXPECT_EQ(map.numChangesDetected(), 0u);
  EXPECT_TRUE(map.changedKeys().empty());
  EXPECT_EQ(map.deviceBytesByUse().changes, idle);
}

// Turned on after some scans, off again, on again: only the scans while it is on count, and
// turning it off keeps what was noted (OctoMap's enableChangeDetection).
TEST(ChangeDetectionApi, OnOffOnFollowsOctoMap) {
  OCTOVK_REQUIRE_CONTEXT(ctx);
  const MapParams params = test::withResolution(0.1);
  OccupancyMap map(ctx, params);
  octomap::OcTree oracle = makeOracle(params);
  std::mt19937 rng(5);
  for (int scan = 0; scan < 6; ++scan) {
    const bool on = scan == 2 || scan == 3 || scan == 5;
    oracle.enableChangeDetection(on);
    map.enableChangeDetection(on);
    const Eigen::Vector3f origin(0.3f * static_cast<float>(scan), 0.0f, 0.0f);
    const auto pts = test::randomScan(rng, origin, 800, scan % 2 == 0 ? 1.5f : 2.5f);
    oracle.insertPointCloud(toPointcloud(pts), toPoint(origin));
    (void)map.insertPointCloud(pts, origin);
    ASSERT_TRUE(sameChanges(oracle, map)) << "after scan " << scan;
  }
  EXPECT_GT(oracle.numChangesDetected(), 0u);
}

// Scans with a pose and depth images (unprojected on the device), after importing a tree.
TEST(ChangeDetectionApi, PosesDepthImagesAndAnImportedTree) {
  OCTOVK_REQUIRE_CONTEXT(ctx);
  const MapParams params = test::withResolution(0.1);
  // The tree both start from: a few scans OctoMap inserted.
  octomap::OcTree oracle = makeOracle(params);
  std::mt19937 rng(23);
  for (int i = 0; i < 3; ++i) {
    const Eigen::Vector3f origin(0.5f * static_cast<float>(i), 0.0f, 0.2f);
    oracle.insertPointCloud(toPointcloud(test::randomScan(rng, origin, 1000, 2.0f)),
                            toPoint(origin));
  }
  OccupancyMap map(ctx, params);
  fromOcTree(map, oracle);
  oracle.enableChangeDetection(true);
  map.enableChangeDetection(true);
  ASSERT_TRUE(sameChanges(oracle, map));
  // A scan in the sensor frame with a pose.
  Pose pose;
  pose.rotation = Eigen::AngleAxisf(0.4f, Eigen::Vector3f::UnitZ());
  pose.translation = Eigen::Vector3f(0.2f, -0.1f, 0.1f);
  const auto sensor_pts = test::randomScan(rng, Eigen::Vector3f::Zero(), 900, 2.2f);
  oracle.insertPointCloud(toPointcloud(sensor_pts), octomap::point3d(0, 0, 0), toPose6D(pose));
  (void)map.insertPointCloud(sensor_pts, Eigen::Vector3f::Zero(), pose);
  ASSERT_TRUE(sameChanges(oracle, map));
  // A float depth image of a wall 1.8 m away, then 1.0 m away (the cells between flip free).
  for (const float wall : {1.8f, 1.0f}) {
    DepthImage image;
    image.width = 48;
    image.height = 36;
    image.fx = image.fy = 40.0f;
    image.cx = 23.5f;
    image.cy = 17.5f;
    image.depth_scale = 1.0f;
    image.encoding = DepthImage::Encoding::kFloat32;
    std::vector<float> depth(std::size_t{image.width} * image.height, wall);
    image.depths = std::span<const float>(depth);
    oracle.insertPointCloud(toPointcloud(unprojectDepthImage(image)), octomap::point3d(0, 0, 0),
                            toPose6D(pose));
    (void)map.insertDepthImage(image, pose);
    ASSERT_TRUE(sameChanges(oracle, map)) << "wall at " << wall << " m";
  }
  const auto [created, flipped] = flagCounts(oracle);
  EXPECT_GT(created, 0u);
  EXPECT_GT(flipped, 0u);
  EXPECT_TRUE(sameTree(oracle, *toOcTree(map)));
}

// Scans through ray tracing note the same changes as walked ones.
TEST(ChangeDetectionApi, RayTracedScansFollowOctoMap) {
  OCTOVK_REQUIRE_CONTEXT(ctx);
  OCTOVK_REQUIRE_RAY_QUERY(ctx);
  MapParams params = test::withResolution(0.05);
  params.scan_rays = ScanRays::kRayTracing;
  OccupancyMap map(ctx, params);
  octomap::OcTree oracle = makeOracle(params);
  oracle.enableChangeDetection(true);
  map.enableChangeDetection(true);
  std::mt19937 rng(17);
  std::size_t flipped_seen = 0;
  for (int scan = 0; scan < 10;
       ++scan) {  // the scenario of SameKeysAndFlagsAsOctoMapAfterEveryScan
    const Eigen::Vector3f origin(0.2f * static_cast<float>(scan % 4),
                                 0.1f * static_cast<float>(scan % 3), 0.0f);
    const auto pts = test::randomScan(rng, origin, 1200, scan % 2 == 0 ? 1.2f : 2.4f);
    oracle.insertPointCloud(toPointcloud(pts), toPoint(origin));
    (void)map.insertPointCloud(pts, origin);
    ASSERT_TRUE(sameChanges(oracle, map)) << "after scan " << scan;
    flipped_seen = std::max(flipped_seen, flagCounts(oracle).second);
    if (scan == 4) {  // a key noted as created stays `true`: only after a reset do flips show
      oracle.resetChangeDetection();
      map.resetChangeDetection();
    }
  }
  EXPECT_GT(flipped_seen, 0u);
}

// Under a cap the change set counts: turning detection on where the set does not fit is
// refused with the cap named, the map unchanged and detection still off.
TEST(ChangeDetectionApi, TheSetCountsUnderTheCap) {
  OCTOVK_REQUIRE_CONTEXT(ctx);
  MapParams params = test::withResolution(0.1);
  params.max_device_bytes = params.minDeviceBytes() + 1024;
  OccupancyMap map(ctx, params);
  try {
    map.enableChangeDetection(true);
    ADD_FAILURE() << "a change set of 64 KiB fitted under a cap 1 KiB above the minimum";
  } catch (const Error& e) {
    EXPECT_EQ(e.code(), ErrorCode::kOutOfDeviceMemory) << e.what();
    EXPECT_NE(std::string(e.what()).find("change set"), std::string::npos) << e.what();
  }
  EXPECT_FALSE(map.isChangeDetectionEnabled());
  EXPECT_LE(map.deviceBytes(), params.max_device_bytes);
}

}  // namespace
}  // namespace octovk::test

namespace octovk::test {
namespace {

// A GPU consumer reads the change set in place: changedKeysOnDevice writes the header and the
// keys into its buffer, the same set as changedKeys(); a buffer too small is refused unwritten.
TEST(ChangeDetectionApi, ChangedKeysOnDeviceIntoACallersBuffer) {
  OCTOVK_REQUIRE_CONTEXT(ctx);
  OccupancyMap map(ctx, test::withResolution(0.1));
  map.enableChangeDetection(true);
  std::mt19937 rng(31);
  (void)map.submitPointCloud(test::randomScan(rng, Eigen::Vector3f::Zero(), 700, 2.0f),
                             Eigen::Vector3f::Zero());
  const std::size_t count = map.numChangesDetected();
  ASSERT_GT(count, 100u);
  const std::vector<KeyFlag> expected = ourChanges(map);
  test::CallerBuffer out(vulkanHandles(ctx), changedKeysBytes(count));
  std::memset(out.data(), 0xAB, changedKeysBytes(count));
  changedKeysOnDevice(map, out.range());
  gpu::ChangedKeysHeader header;
  std::memcpy(&header, out.data(), sizeof(header));
  ASSERT_EQ(header.count, count);
  std::vector<KeyFlag> actual;
  for (std::size_t i = 0; i < count; ++i) {
    gpu::ChangedKey k;
    std::memcpy(&k, static_cast<const unsigned char*>(out.data()) + sizeof(header) + i * sizeof(k),
                sizeof(k));
    actual.emplace_back(k.key_x, k.key_y, k.key_z, k.created != 0);
  }
  std::sort(actual.begin(), actual.end());
  EXPECT_EQ(actual, expected);
  // Too small by one entry: refused, nothing written.
  test::CallerBuffer small(vulkanHandles(ctx), changedKeysBytes(count));
  std::memset(small.data(), 0xAB, changedKeysBytes(count));
  BufferRange range = small.range();
  range.size = changedKeysBytes(count - 1);
  try {
    changedKeysOnDevice(map, range);
    ADD_FAILURE() << "a range one entry short was accepted";
  } catch (const Error& e) {
    EXPECT_EQ(e.code(), ErrorCode::kInvalidArgument) << e.what();
  }
  EXPECT_EQ(static_cast<const unsigned char*>(small.data())[0], 0xAB);
}

}  // namespace
}  // namespace octovk::test

namespace octovk::test {
namespace {

// A GPU consumer that waits on the device: octovk signals the caller's timeline semaphore once
// the change set (then a lookup batch) is in the caller's buffer; the consumer's submission waits
// for that value and copies the results on the device; what it copied is the answer.
TEST(ChangeDetectionApi, ConsumerWaitsOnTheSignalledValueOnTheDevice) {
  OCTOVK_REQUIRE_CONTEXT(ctx);
  const VulkanHandles vk = vulkanHandles(ctx);
  test::DeviceConsumer consumer(ctx, vk);
  const VkSemaphore timeline = consumer.timeline();
  const auto consume = [&](const test::CallerBuffer& from, const test::CallerBuffer& to,
                           VkDeviceSize bytes,
                           std::uint64_t value) { consumer.copyAfter(from, to, bytes, value); };

  OccupancyMap map(ctx, test::withResolution(0.1));
  map.enableChangeDetection(true);
  std::mt19937 rng(37);
  (void)map.insertPointCloud(test::randomScan(rng, Eigen::Vector3f::Zero(), 600, 2.0f),
                             Eigen::Vector3f::Zero());
  const std::size_t count = map.numChangesDetected();
  ASSERT_GT(count, 100u);
  const VkDeviceSize bytes = changedKeysBytes(count);
  test::CallerBuffer keys(vk, bytes), copy(vk, bytes);
  std::memset(copy.data(), 0, bytes);
  changedKeysOnDevice(map, keys.range(), SignalSemaphore{timeline, 7});
  consume(keys, copy, bytes, 7);
  EXPECT_EQ(std::memcmp(copy.data(), keys.data(), bytes), 0);
  gpu::ChangedKeysHeader header;
  std::memcpy(&header, copy.data(), sizeof(header));
  EXPECT_EQ(header.count, count);

  // The same for a lookup batch, to the next value.
  std::vector<Eigen::Vector3f> points;
  for (int i = 0; i < 64; ++i) points.emplace_back(0.05f * static_cast<float>(i), 0.0f, 0.0f);
  test::CallerBuffer in(vk, points.size() * 12), out(vk, points.size() * sizeof(gpu::LookupResult)),
      out_copy(vk, points.size() * sizeof(gpu::LookupResult));
  std::memcpy(in.data(), points.data(), points.size() * 12);
  searchOnDevice(map, in.range(), static_cast<std::uint32_t>(points.size()), out.range(),
                 SignalSemaphore{timeline, 8});
  consume(out, out_copy, points.size() * sizeof(gpu::LookupResult), 8);
  const std::vector<Lookup> want = map.search(points);
  const auto* got = static_cast<const gpu::LookupResult*>(out_copy.data());
  std::size_t known = 0;
  for (std::size_t i = 0; i < points.size(); ++i) {
    EXPECT_EQ(got[i].state, static_cast<std::uint32_t>(want[i].state)) << i;
    known += want[i].state != CellState::kUnknown;
  }
  EXPECT_GT(known, 3u);  // the 2 m sphere: the points inside it are free
}

}  // namespace
}  // namespace octovk::test
