// Depth images: unprojected on the device (shaders/unproject.comp), they give OctoMap's map of
// the points the formula gives, inserted with the camera pose.
#include <cmath>
#include <cstring>
#include <functional>
#include <limits>
#include <random>
#include <span>
#include <string>
#include <vector>

#include "test_support.hpp"

namespace octovk::test {
namespace {

// The formula of the issue, written out here independently of the library: z = d / scale,
// x = (u - cx) * z / fx, y = (v - cy) * z / fy, in float; no point where d is 0 or not finite
// (nor where d or z is subnormal, which the library also skips).
std::vector<Eigen::Vector3f> expectedPoints(const std::vector<float>& depth, std::uint32_t width,
                                            const DepthImage& cam, std::size_t* skipped) {
  std::vector<Eigen::Vector3f> out;
  *skipped = 0;
  for (std::size_t i = 0; i < depth.size(); ++i) {
    const float d = depth[i];
    const float z = d / cam.depth_scale;
    if (d == 0.0f || !std::isfinite(d) || !std::isnormal(d) || !std::isnormal(z)) {
      ++*skipped;
      continue;
    }
    const float u = static_cast<float>(i % width), v = static_cast<float>(i / width);
    const float xz = (u - cam.cx) * z;
    const float yz = (v - cam.cy) * z;
    out.emplace_back(xz / cam.fx, yz / cam.fy, z);
  }
  return out;
}

// A camera in a box-shaped room: depth of the wall each pixel sees, in metres, with holes.
std::vector<float> roomDepth(std::uint32_t w, std::uint32_t h, const DepthImage& cam,
                             std::mt19937& rng) {
  std::uniform_real_distribution<float> noise(-0.01f, 0.01f);
  std::uniform_int_distribution<int> hole(0, 19);
  std::vector<float> depth(std::size_t{w} * h);
  for (std::uint32_t v = 0; v < h; ++v)
    for (std::uint32_t u = 0; u < w; ++u) {
      const float dx = (static_cast<float>(u) - cam.cx) / cam.fx;
      const float dy = (static_cast<float>(v) - cam.cy) / cam.fy;
      // Walls at x = +-2, y = +-1.2, z = 3.5 in the camera frame.
      float z = 3.5f;
      if (std::abs(dx) > 1e-6f) z = std::min(z, 2.0f / std::abs(dx));
      if (std::abs(dy) > 1e-6f) z = std::min(z, 1.2f / std::abs(dy));
      depth[std::size_t{v} * w + u] = hole(rng) == 0 ? 0.0f : z + noise(rng);
    }
  return depth;
}

Pose cameraPose(std::mt19937& rng) {
  std::uniform_real_distribution<float> a(-0.6f, 0.6f), t(-0.5f, 0.5f);
  Pose pose;
  pose.rotation = Eigen::AngleAxisf(a(rng), Eigen::Vector3f::UnitZ()) *
                  Eigen::AngleAxisf(a(rng), Eigen::Vector3f::UnitY()) *
                  Eigen::AngleAxisf(a(rng), Eigen::Vector3f::UnitX());
  pose.translation = Eigen::Vector3f(t(rng), t(rng), t(rng));
  return pose;
}

TEST(DepthImage, HostUnprojectionIsTheFormula) {
  std::mt19937 rng(3);
  DepthImage cam;
  cam.width = 40;
  cam.height = 30;
  cam.fx = 35.5f;
  cam.fy = 36.25f;
  cam.cx = 19.5f;
  cam.cy = 14.75f;
  cam.depth_scale = 1.0f;
  cam.encoding = DepthImage::Encoding::kFloat32;
  std::vector<float> depth = roomDepth(cam.width, cam.height, cam, rng);
  depth[5] = std::numeric_limits<float>::quiet_NaN();
  depth[6] = std::numeric_limits<float>::infinity();
  depth[7] = -std::numeric_limits<float>::infinity();
  depth[8] = 1e-40f;  // subnormal
  depth[9] = -1.5f;   // behind the camera: a point like any other
  cam.depths = std::span<const float>(depth);
  std::size_t skipped_expected = 0, skipped = 0;
  const auto expected = expectedPoints(depth, cam.width, cam, &skipped_expected);
  const auto points = unprojectDepthImage(cam, &skipped);
  EXPECT_EQ(skipped, skipped_expected);
  ASSERT_EQ(points.size(), expected.size());
  for (std::size_t i = 0; i < points.size(); ++i)
    for (int c = 0; c < 3; ++c)
      ASSERT_EQ(test::floatBits(points[i][c]), test::floatBits(expected[i][c]))
          << "point " << i << " coordinate " << c;
}

struct DepthCase {
  std::uint32_t seed;
  double resolution;
  double max_range;
  bool uint16;
  bool discretize;
};

class DepthImageOracle : public ::testing::TestWithParam<DepthCase> {};

// Three images from three poses into one map: after each, OctoMap's map of the formula's points
// inserted with insertPointCloud(points, origin, pose), node by node, log-odds bits included.
TEST_P(DepthImageOracle, SameMapAsOctoMapAfterEveryImage) {
  OCTOVK_REQUIRE_CONTEXT(ctx);
  const DepthCase c = GetParam();
  const MapParams params = withResolution(c.resolution);
  OccupancyMap map(ctx, params);
  octomap::OcTree oracle = makeOracle(params);
  std::mt19937 rng(c.seed);
  DepthImage cam;
  cam.width = 64;
  cam.height = 48;
  cam.fx = 52.5f;
  cam.fy = 52.5f;
  cam.cx = 31.5f;
  cam.cy = 23.5f;
  for (int view = 0; view < 3; ++view) {
    std::vector<float> metres = roomDepth(cam.width, cam.height, cam, rng);
    std::vector<float> depth(metres.size());
    std::vector<std::uint16_t> raw(metres.size());
    if (c.uint16) {
      cam.encoding = DepthImage::Encoding::kUint16;
      cam.depth_scale = 5000.0f;
      for (std::size_t i = 0; i < metres.size(); ++i) {
        raw[i] = static_cast<std::uint16_t>(std::lround(metres[i] * 5000.0f));
        depth[i] = static_cast<float>(raw[i]);
      }
      cam.depths = std::span<const std::uint16_t>(raw);
    } else {
      cam.encoding = DepthImage::Encoding::kFloat32;
      cam.depth_scale = 1.0f;
      depth = metres;
      depth[10] = std::numeric_limits<float>::quiet_NaN();
      depth[11] = std::numeric_limits<float>::infinity();
      depth[12] = 1e-41f;
      cam.depths = std::span<const float>(depth);
    }
    const Pose pose = cameraPose(rng);
    const Eigen::Vector3f origin_camera(0.01f * static_cast<float>(view), 0.0f, 0.0f);
    std::size_t skipped = 0;
    const auto points = expectedPoints(depth, cam.width, cam, &skipped);
    oracle.insertPointCloud(toPointcloud(points), toPoint(origin_camera), toPose6D(pose),
                            c.max_range, false, c.discretize);
    const ScanStats stats = map.insertDepthImage(
        cam, pose, {.max_range_m = c.max_range, .discretize = c.discretize}, origin_camera);
    EXPECT_EQ(stats.points, std::size_t{cam.width} * cam.height);
    EXPECT_EQ(stats.skipped_no_depth, skipped) << "view " << view;
    EXPECT_EQ(stats.skipped_nonfinite, 0u) << "view " << view;
    EXPECT_GT(skipped, 0u);
    EXPECT_EQ(stats.nodes, oracle.size());
    auto ours = toOcTree(map);
    ASSERT_TRUE(sameTree(oracle, *ours)) << "after view " << view;
  }
}

INSTANTIATE_TEST_SUITE_P(Cases, DepthImageOracle,
                         ::testing::Values(DepthCase{1, 0.05, -1.0, true, false},
                                           DepthCase{2, 0.1, 3.0, false, false},
                                           DepthCase{3, 0.02, 2.5, true, false},
                                           DepthCase{4, 0.1, -1.0, false, true}),
                         [](const ::testing::TestParamInfo<DepthCase>& info) {
                           const DepthCase& c = info.param;
                           return "seed" + std::to_string(c.seed) + (c.uint16 ? "_u16" : "_f32") +
                                  (c.max_range < 0 ? "" : "_maxrange") +
                                  (c.discretize ? "_discretize" : "");
                         });

// The device's unprojection and the point-cloud overload with the host's points give the same
// map, and a point scan after a depth image (and the reverse) still agree: the two share buffers.
TEST(DepthImage, SameAsPointCloudOverloadAndMixesWithIt) {
  OCTOVK_REQUIRE_CONTEXT(ctx);
  const MapParams params = withResolution(0.05);
  OccupancyMap a(ctx, params), b(ctx, params);
  std::mt19937 rng(9);
  DepthImage cam;
  cam.width = 3;  // tiny: the depth buffer's staging is larger than the points'
  cam.height = 1;
  cam.encoding = DepthImage::Encoding::kUint16;
  const std::uint16_t tiny[3] = {5000, 0, 7000};
  cam.depths = std::span<const std::uint16_t>(tiny);
  const Pose pose = cameraPose(rng);
  a.insertDepthImage(cam, pose);
  b.insertPointCloud(unprojectDepthImage(cam), Eigen::Vector3f::Zero(), pose);
  const auto scan = test::randomScan(rng, Eigen::Vector3f::Zero(), 3000, 2.0f);
  a.insertPointCloud(scan, Eigen::Vector3f::Zero());
  b.insertPointCloud(scan, Eigen::Vector3f::Zero());
  cam.width = 64;
  cam.height = 48;
  std::vector<float> depth = roomDepth(64, 48, cam, rng);
  cam.encoding = DepthImage::Encoding::kFloat32;
  cam.depth_scale = 1.0f;
  cam.depths = std::span<const float>(depth);
  a.insertDepthImage(cam, pose);
  b.insertPointCloud(unprojectDepthImage(cam), Eigen::Vector3f::Zero(), pose);
  ASSERT_TRUE(sameTree(*toOcTree(b), *toOcTree(a)));
}

TEST(DepthImage, BadImagesAreRefusedAndTheMapIsUnchanged) {
  OCTOVK_REQUIRE_CONTEXT(ctx);
  OccupancyMap map(ctx, withResolution(0.1));
  const std::uint16_t pixels[4] = {1000, 2000, 3000, 4000};
  DepthImage good;
  good.width = 2;
  good.height = 2;
  good.depths = std::span<const std::uint16_t>(pixels);
  map.insertDepthImage(good, Pose{});
  const std::size_t nodes = map.nodeCount();
  ASSERT_GT(nodes, 0u);
  auto refused = [&](DepthImage image, const std::string& names) {
    try {
      map.insertDepthImage(image, Pose{});
    } catch (const Error& e) {
      EXPECT_EQ(e.code(), ErrorCode::kInvalidArgument);
      EXPECT_NE(std::string(e.what()).find(names), std::string::npos) << e.what();
      return;
    }
    ADD_FAILURE() << "accepted a bad image (" << names << ")";
  };
  DepthImage bad = good;
  bad.width = 0;
  refused(bad, "empty");
  bad = good;
  bad.depths = {};
  refused(bad, "no depths (DepthImage::depths is empty)");
  bad = good;
  bad.fx = 0.0f;
  refused(bad, "fx");
  bad = good;
  bad.cy = std::numeric_limits<float>::quiet_NaN();
  refused(bad, "cx, cy");
  bad = good;
  bad.depth_scale = -5000.0f;
  refused(bad, "depth_scale");
  bad = good;
  bad.encoding = static_cast<DepthImage::Encoding>(7);
  refused(bad, "encoding");
  Pose nan_pose;
  nan_pose.translation.x() = std::numeric_limits<float>::quiet_NaN();
  EXPECT_THROW(map.insertDepthImage(good, nan_pose), Error);
  EXPECT_EQ(map.nodeCount(), nodes);
}

// The depths are a typed, sized view: a buffer shorter (or longer) than width * height, or of the
// other type than the encoding, is refused by every call that reads it, naming the sizes or the
// fix; the map is unchanged (a void pointer was read past its end, or as the wrong type).
TEST(DepthImage, ShortBufferAndWrongEncodingAreRefused) {
  OCTOVK_REQUIRE_CONTEXT(ctx);
  OccupancyMap map(ctx, withResolution(0.1));
  const std::vector<std::uint16_t> raw(4 * 3, 5000);
  const std::vector<float> metres(4 * 3, 1.0f);
  DepthImage good{.width = 4, .height = 3, .depths = std::span<const std::uint16_t>(raw)};
  map.insertDepthImage(good, Pose{});
  const std::size_t nodes = map.nodeCount();
  auto refused = [&](const DepthImage& image, const std::vector<std::string>& words) {
    const std::function<void()> calls[] = {[&] { map.insertDepthImage(image, Pose{}); },
                                           [&] { map.submitDepthImage(image, Pose{}); },
                                           [&] { (void)unprojectDepthImage(image); }};
    for (const auto& call : calls) {
      try {
        call();
        ADD_FAILURE() << "accepted: " << words.front();
      } catch (const Error& e) {
        EXPECT_EQ(e.code(), ErrorCode::kInvalidArgument);
        for (const std::string& w : words)
          EXPECT_NE(std::string(e.what()).find(w), std::string::npos) << e.what();
      }
    }
    EXPECT_EQ(image.validate().empty(), false);
  };
  DepthImage bad = good;
  bad.depths = std::span<const std::uint16_t>(raw).first(11);
  refused(bad, {"4 x 3 = 12 pixels", "holds 11 std::uint16_t depths", "short"});
  bad.depths = std::span<const std::uint16_t>(raw.data(), 0);
  refused(bad, {"holds 0 std::uint16_t depths"});
  bad = good;
  bad.height = 4;  // the same buffer, one row too few
  refused(bad, {"4 x 4 = 16 pixels", "holds 12"});
  bad = good;
  bad.width = 2;  // more depths than pixels: the wrong width, not a crop
  refused(bad, {"2 x 3 = 6 pixels", "holds 12"});
  bad = good;
  bad.depths = std::span<const float>(metres);  // encoding left at kUint16
  refused(bad, {"depths are float but its encoding is kUint16",
                "set encoding = DepthImage::Encoding::kFloat32"});
  bad.encoding = DepthImage::Encoding::kFloat32;
  bad.depths = std::span<const std::uint16_t>(raw);
  refused(bad, {"depths are std::uint16_t but its encoding is kFloat32", "kUint16"});
  map.flush();
  EXPECT_EQ(map.nodeCount(), nodes);
  // Given as they are, both are accepted.
  bad.depths = std::span<const float>(metres);
  bad.depth_scale = 1.0f;
  EXPECT_TRUE(bad.validate().empty()) << bad.validate();
  EXPECT_EQ(unprojectDepthImage(bad), unprojectDepthImage(good));
}

}  // namespace
}  // namespace octovk::test
