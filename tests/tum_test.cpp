// tum_test: TUM RGB-D folders. A small synthetic sequence (a box-shaped room seen from a moving
// camera, 16-bit PNG depth images written here with libpng, depth.txt and groundtruth.txt with
// TUM's comments and precision) is read by the library, converted to a scan graph with
// `octovk convert`, and integrated with `octovk integrate DIR`: the maps must be byte-identical
// to graph2tree's on the converted graph. Bad folders give one error line and no file.
#include <fcntl.h>
#include <gtest/gtest.h>
#include <octomap/OcTree.h>
#include <octomap/ScanGraph.h>
#include <png.h>
#include <sys/resource.h>
#include <sys/wait.h>
#include <unistd.h>
#include <zlib.h>

#include <algorithm>
#include <array>
#include <chrono>
#include <cmath>
#include <csetjmp>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <iomanip>
#include <sstream>
#include <string>
#include <vector>

#include "cli_support.hpp"
#include "io/tum_parse.hpp"
#include "octovk/octomap_io.hpp"
#include "octovk/tum_sequence.hpp"
#include "png_writer.hpp"
#include "test_support.hpp"

namespace octovk::test {
namespace {

namespace fs = std::filesystem;

// ---- PNG files, written with libpng's full API (big-endian samples built here, no swap) ----

// `samples` per pixel (1 gray, 3 RGB), each `bit_depth` bits; 16-bit values stored big-endian.
void writePng(const fs::path& path, std::uint32_t width, std::uint32_t height, int bit_depth,
              int color_type, const std::vector<std::uint16_t>& values,
              int interlace = PNG_INTERLACE_NONE) {
  const std::size_t samples = color_type == PNG_COLOR_TYPE_RGB ? 3 : 1;
  const std::size_t bytes = bit_depth == 16 ? 2 : 1;
  const std::size_t row_bytes = width * samples * bytes;
  std::vector<unsigned char> data(row_bytes * height);
  for (std::size_t i = 0; i < values.size(); ++i) {
    if (bytes == 2) {
      data[2 * i] = static_cast<unsigned char>(values[i] >> 8);
      data[2 * i + 1] = static_cast<unsigned char>(values[i] & 0xFF);
    } else {
      data[i] = static_cast<unsigned char>(values[i]);
    }
  }
  std::vector<png_bytep> rows(height);
  for (std::uint32_t y = 0; y < height; ++y) rows[y] = data.data() + y * row_bytes;
  ASSERT_TRUE(
      writePngRows(path.c_str(), width, height, bit_depth, color_type, interlace, rows.data()))
      << path;
}

void writeDepthPng(const fs::path& path, std::uint32_t width, std::uint32_t height,
                   const std::vector<std::uint16_t>& depths, int interlace = PNG_INTERLACE_NONE) {
  writePng(path, width, height, 16, PNG_COLOR_TYPE_GRAY, depths, interlace);
}

// ---- the synthetic sequence ----

constexpr std::uint32_t kWidth = 64;
constexpr std::uint32_t kHeight = 48;

struct Camera {
  float fx = 50.0f, fy = 52.0f, cx = 31.5f, cy = 23.25f, scale = 5000.0f;
};

struct Sequence {
  fs::path dir;
  Camera camera;
  std::vector<std::string> image_times;  // as written in depth.txt
  std::vector<std::string> image_files;  // relative to dir
  std::vector<std::vector<std::uint16_t>> depths;
  std::vector<std::array<std::string, 8>> poses;  // groundtruth.txt's fields as written
};

// Camera to world at time s (seconds since the start), with TUM's optical frame (z forward).
Eigen::Matrix3d rotationAt(double s) {
  const Eigen::Matrix3d optical_to_body =
      (Eigen::Matrix3d() << 0, 0, 1, -1, 0, 0, 0, -1, 0).finished();
  return (Eigen::AngleAxisd(0.2 + 4.0 * s, Eigen::Vector3d::UnitZ()) *
          Eigen::AngleAxisd(0.25 * std::sin(9.0 * s), Eigen::Vector3d::UnitY()) *
          Eigen::AngleAxisd(0.15 - 0.5 * s, Eigen::Vector3d::UnitX()))
             .toRotationMatrix() *
         optical_to_body;
}

Eigen::Vector3d positionAt(double s) {
  return {0.4 * std::sin(3.0 * s), 0.3 * std::cos(2.0 * s) - 0.1, 0.35 + 0.5 * s};
}

std::string fixed(double v, int decimals) {
  std::ostringstream s;
  s << std::fixed << std::setprecision(decimals) << v;
  return s.str();
}

// Five images 1/30 s apart; ground truth at 100 Hz with a gap around the third image, which is
// therefore skipped. Depths: the distance to the walls of a box-shaped room, with holes (0).
Sequence makeSequence(const fs::path& dir, const Camera& camera = {}) {
  Sequence seq;
  seq.dir = dir;
  seq.camera = camera;
  fs::create_directories(dir / "depth");
  const double t0 = 1305031102.175304;
  const Eigen::Vector3d room_min(-2.5, -2.0, -1.0), room_max(3.0, 2.2, 1.6);
  std::ofstream depth_txt(dir / "depth.txt");
  depth_txt << "# depth maps\n# file: 'synthetic.bag'\n# timestamp filename\n";
  for (int k = 0; k < 5; ++k) {
    const double s = 0.0333 * k;
    const std::string stamp = fixed(t0 + s, 6);
    seq.image_times.push_back(stamp);
    seq.image_files.push_back("depth/" + stamp + ".png");
    depth_txt << stamp << " " << seq.image_files.back() << "\n";
    if (k == 1) depth_txt << "\n";  // blank lines are allowed
    const Eigen::Matrix3d r = rotationAt(s);
    const Eigen::Vector3d o = positionAt(s);
    std::vector<std::uint16_t> depths(kWidth * kHeight);
    for (std::uint32_t v = 0; v < kHeight; ++v) {
      for (std::uint32_t u = 0; u < kWidth; ++u) {
        const Eigen::Vector3d ray_camera((u - double{camera.cx}) / camera.fx,
                                         (v - double{camera.cy}) / camera.fy, 1.0);
        const Eigen::Vector3d d = r * ray_camera;
        double t = 1e9;
        for (int i = 0; i < 3; ++i) {
          if (d[i] > 0) t = std::min(t, (room_max[i] - o[i]) / d[i]);
          if (d[i] < 0) t = std::min(t, (room_min[i] - o[i]) / d[i]);
        }
        const double raw = std::round(t * camera.scale);  // t is the depth: ray_camera.z = 1
        const bool hole = (u + 3 * v) % 11 == 0 || (u >= 10 && u < 14 && v >= 5 && v < 9);
        depths[v * kWidth + u] = hole || raw > 65535.0 ? 0 : static_cast<std::uint16_t>(raw);
      }
    }
    writeDepthPng(dir / seq.image_files.back(), kWidth, kHeight, depths);
    seq.depths.push_back(std::move(depths));
  }
  std::ofstream gt(dir / "groundtruth.txt");
  gt << "# ground truth trajectory\n# file: 'synthetic.bag'\n# timestamp tx ty tz qx qy qz qw\n";
  const double third = 2 * 0.0333;
  for (int j = 0; j < 40; ++j) {
    const double s = -0.05 + 0.01 * j + 0.0013;
    if (std::abs(s - third) < 0.035) continue;
    const Eigen::Quaterniond q(rotationAt(s));
    const Eigen::Vector3d p = positionAt(s);
    // TUM writes 4 decimals: the quaternion is unit only to about 1e-4.
    std::array<std::string, 8> f = {fixed(t0 + s, 4), fixed(p.x(), 4), fixed(p.y(), 4),
                                    fixed(p.z(), 4),  fixed(q.x(), 4), fixed(q.y(), 4),
                                    fixed(q.z(), 4),  fixed(q.w(), 4)};
    gt << f[0] << " " << f[1] << " " << f[2] << " " << f[3] << " " << f[4] << " " << f[5] << " "
       << f[6] << " " << f[7] << "\n";
    seq.poses.push_back(f);
  }
  return seq;
}

// The pose as the test reads groundtruth.txt: float values (strtof), Pose6D's argument order.
octovk::Pose expectedPose(const std::array<std::string, 8>& f) {
  const auto v = [&](int i) {
    return std::strtof(f[static_cast<std::size_t>(i)].c_str(), nullptr);
  };
  octovk::Pose pose;
  pose.translation = {v(1), v(2), v(3)};
  pose.rotation = Eigen::Quaternionf(v(7), v(4), v(5), v(6));
  return pose;
}

// Index of the pose nearest in time to image k (brute force), or -1 when none is < 0.02 s away.
int nearestPose(const Sequence& seq, std::size_t k) {
  const double t = std::strtod(seq.image_times[k].c_str(), nullptr);
  int best = -1;
  double best_gap = 0.02;
  for (std::size_t j = 0; j < seq.poses.size(); ++j) {
    const double gap = std::abs(std::strtod(seq.poses[j][0].c_str(), nullptr) - t);
    if (gap < best_gap) {
      best_gap = gap;
      best = static_cast<int>(j);
    }
  }
  return best;
}

// The camera-frame points of image k, computed here: z = d / s, x = (u - cx) z / fx, ... (float).
std::vector<Eigen::Vector3f> expectedPoints(const Sequence& seq, std::size_t k) {
  std::vector<Eigen::Vector3f> points;
  const Camera& c = seq.camera;
  for (std::uint32_t v = 0; v < kHeight; ++v)
    for (std::uint32_t u = 0; u < kWidth; ++u) {
      const std::uint16_t d = seq.depths[k][v * kWidth + u];
      if (d == 0) continue;
      const float z = static_cast<float>(d) / c.scale;
      points.emplace_back((static_cast<float>(u) - c.cx) * z / c.fx,
                          (static_cast<float>(v) - c.cy) * z / c.fy, z);
    }
  return points;
}

octovk::CameraIntrinsics intrinsics(const Camera& c) { return {c.fx, c.fy, c.cx, c.cy, c.scale}; }

std::vector<std::string> cameraArgs(const Camera& c) {
  const auto text = [](float v) {
    std::ostringstream s;
    s << std::setprecision(9) << v;
    return s.str();
  };
  return {"--intrinsics", text(c.fx),      text(c.fy),   text(c.cx),
          text(c.cy),     "--depth-scale", text(c.scale)};
}

bool sameBits(const Eigen::Vector3f& a, const Eigen::Vector3f& b) {
  return std::memcmp(a.data(), b.data(), sizeof(float) * 3) == 0;
}

// ---- the reader ----

TEST(TumReader, MatchesImagesToTheNearestPose) {
  Scratch scratch("tum");
  const Sequence seq = makeSequence(scratch.dir() / "seq");
  const octovk::TumSequence read = octovk::readTumSequence(seq.dir.string());
  EXPECT_EQ(read.images_listed, 5u);
  EXPECT_EQ(read.poses, seq.poses.size());
  EXPECT_EQ(read.skipped_no_pose, 1u);
  ASSERT_EQ(read.frames.size(), 4u);
  std::size_t f = 0;
  int before = 0, after = 0;
  for (std::size_t k = 0; k < seq.image_times.size(); ++k) {
    const int j = nearestPose(seq, k);
    if (j < 0) {
      EXPECT_EQ(k, 2u) << "the synthetic sequence leaves only the third image without a pose";
      continue;
    }
    ASSERT_LT(f, read.frames.size());
    const octovk::TumFrame& frame = read.frames[f++];
    EXPECT_EQ(frame.image_path, (seq.dir / seq.image_files[k]).string());
    EXPECT_EQ(frame.timestamp, std::strtod(seq.image_times[k].c_str(), nullptr));
    const double pose_time =
        std::strtod(seq.poses[static_cast<std::size_t>(j)][0].c_str(), nullptr);
    EXPECT_EQ(frame.pose_timestamp, pose_time) << "image " << k;
    (pose_time < frame.timestamp ? before : after)++;
    const octovk::Pose expected = expectedPose(seq.poses[static_cast<std::size_t>(j)]);
    EXPECT_TRUE(sameBits(frame.T_world_camera.translation, expected.translation));
    EXPECT_EQ(frame.T_world_camera.rotation.coeffs(), expected.rotation.coeffs());
  }
  // The nearest pose is sometimes the earlier one, sometimes the later one.
  EXPECT_GT(before, 0);
  EXPECT_GT(after, 0);
}

TEST(TumReader, PoseIsOctomapPose6D) {
  // octovk::Pose from groundtruth.txt's floats must move points exactly as
  // Pose6D(Vector3(tx, ty, tz), Quaternion(qw, qx, qy, qz)) does, unnormalised quaternion and all,
  // and give graph2tree's sensor origin.
  Scratch scratch("tum");
  const Sequence seq = makeSequence(scratch.dir() / "seq");
  const octovk::TumSequence read = octovk::readTumSequence(seq.dir.string());
  std::size_t unnormalised = 0;
  for (const octovk::TumFrame& frame : read.frames) {
    const octovk::Pose& pose = frame.T_world_camera;
    const octomath::Pose6D pose6d = octovk::test::toPose6D(pose);
    if (pose.rotation.norm() != 1.0f) ++unnormalised;
    for (const Eigen::Vector3f& p :
         {Eigen::Vector3f(0.5f, -1.25f, 3.0f), Eigen::Vector3f(-2.0f, 0.3f, 0.7f),
          Eigen::Vector3f(1e-3f, 4.5f, -0.25f)}) {
      const octomap::point3d q = pose6d.transform(octomap::point3d(p.x(), p.y(), p.z()));
      EXPECT_TRUE(sameBits(pose.transform(p), Eigen::Vector3f(q.x(), q.y(), q.z())));
    }
    const octomap::point3d origin = pose6d.inv().transform(pose6d.trans());
    EXPECT_TRUE(sameBits(octovk::graph2treeSensorOrigin(pose),
                         Eigen::Vector3f(origin.x(), origin.y(), origin.z())));
  }
  EXPECT_GT(unnormalised, 0u) << "4-decimal quaternions should not all be unit in float";
}

TEST(TumReader, ReadsSixteenBitPngsInHostOrder) {
  Scratch scratch("tum");
  std::vector<std::uint16_t> depths(7 * 5);
  for (std::size_t i = 0; i < depths.size(); ++i)
    depths[i] = static_cast<std::uint16_t>(0x0102 * (i + 1) + (i % 3 == 0 ? 0xF000 : 0));
  for (const int interlace : {PNG_INTERLACE_NONE, PNG_INTERLACE_ADAM7}) {
    const fs::path path = scratch.dir() / ("d" + std::to_string(interlace) + ".png");
    writeDepthPng(path, 7, 5, depths, interlace);
    const octovk::DepthPng png = octovk::readDepthPng(path.string());
    EXPECT_EQ(png.width, 7u);
    EXPECT_EQ(png.height, 5u);
    EXPECT_EQ(png.depths, depths) << "interlace " << interlace;
    const octovk::DepthImage image = png.image({1.0f, 2.0f, 3.0f, 4.0f, 10.0f});
    const auto* view = std::get_if<std::span<const std::uint16_t>>(&image.depths);
    ASSERT_NE(view, nullptr);
    EXPECT_EQ(view->data(), png.depths.data());
    EXPECT_EQ(view->size(), png.depths.size());
    EXPECT_EQ(image.encoding, octovk::DepthImage::Encoding::kUint16);
    EXPECT_EQ(image.fy, 2.0f);
    EXPECT_EQ(image.depth_scale, 10.0f);
  }
}

TEST(TumReader, RefusesOtherPngFormats) {
  Scratch scratch("tum");
  const std::vector<std::uint16_t> gray(4 * 3, 100), rgb(4 * 3 * 3, 100);
  writePng(scratch.dir() / "gray8.png", 4, 3, 8, PNG_COLOR_TYPE_GRAY, gray);
  writePng(scratch.dir() / "rgb16.png", 4, 3, 16, PNG_COLOR_TYPE_RGB, rgb);
  writePng(scratch.dir() / "rgb8.png", 4, 3, 8, PNG_COLOR_TYPE_RGB, rgb);
  std::ofstream(scratch.dir() / "text.png") << "not a png at all";
  const std::string whole = readFile(scratch.dir() / "rgb16.png");
  std::ofstream(scratch.dir() / "cut.png", std::ios_base::binary) << whole.substr(0, 40);
  const auto message = [&](const std::string& name) -> std::string {
    try {
      octovk::readDepthPng((scratch.dir() / name).string());
    } catch (const octovk::Error& e) {
      EXPECT_EQ(e.code(), octovk::ErrorCode::kFormat) << e.what();
      return e.what();
    }
    ADD_FAILURE() << name << " was accepted";
    return "";
  };
  for (const auto& [name, words] : std::vector<std::pair<std::string, std::string>>{
           {"gray8.png", "grayscale PNG of bit depth 8"},
           {"rgb16.png", "RGB colour PNG of bit depth 16"},
           {"rgb8.png", "RGB colour PNG of bit depth 8"},
           {"text.png", "not a PNG"},
           {"cut.png", "corrupt or truncated"}}) {
    const std::string why = message(name);
    EXPECT_NE(why.find(name), std::string::npos) << why;
    EXPECT_NE(why.find(words), std::string::npos) << why;
    EXPECT_EQ(why.find('\n'), std::string::npos) << why;
  }
  try {
    octovk::readDepthPng((scratch.dir() / "missing.png").string());
    ADD_FAILURE() << "a missing file was accepted";
  } catch (const octovk::Error& e) {
    EXPECT_EQ(e.code(), octovk::ErrorCode::kIo);
    EXPECT_NE(std::string(e.what()).find("missing.png"), std::string::npos) << e.what();
  }
}

// A copy of the PNG `bytes` whose header (IHDR, the first chunk) announces `width` x `height`,
// its checksum recomputed: only the pixel data that follows gives it away.
std::string withHeaderSize(std::string bytes, std::uint32_t width, std::uint32_t height) {
  EXPECT_EQ(bytes.substr(12, 4), "IHDR");
  for (int i = 0; i < 4; ++i) {
    bytes[16 + i] = static_cast<char>(width >> (24 - 8 * i));
    bytes[20 + i] = static_cast<char>(height >> (24 - 8 * i));
  }
  const uLong crc = ::crc32(0L, reinterpret_cast<const Bytef*>(bytes.data() + 12), 4 + 13);
  for (int i = 0; i < 4; ++i) bytes[29 + i] = static_cast<char>(crc >> (24 - 8 * i));
  return bytes;
}

// The message of the kFormat error `read` throws ("" and a failure when it throws none).
template <class Read>
std::string formatError(Read read) {
  try {
    read();
  } catch (const octovk::Error& e) {
    EXPECT_EQ(e.code(), octovk::ErrorCode::kFormat) << e.what();
    return e.what();
  }
  ADD_FAILURE() << "accepted";
  return "";
}

TEST(TumReader, RefusesAPngAnnouncingMorePixelsThanItsBytesHold) {
  // A PNG of under 100 bytes claiming 65536 x 65536 16-bit pixels used to be given an 8 GiB
  // buffer before libpng found its data cut short (seen while writing fuzz_depth_png): now the
  // header is refused, since deflate cannot shrink 8 GiB into 100 bytes.
  Scratch scratch("tum");
  const fs::path small = scratch.dir() / "small.png";
  writeDepthPng(small, 4, 3, std::vector<std::uint16_t>(12, 5000));
  const std::string huge = withHeaderSize(readFile(small), 65536, 65536);
  const fs::path path = scratch.dir() / "huge.png";
  std::ofstream(path, std::ios_base::binary) << huge;
  for (const std::string& why :
       {formatError([&] { octovk::readDepthPng(path.string()); }),
        formatError([&] { octovk::checkDepthPng(path.string()); }),
        formatError([&] { octovk::io::decodeDepthPng(huge, path.string()); })}) {
    EXPECT_NE(why.find("'" + path.string() + "'"), std::string::npos) << why;
    EXPECT_NE(why.find("65536 x 65536"), std::string::npos) << why;
    EXPECT_NE(why.find("corrupt or truncated"), std::string::npos) << why;
  }
  // A large image of one depth compresses about as far as deflate can, and is still read.
  const fs::path flat = scratch.dir() / "flat.png";
  writeDepthPng(flat, 2000, 1000, std::vector<std::uint16_t>(2000 * 1000, 0));
  EXPECT_LT(fs::file_size(flat), 2u * 2000 * 1000 / 100) << "not the compression this test needs";
  const octovk::DepthPng read = octovk::readDepthPng(flat.string());
  EXPECT_EQ(read.depths, std::vector<std::uint16_t>(2000 * 1000, 0));
}

TEST(TumReader, RefusesAHugeChunkWithoutAllocatingIt) {
  Scratch scratch("tum");
  const std::string bytes = octovk::test::hugeTextChunkPng();
  ASSERT_EQ(bytes.size(), 2475u);
  // The fuzz targets' regression corpus holds the same file (tests/fuzz/make_corpus.cpp).
  EXPECT_EQ(readFile(fs::path(OCTOVK_PATH(OCTOVK_SHARED_DATA_DIR)) /
                     "../fuzz/corpus/depth_png/text_chunk_2gib.png"),
            bytes);
  const fs::path path = scratch.dir() / "text.png";
  std::ofstream(path, std::ios_base::binary) << bytes;
  const auto start = std::chrono::steady_clock::now();
  for (const std::string& why :
       {formatError([&] { octovk::readDepthPng(path.string()); }),
        formatError([&] { octovk::checkDepthPng(path.string()); }),
        formatError([&] { octovk::io::decodeDepthPng(bytes, path.string()); })}) {
    EXPECT_NE(why.find("'" + path.string() + "'"), std::string::npos) << why;
    EXPECT_NE(why.find("corrupt or truncated"), std::string::npos) << why;
  }
  // Three reads that each allocated and touched 2 GiB took seconds; now they take microseconds.
  EXPECT_LT(std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count(), 1.0);
  // An ancillary chunk of honest length is skipped, and the image still read.
  const fs::path small = scratch.dir() / "small.png";
  writeDepthPng(small, 4, 3, std::vector<std::uint16_t>(12, 5000));
  std::string with_text = readFile(small);
  const std::size_t idat = with_text.find("IDAT") - 4;
  std::string text;
  octovk::test::appendPngChunk(text, "tEXt", std::string("Comment\0hello", 13), 13);
  with_text.insert(idat, text);
  EXPECT_EQ(octovk::io::decodeDepthPng(with_text, "text").depths,
            std::vector<std::uint16_t>(12, 5000));
}

TEST(TumCli, HugeChunkIsACheapCleanError) {
  // The hostile PNG in a folder: integrate refuses it while checking the images, before any
  // Vulkan work, in well under a second and 200 MB (it took 2.1 GB and 7-9 s).
  Scratch scratch("tum");
  const Sequence seq = makeSequence(scratch.dir() / "seq");
  std::ofstream(seq.dir / seq.image_files[1], std::ios_base::binary | std::ios_base::trunc)
      << octovk::test::hugeTextChunkPng();
  const test::RunResult m =
      test::runMeasured({"integrate", seq.dir.string(), "-o", scratch / "map.bt"}, scratch.dir());
  test::expectOneErrorLine(m, 1, {seq.image_files[1], "corrupt or truncated"});
  EXPECT_LT(m.max_rss_kb, 200 * 1024) << "peak RSS of the run";
  EXPECT_LT(m.cpu_s, 1.0) << "CPU time of the run";
  EXPECT_FALSE(fs::exists(scratch / "map.bt"));
}

// A 16-bit PNG whose header announces `side` x `side` pixels, with an honest ancillary chunk
// large enough that deflate could hold them (so only a size limit refuses it from its header).
std::string paddedHugePng(const fs::path& scratch_dir, std::uint32_t side) {
  const fs::path small = scratch_dir / "small_for_huge.png";
  writeDepthPng(small, 4, 3, std::vector<std::uint16_t>(12, 5000));
  std::string png = withHeaderSize(readFile(small), side, side);
  const std::uint64_t raw = std::uint64_t{side} * (1 + 2 * std::uint64_t{side});
  const auto padding = static_cast<std::uint32_t>(raw / octovk::io::kDeflateMaxRatio + 20000);
  std::string text;
  octovk::test::appendPngChunk(
      text, "tEXt", "Comment" + std::string(1, '\0') + std::string(padding, 'x'), padding + 8);
  png.insert(png.find("IDAT") - 4, text);
  return png;
}

TEST(TumReader, ImageLargerThanTheLimitIsRefusedFromItsHeader) {
  // A 530 kB PNG of 16000 x 16000 was decoded whole (554 MB, 2 s) before integrate refused its
  // 256 million points: now its header is checked against the limit first.
  Scratch scratch("tum");
  const fs::path path = scratch.dir() / "huge.png";
  std::ofstream(path, std::ios_base::binary) << paddedHugePng(scratch.dir(), 16000);
  const octovk::DepthPngSize size = octovk::checkDepthPng(path.string());
  EXPECT_EQ(size.width, 16000u);
  EXPECT_EQ(size.height, 16000u);
  const auto start = std::chrono::steady_clock::now();
  for (int check = 0; check < 2; ++check) {
    try {
      if (check == 0)
        octovk::readDepthPng(path.string(), 4194240);
      else
        octovk::checkDepthPng(path.string(), 4194240);
      ADD_FAILURE() << "an image over the limit was accepted";
    } catch (const octovk::Error& e) {
      const std::string why = e.what();
      EXPECT_EQ(e.code(), octovk::ErrorCode::kInvalidArgument) << why;
      EXPECT_NE(why.find(path.string()), std::string::npos) << why;
      EXPECT_NE(why.find("16000 x 16000 = 256000000 pixels"), std::string::npos) << why;
      EXPECT_NE(why.find("at most 4194240"), std::string::npos) << why;
    }
  }
  EXPECT_LT(std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count(), 0.5);
  // At the limit, an image is read.
  const fs::path small = scratch.dir() / "small.png";
  writeDepthPng(small, 4, 3, std::vector<std::uint16_t>(12, 5000));
  EXPECT_EQ(octovk::readDepthPng(small.string(), 12).depths.size(), 12u);
}

TEST(TumCli, ImageLargerThanTheDeviceTakesIsACheapCleanError) {
  // integrate: refused by the device's limit on a scan's points, from the header (it decoded
  // 554 MB first). convert under `ulimit -v 4G`: refused by the host memory converting it needs
  // (it reached 3.4 GB, then "unexpected failure: std::bad_alloc").
  OCTOVK_REQUIRE_CONTEXT(ctx);
  Scratch scratch("tum");
  const Sequence seq = makeSequence(scratch.dir() / "seq");
  // 16000 x 16000 (lavapipe takes 4,194,240 points), or a square just over the device's limit.
  const std::uint64_t limit = octovk::maxDepthImagePixels(ctx);
  std::uint32_t side = 16000;
  while (std::uint64_t{side} * side <= limit) ++side;
  std::ofstream(seq.dir / seq.image_files[1], std::ios_base::binary | std::ios_base::trunc)
      << paddedHugePng(scratch.dir(), side);
  const test::RunResult m =
      test::runMeasured({"integrate", seq.dir.string(), "-o", scratch / "map.bt"}, scratch.dir());
  test::expectOneErrorLine(m, 1, {seq.image_files[1], "at most " + std::to_string(limit)});
  if (!octovk::test::kAddressSanitizer) {
    EXPECT_LT(m.max_rss_kb, 400 * 1024) << "peak RSS of the run";
  }
  EXPECT_FALSE(fs::exists(scratch / "map.bt"));
  if (octovk::test::kAddressSanitizer)
    return;  // ulimit -v stops an ASan program at start (test_support.hpp)
  const RunResult r =
      runShell("ulimit -v 4194304; " + quote(OCTOVK_PATH(OCTOVK_CLI)) + " convert " +
                   quote(seq.dir.string()) + " -o " + quote(scratch / "scans.graph"),
               scratch.dir());
  EXPECT_EQ(r.exit_code, 1) << r.err;
  EXPECT_EQ(r.err.rfind("octovk: error: ", 0), 0u) << r.err;
  EXPECT_EQ(std::count(r.err.begin(), r.err.end(), '\n'), 1) << r.err;
  EXPECT_NE(r.err.find(seq.image_files[1]), std::string::npos) << r.err;
  EXPECT_NE(r.err.find("host memory"), std::string::npos) << r.err;
  EXPECT_FALSE(fs::exists(scratch / "scans.graph"));
}

TEST(TumCli, SparseListsAreACheapCleanError) {
  // depth.txt or groundtruth.txt of 1 GiB of zeros (a sparse file): read whole before their
  // first line was parsed (and one of 10 GiB under `ulimit -v 4G` ended in "unexpected failure:
  // std::bad_alloc"). Now they are read a line at a time, and a line too long for a list fails.
  Scratch scratch("tum");
  for (const char* list : {"depth.txt", "groundtruth.txt"}) {
    SCOPED_TRACE(list);
    const Sequence seq = makeSequence(scratch.dir() / (std::string("seq_") + list));
    std::ofstream(seq.dir / list, std::ios_base::trunc).close();
    fs::resize_file(seq.dir / list, std::uintmax_t{1} << 30);
    const test::RunResult m = test::runMeasured(
        {"convert", seq.dir.string(), "-o", scratch / "scans.graph"}, scratch.dir());
    test::expectOneErrorLine(m, 1, {std::string(list) + "' line 1 is longer than 65536 bytes"});
    if (!octovk::test::kAddressSanitizer) {  // ASan's memory and time are not the program's
                                             // (test_support.hpp)
      EXPECT_LT(m.max_rss_kb, 100 * 1024) << "peak RSS of the run";
      EXPECT_LT(m.cpu_s, 1.0) << "CPU time of the run";
    }
    fs::resize_file(seq.dir / list, std::uintmax_t{10} << 30);
    if (octovk::test::kAddressSanitizer) {
      fs::remove_all(seq.dir);
      continue;  // ulimit -v stops an ASan program at start
    }
    const RunResult r =
        runShell("ulimit -v 4194304; " + quote(OCTOVK_PATH(OCTOVK_CLI)) + " convert " +
                     quote(seq.dir.string()) + " -o " + quote(scratch / "scans.graph"),
                 scratch.dir());
    EXPECT_EQ(r.exit_code, 1) << r.err;
    EXPECT_NE(r.err.find("longer than 65536 bytes"), std::string::npos) << r.err;
    EXPECT_FALSE(fs::exists(scratch / "scans.graph"));
    fs::remove_all(seq.dir);
  }
}

TEST(TumReader, BytesInReadersMatchTheFileReaders) {
  // io::parseGroundTruth + io::associateDepthList and io::decodeDepthPng (the fuzz targets'
  // entry points) give what readTumSequence and readDepthPng give on the files.
  Scratch scratch("tum");
  const Sequence seq = makeSequence(scratch.dir() / "seq");
  const octovk::TumSequence files = octovk::readTumSequence(seq.dir.string());
  const octovk::io::TumListNames names{seq.dir.string(), (seq.dir / "depth.txt").string(),
                                       (seq.dir / "groundtruth.txt").string()};
  std::vector<std::string> taken;
  const octovk::TumSequence bytes = octovk::io::associateDepthList(
      readFile(seq.dir / "depth.txt"),
      octovk::io::parseGroundTruth(readFile(seq.dir / "groundtruth.txt"), names.groundtruth), names,
      octovk::kTumMaxTimeDifference,
      [&](const octovk::TumFrame& frame) { taken.push_back(frame.image_path); });
  EXPECT_EQ(bytes.dir, files.dir);
  EXPECT_EQ(bytes.images_listed, files.images_listed);
  EXPECT_EQ(bytes.skipped_no_pose, files.skipped_no_pose);
  EXPECT_EQ(bytes.poses, files.poses);
  ASSERT_EQ(bytes.frames.size(), files.frames.size());
  ASSERT_EQ(taken.size(), files.frames.size());
  for (std::size_t i = 0; i < files.frames.size(); ++i) {
    EXPECT_EQ(bytes.frames[i].image_path, files.frames[i].image_path);
    EXPECT_EQ(taken[i], files.frames[i].image_path);
    EXPECT_EQ(bytes.frames[i].line, files.frames[i].line);
    EXPECT_EQ(bytes.frames[i].timestamp, files.frames[i].timestamp);
    EXPECT_EQ(bytes.frames[i].pose_timestamp, files.frames[i].pose_timestamp);
    EXPECT_EQ(bytes.frames[i].T_world_camera.translation,
              files.frames[i].T_world_camera.translation);
    EXPECT_EQ(bytes.frames[i].T_world_camera.rotation.coeffs(),
              files.frames[i].T_world_camera.rotation.coeffs());
    const octovk::DepthPng from_file = octovk::readDepthPng(files.frames[i].image_path);
    const octovk::DepthPng from_bytes =
        octovk::io::decodeDepthPng(readFile(files.frames[i].image_path), "image");
    EXPECT_EQ(from_bytes.width, from_file.width);
    EXPECT_EQ(from_bytes.height, from_file.height);
    EXPECT_EQ(from_bytes.depths, from_file.depths);
  }
  // Lines end at '\n' whether or not the last has one, '\r' before it is dropped.
  const std::vector<octovk::io::GroundTruthPose> poses =
      octovk::io::parseGroundTruth("# c\r\n\r\n1.5 1 2 3 0 0 0 1\r\n\t2.5\t4 5 6 0 0 0 1", "gt");
  ASSERT_EQ(poses.size(), 2u);
  EXPECT_EQ(poses[1].timestamp, 2.5);
  EXPECT_EQ(poses[1].pose.translation, Eigen::Vector3f(4, 5, 6));
  // A malformed line names the caller's name for the file and the line.
  const std::string why =
      formatError([] { octovk::io::parseGroundTruth("# c\n\n1 2 3\n", "my-gt.txt"); });
  EXPECT_NE(why.find("'my-gt.txt' line 3"), std::string::npos) << why;
  // Nothing at all is a format error, not a crash.
  EXPECT_NE(formatError([] { octovk::io::decodeDepthPng({}, "empty.png"); }).find("not a PNG"),
            std::string::npos);
  EXPECT_NE(formatError([] { octovk::io::parseGroundTruth({}, "gt"); }).find("no poses"),
            std::string::npos);
}

// ---- the library: a depth image is the point cloud of its pixels ----

TEST(TumLibrary, DepthImageEqualsItsPointsAndOctomap) {
  OCTOVK_REQUIRE_CONTEXT(ctx);
  Scratch scratch("tum");
  const Sequence seq = makeSequence(scratch.dir() / "seq");
  const octovk::TumSequence read = octovk::readTumSequence(seq.dir.string());
  for (const double max_range : {-1.0, 2.0}) {
    octovk::MapParams params;
    params.resolution = 0.1;
    octovk::OccupancyMap by_image(ctx, params), by_points(ctx, params);
    octomap::OcTree oracle = octovk::test::makeOracle(params);
    for (const octovk::TumFrame& frame : read.frames) {
      const octovk::DepthPng png = octovk::readDepthPng(frame.image_path);
      const octovk::DepthImage image = png.image(intrinsics(seq.camera));
      const Eigen::Vector3f origin = octovk::graph2treeSensorOrigin(frame.T_world_camera);
      std::size_t no_depth = 0;
      const std::vector<Eigen::Vector3f> points = octovk::unprojectDepthImage(image, &no_depth);
      const octovk::ScanStats stats = by_image.insertDepthImage(image, frame.T_world_camera,
                                                                {.max_range_m = max_range}, origin);
      by_points.insertPointCloud(points, origin, frame.T_world_camera, {.max_range_m = max_range});
      oracle.insertPointCloud(octovk::test::toPointcloud(points), octovk::test::toPoint(origin),
                              octovk::test::toPose6D(frame.T_world_camera), max_range);
      EXPECT_EQ(stats.skipped_no_depth, no_depth);
      EXPECT_GT(no_depth, 0u);
      EXPECT_EQ(stats.points, std::size_t{kWidth} * kHeight);
    }
    const auto image_tree = octovk::toOcTree(by_image);
    const auto points_tree = octovk::toOcTree(by_points);
    EXPECT_EQ(octovk::test::btBytes(*image_tree), octovk::test::btBytes(*points_tree));
    EXPECT_EQ(octovk::test::otBytes(*image_tree), octovk::test::otBytes(*points_tree));
    EXPECT_TRUE(octovk::test::sameTree(oracle, *image_tree)) << "max range " << max_range;
    EXPECT_GT(image_tree->size(), 100u);
  }
}

// ---- the program: convert, graph2tree, integrate ----

TEST(TumCli, ConvertWritesTheImagesAsAScanGraph) {
  Scratch scratch("tum");
  const Sequence seq = makeSequence(scratch.dir() / "seq");
  const std::string graph = scratch / "scans.graph";
  std::vector<std::string> args = {"convert", seq.dir.string(), "-o", graph};
  for (const std::string& a : cameraArgs(seq.camera)) args.push_back(a);
  const RunResult r = runOctovk(args, scratch.dir());
  ASSERT_EQ(r.exit_code, 0) << r.out << r.err;
  EXPECT_EQ(r.err, "");
  EXPECT_NE(r.out.find("images:        4 used of 5 in depth.txt (1 skipped"), std::string::npos)
      << r.out;
  EXPECT_NE(r.out.find("wrote:         " + graph), std::string::npos) << r.out;

  // OctoMap's own reader: one node per image with a pose, the points computed here, the pose.
  octomap::ScanGraph read;
  ASSERT_TRUE(read.readBinary(graph));
  ASSERT_EQ(read.size(), 4u);
  std::size_t node = 0, total = 0;
  for (std::size_t k = 0; k < seq.image_times.size(); ++k) {
    const int j = nearestPose(seq, k);
    if (j < 0) continue;
    const octomap::ScanNode& n = *read.getNodeByID(static_cast<unsigned int>(node++));
    const std::vector<Eigen::Vector3f> expected = expectedPoints(seq, k);
    total += expected.size();
    ASSERT_EQ(n.scan->size(), expected.size()) << "image " << k;
    for (std::size_t i = 0; i < expected.size(); ++i) {
      const octomap::point3d& p = n.scan->getPoint(static_cast<unsigned int>(i));
      ASSERT_TRUE(sameBits(Eigen::Vector3f(p.x(), p.y(), p.z()), expected[i]))
          << "image " << k << " point " << i;
    }
    const octovk::Pose pose = expectedPose(seq.poses[static_cast<std::size_t>(j)]);
    EXPECT_EQ(n.pose.trans().x(), pose.translation.x());
    EXPECT_EQ(n.pose.trans().y(), pose.translation.y());
    EXPECT_EQ(n.pose.trans().z(), pose.translation.z());
    EXPECT_EQ(n.pose.rot().u(), pose.rotation.w());
    EXPECT_EQ(n.pose.rot().x(), pose.rotation.x());
    EXPECT_EQ(n.pose.rot().y(), pose.rotation.y());
    EXPECT_EQ(n.pose.rot().z(), pose.rotation.z());
  }
  EXPECT_NE(r.out.find("points:        " + std::to_string(total) + " "), std::string::npos)
      << r.out;
  // octovk's own reader agrees.
  EXPECT_EQ(octovk::readScanGraph(graph).size(), 4u);
}

struct ParityCase {
  std::string name;
  std::string resolution = "0.1";
  std::string max_range;
  bool default_camera = false;
  bool discretize = false;
};

// Test names show the case, not its bytes.
void PrintTo(const ParityCase& c, std::ostream* os) { *os << c.name; }

class TumParity : public ::testing::TestWithParam<ParityCase> {};

// convert -> graph2tree against integrate DIR: both files byte for byte.
TEST_P(TumParity, IntegrateEqualsGraph2treeOnConvertedGraph) {
  OCTOVK_REQUIRE_CONTEXT(ctx);
  OCTOVK_REQUIRE_GRAPH2TREE();
  const ParityCase& c = GetParam();
  Scratch scratch("tum");
  Camera camera;
  if (c.default_camera) camera = {525.0f, 525.0f, 319.5f, 239.5f, 5000.0f};
  const Sequence seq = makeSequence(scratch.dir() / "seq", camera);
  const std::vector<std::string> camera_args =
      c.default_camera ? std::vector<std::string>{} : cameraArgs(camera);

  const std::string graph = scratch / "scans.graph";
  std::vector<std::string> convert = {"convert", seq.dir.string(), "-o", graph};
  convert.insert(convert.end(), camera_args.begin(), camera_args.end());
  const RunResult converted = runOctovk(convert, scratch.dir());
  ASSERT_EQ(converted.exit_code, 0) << converted.out << converted.err;

  const std::string ref = scratch / "graph2tree.bt";
  std::string g2t = quote(OCTOVK_PATH(OCTOVK_GRAPH2TREE)) + " -i " + quote(graph) + " -o " +
                    quote(ref) + " -res " + c.resolution;
  const std::string bt = scratch / "octovk.bt", ot = scratch / "octovk.ot";
  // --quiet: no progress lines on a slow run (under the sanitizers), so stderr stays empty.
  std::vector<std::string> integrate = {"integrate", seq.dir.string(), "-o",         bt,       "-o",
                                        ot,          "--resolution",   c.resolution, "--quiet"};
  integrate.insert(integrate.end(), camera_args.begin(), camera_args.end());
  if (!c.max_range.empty()) {
    g2t += " -m " + c.max_range;
    integrate.insert(integrate.end(), {"--max-range", c.max_range});
  }
  if (c.discretize) {
    g2t += " -discretize";
    integrate.push_back("--discretize");
  }
  const RunResult reference = runShell(g2t, scratch.dir());
  ASSERT_EQ(reference.exit_code, 0) << g2t << "\n" << reference.out << reference.err;
  const RunResult mine = runOctovk(integrate, scratch.dir());
  ASSERT_EQ(mine.exit_code, 0) << mine.out << mine.err;

  const std::string ref_bt = readFile(ref), ref_ot = readFile(ref + ".ot");
  ASSERT_GT(ref_bt.size(), 100u);
  EXPECT_TRUE(readFile(bt) == ref_bt) << "the .bt differs from graph2tree's";
  EXPECT_TRUE(readFile(ot) == ref_ot) << "the .ot differs from graph2tree's .bt.ot";

  EXPECT_NE(mine.out.find("images:        4 used of 5 in depth.txt (1 skipped: no ground-truth "
                          "pose less than 0.02 s away)"),
            std::string::npos)
      << mine.out;
  EXPECT_NE(mine.out.find("scans:         4\n"), std::string::npos) << mine.out;
  EXPECT_NE(mine.out.find("pixels:        " + std::to_string(4 * kWidth * kHeight) + " ("),
            std::string::npos)
      << mine.out;
  const std::size_t at = reference.out.find("Tree size: ");
  ASSERT_NE(at, std::string::npos) << reference.out;
  const std::string nodes =
      reference.out.substr(at + 11, reference.out.find(' ', at + 11) - at - 11);
  EXPECT_NE(mine.out.find("nodes:         " + nodes + " in memory"), std::string::npos) << mine.out;
  EXPECT_NE(mine.out.find("device: " + ctx.device().name), std::string::npos) << mine.out;
  EXPECT_EQ(mine.err, "");
}

INSTANTIATE_TEST_SUITE_P(
    Synthetic, TumParity,
    ::testing::Values(ParityCase{.name = "Res10cm"},
                      ParityCase{.name = "Res5cm", .resolution = "0.05"},
                      ParityCase{.name = "MaxRange2", .max_range = "2"},
                      ParityCase{.name = "DefaultCamera", .default_camera = true},
                      ParityCase{.name = "Discretize", .discretize = true}),
    [](const ::testing::TestParamInfo<ParityCase>& info) { return info.param.name; });

// ---- bad folders: one error line, the documented exit code, no file ----

// `mid_run`: the failure comes while working (damage inside an image): integrate has printed the
// device line by then, so stdout may hold that line.
void expectRejected(const std::vector<std::string>& args, int exit_code,
                    const std::vector<std::string>& mentions, const Scratch& scratch,
                    bool mid_run = false) {
  const RunResult r = runOctovk(args, scratch.dir());
  expectOneErrorLine(r, exit_code, mentions);
  if (mid_run && args.front() == "integrate")
    EXPECT_TRUE(r.out.empty() || (r.out.starts_with("device: ") &&
                                  std::count(r.out.begin(), r.out.end(), '\n') == 1))
        << r.out;
  else
    EXPECT_EQ(r.out, "");
  for (const auto& entry : fs::recursive_directory_iterator(scratch.dir())) {
    const std::string name = entry.path().filename().string();
    EXPECT_FALSE(entry.is_regular_file() &&
                 (name.ends_with(".bt") || name.ends_with(".ot") || name.ends_with(".graph") ||
                  name.find(".tmp") != std::string::npos))
        << "left behind: " << entry.path();
  }
}

// Both commands on `dir`: integrate (two outputs) and convert.
void expectBothRejected(const fs::path& dir, int exit_code,
                        const std::vector<std::string>& mentions, const Scratch& scratch,
                        bool mid_run = false) {
  expectRejected({"integrate", dir.string(), "-o", scratch / "map.bt", "-o", scratch / "map.ot"},
                 exit_code, mentions, scratch, mid_run);
  expectRejected({"convert", dir.string(), "-o", scratch / "scans.graph"}, exit_code, mentions,
                 scratch, mid_run);
}

void replaceLine(const fs::path& file, std::size_t number, const std::string& text) {
  std::ifstream in(file);
  std::vector<std::string> lines;
  for (std::string line; std::getline(in, line);) lines.push_back(line);
  in.close();
  ASSERT_LE(number, lines.size());
  lines[number - 1] = text;
  std::ofstream out(file);
  for (const std::string& line : lines) out << line << "\n";
}

TEST(TumBadInput, MissingDepthTxt) {
  Scratch scratch("tum");
  const Sequence seq = makeSequence(scratch.dir() / "seq");
  fs::remove(seq.dir / "depth.txt");
  expectBothRejected(seq.dir, 2, {"depth.txt", seq.dir.string()}, scratch);
}

TEST(TumBadInput, MissingGroundTruth) {
  Scratch scratch("tum");
  const Sequence seq = makeSequence(scratch.dir() / "seq");
  fs::remove(seq.dir / "groundtruth.txt");
  expectBothRejected(seq.dir, 2, {"groundtruth.txt"}, scratch);
}

TEST(TumBadInput, FolderDoesNotExist) {
  Scratch scratch("tum");
  expectRejected({"convert", scratch / "nowhere", "-o", scratch / "scans.graph"}, 2,
                 {"nowhere", "does not exist"}, scratch);
}

TEST(TumBadInput, EightBitPng) {
  Scratch scratch("tum");
  const Sequence seq = makeSequence(scratch.dir() / "seq");
  writePng(seq.dir / seq.image_files[3], kWidth, kHeight, 8, PNG_COLOR_TYPE_GRAY,
           std::vector<std::uint16_t>(kWidth * kHeight, 7));
  expectBothRejected(seq.dir, 1, {seq.image_files[3], "grayscale PNG of bit depth 8", "16-bit"},
                     scratch);
}

TEST(TumBadInput, ColourPng) {
  Scratch scratch("tum");
  const Sequence seq = makeSequence(scratch.dir() / "seq");
  writePng(seq.dir / seq.image_files[0], kWidth, kHeight, 16, PNG_COLOR_TYPE_RGB,
           std::vector<std::uint16_t>(kWidth * kHeight * 3, 7));
  expectBothRejected(seq.dir, 1, {seq.image_files[0], "RGB colour PNG of bit depth 16"}, scratch);
}

TEST(TumBadInput, MissingImage) {
  Scratch scratch("tum");
  const Sequence seq = makeSequence(scratch.dir() / "seq");
  fs::remove(seq.dir / seq.image_files[4]);
  // depth.txt: 3 comment lines, images 0 and 1, a blank line, then images 2, 3, 4 (line 9).
  expectBothRejected(seq.dir, 1, {seq.image_files[4], "does not exist", "line 9"}, scratch);
}

TEST(TumBadInput, MissingImageWithoutPoseIsNotRead) {
  // The third image has no pose: it is skipped, so its file is never needed.
  OCTOVK_REQUIRE_CONTEXT(ctx);
  (void)ctx;  // integrate needs a device
  Scratch scratch("tum");
  const Sequence seq = makeSequence(scratch.dir() / "seq");
  fs::remove(seq.dir / seq.image_files[2]);
  const RunResult r =
      runOctovk({"integrate", seq.dir.string(), "-o", scratch / "map.bt"}, scratch.dir());
  EXPECT_EQ(r.exit_code, 0) << r.err;
  EXPECT_TRUE(fs::exists(scratch / "map.bt"));
}

TEST(TumBadInput, TruncatedPng) {
  Scratch scratch("tum");
  const Sequence seq = makeSequence(scratch.dir() / "seq");
  const fs::path image = seq.dir / seq.image_files[1];
  const std::string whole = readFile(image);
  std::ofstream(image, std::ios_base::binary | std::ios_base::trunc)
      << whole.substr(0, whole.size() / 2);
  expectBothRejected(seq.dir, 1, {seq.image_files[1], "corrupt or truncated"}, scratch,
                     /*mid_run=*/true);
}

TEST(TumBadInput, ScanErrorsNameTheImage) {
  // Damage found while integrating (the header is sound, the pixels cut short) names the folder,
  // the image's timestamp and its depth.txt line before the reader's message.
  OCTOVK_REQUIRE_CONTEXT(ctx);
  (void)ctx;
  Scratch scratch("tum");
  const Sequence seq = makeSequence(scratch.dir() / "seq");
  const fs::path image = seq.dir / seq.image_files[3];  // depth.txt line 8
  const std::string whole = readFile(image);
  std::ofstream(image, std::ios_base::binary | std::ios_base::trunc)
      << whole.substr(0, whole.size() / 2);
  expectRejected({"integrate", seq.dir.string(), "-o", scratch / "map.bt"}, 1,
                 {seq.dir.string() + ": depth image " + seq.image_times[3] + " (" +
                      seq.image_files[3] + ", depth.txt line 8): ",
                  "corrupt or truncated"},
                 scratch, /*mid_run=*/true);
}

TEST(TumBadInput, GarbageLineInDepthTxt) {
  Scratch scratch("tum");
  const Sequence seq = makeSequence(scratch.dir() / "seq");
  replaceLine(seq.dir / "depth.txt", 5, "1305031102.2 depth/a.png extra");
  expectBothRejected(seq.dir, 1, {"depth.txt' line 5", "expected 2 fields"}, scratch);
  replaceLine(seq.dir / "depth.txt", 5, "yesterday depth/a.png");
  expectBothRejected(seq.dir, 1, {"depth.txt' line 5", "'yesterday'"}, scratch);
}

TEST(TumBadInput, AbsoluteImageName) {
  // Joined with the folder, an absolute name dropped it (found by fuzz_tum_lists): any file on the
  // machine could be read as a depth image. depth.txt names images relative to the folder.
  Scratch scratch("tum");
  const Sequence seq = makeSequence(scratch.dir() / "seq");
  const std::string absolute = (seq.dir / seq.image_files[0]).string();
  replaceLine(seq.dir / "depth.txt", 5, "1305031102.2 " + absolute);
  expectBothRejected(seq.dir, 1, {"depth.txt' line 5", "'" + absolute + "' is absolute"}, scratch);
  try {
    octovk::readTumSequence(seq.dir.string());
    ADD_FAILURE() << "an absolute image name was accepted";
  } catch (const octovk::Error& e) {
    EXPECT_EQ(e.code(), octovk::ErrorCode::kFormat) << e.what();
  }
}

TEST(TumBadInput, DotDotImageName) {
  // '..' climbs out of the folder as an absolute name leaves it: refused the same way, wherever
  // it leads (even back inside: the rule is on the name, not on where it happens to land).
  Scratch scratch("tum");
  const Sequence seq = makeSequence(scratch.dir() / "seq");
  fs::copy_file(seq.dir / seq.image_files[0], scratch.dir() / "outside.png");
  const std::vector<std::string> names = {"../outside.png", "depth/../../outside.png",
                                          "depth/../" + seq.image_files[0]};
  for (const std::string& name : names) {
    SCOPED_TRACE(name);
    replaceLine(seq.dir / "depth.txt", 5, "1305031102.2 " + name);
    expectBothRejected(seq.dir, 1, {"depth.txt' line 5", "'" + name + "' has a '..' component"},
                       scratch);
    try {
      octovk::readTumSequence(seq.dir.string());
      ADD_FAILURE() << "a '..' image name was accepted";
    } catch (const octovk::Error& e) {
      EXPECT_EQ(e.code(), octovk::ErrorCode::kFormat) << e.what();
    }
  }
}

TEST(TumBadInput, SymlinkOutOfTheFolder) {
  // A link in the folder to an image outside it (or to a folder outside it) reads any file on
  // the machine, as '..' or an absolute name would: refused. Links that stay inside are fine,
  // and so is a folder given through a link.
  Scratch scratch("tum");
  const Sequence seq = makeSequence(scratch.dir() / "seq");
  fs::create_directories(scratch.dir() / "elsewhere");
  const fs::path outside = scratch.dir() / "elsewhere" / "image.png";
  fs::copy_file(seq.dir / seq.image_files[0], outside);
  const fs::path image = seq.dir / seq.image_files[0];  // depth.txt line 4
  fs::remove(image);
  fs::create_symlink(outside, image);
  expectBothRejected(seq.dir, 1,
                     {"depth.txt' line 4", seq.image_files[0], "symbolic link",
                      "outside the folder", fs::canonical(outside).string()},
                     scratch);
  // A relative link, and a link to a folder outside on the way to the image.
  fs::remove(image);
  fs::create_symlink("../../elsewhere/image.png", image);
  expectBothRejected(seq.dir, 1, {"depth.txt' line 4", "outside the folder"}, scratch);
  fs::remove(image);
  fs::create_symlink(outside.parent_path(), seq.dir / "linked");
  replaceLine(seq.dir / "depth.txt", 4, seq.image_times[0] + " linked/image.png");
  expectBothRejected(seq.dir, 1, {"depth.txt' line 4", "linked/image.png", "outside the folder"},
                     scratch);
  try {
    octovk::readTumSequence(seq.dir.string());
    ADD_FAILURE() << "a link out of the folder was accepted";
  } catch (const octovk::Error& e) {
    EXPECT_EQ(e.code(), octovk::ErrorCode::kIo) << e.what();
  }
  // Inside the folder a link is an ordinary name, and the folder may be reached through one.
  fs::create_symlink(fs::path("..") / seq.image_files[1], seq.dir / "depth" / "inside.png");
  replaceLine(seq.dir / "depth.txt", 4, seq.image_times[0] + " depth/inside.png");
  fs::create_symlink(seq.dir, scratch.dir() / "seq-link");
  for (const fs::path& dir : {seq.dir, scratch.dir() / "seq-link"}) {
    const octovk::TumSequence read = octovk::readTumSequence(dir.string());
    ASSERT_EQ(read.frames.size(), 4u) << dir;
    EXPECT_EQ(octovk::readDepthPng(read.frames[0].image_path).depths, seq.depths[1]);
  }
}

TEST(TumBadInput, ListSymlinkOutOfTheFolder) {
  // depth.txt or groundtruth.txt as a link out of the folder was read: the lists follow the
  // images' rule. A list linked inside the folder is read.
  Scratch scratch("tum");
  const Sequence seq = makeSequence(scratch.dir() / "seq");
  fs::create_directories(scratch.dir() / "elsewhere");
  for (const char* list : {"depth.txt", "groundtruth.txt"}) {
    SCOPED_TRACE(list);
    const fs::path outside = scratch.dir() / "elsewhere" / list;
    fs::rename(seq.dir / list, outside);
    fs::create_symlink(outside, seq.dir / list);
    expectBothRejected(seq.dir, 1,
                       {std::string(list) + "' leads through a symbolic link",
                        fs::canonical(outside).string(), "outside the folder"},
                       scratch);
    try {
      octovk::readTumSequence(seq.dir.string());
      ADD_FAILURE() << "a list linked out of the folder was read";
    } catch (const octovk::Error& e) {
      EXPECT_EQ(e.code(), octovk::ErrorCode::kIo) << e.what();
    }
    fs::remove(seq.dir / list);
    fs::rename(outside, seq.dir / "depth" / list);
    fs::create_symlink(fs::path("depth") / list, seq.dir / list);
    EXPECT_EQ(octovk::readTumSequence(seq.dir.string()).frames.size(), 4u);
    fs::remove(seq.dir / list);
    fs::rename(seq.dir / "depth" / list, seq.dir / list);
  }
}

TEST(TumBadInput, GarbageLineInGroundTruth) {
  Scratch scratch("tum");
  const Sequence seq = makeSequence(scratch.dir() / "seq");
  replaceLine(seq.dir / "groundtruth.txt", 6, "1305031102.2 1 2 3 0 0 0");
  expectBothRejected(seq.dir, 1, {"groundtruth.txt' line 6", "expected 8 values"}, scratch);
  replaceLine(seq.dir / "groundtruth.txt", 6, "1305031102.2 1 2 3 0 0 0 1x");
  expectBothRejected(seq.dir, 1, {"groundtruth.txt' line 6", "qw '1x'"}, scratch);
  replaceLine(seq.dir / "groundtruth.txt", 6, "1305031102.2 1 2 3 0 0 0 0");
  expectBothRejected(seq.dir, 1, {"groundtruth.txt' line 6", "norm 0"}, scratch);
}

TEST(TumBadInput, NoPoseForAnyImage) {
  Scratch scratch("tum");
  const Sequence seq = makeSequence(scratch.dir() / "seq");
  std::ofstream(seq.dir / "groundtruth.txt") << "# nothing near\n100.0 0 0 0 0 0 0 1\n";
  expectBothRejected(seq.dir, 1, {"no image", "0.02", "groundtruth.txt"}, scratch);
  std::ofstream(seq.dir / "groundtruth.txt") << "# only comments\n";
  expectBothRejected(seq.dir, 1, {"groundtruth.txt", "no poses"}, scratch);
}

TEST(TumBadInput, NoImagesListed) {
  Scratch scratch("tum");
  const Sequence seq = makeSequence(scratch.dir() / "seq");
  std::ofstream(seq.dir / "depth.txt") << "# depth maps\n\n";
  expectBothRejected(seq.dir, 1, {"depth.txt", "no images"}, scratch);
}

TEST(TumBadInput, BadCameraOptions) {
  Scratch scratch("tum");
  const Sequence seq = makeSequence(scratch.dir() / "seq");
  const std::string dir = seq.dir.string();
  expectRejected({"convert", dir, "-o", scratch / "s.graph", "--intrinsics", "0", "1", "2", "3"}, 2,
                 {"--intrinsics", "FX"}, scratch);
  expectRejected({"convert", dir, "-o", scratch / "s.graph", "--intrinsics=1,2,3"}, 2,
                 {"--intrinsics", "4 values"}, scratch);
  expectRejected({"integrate", dir, "-o", scratch / "m.bt", "--depth-scale", "-5"}, 2,
                 {"--depth-scale"}, scratch);
  expectRejected({"convert", dir, "-o", scratch / "s.txt"}, 2, {".graph"}, scratch);
  expectRejected({"convert", dir}, 2, {"-o"}, scratch);
  // Camera options mean nothing for a scan graph.
  const std::string graph = OCTOVK_PATH(OCTOVK_OCTOMAP_DATA_DIR) + "/spherical_scan.graph";
  expectRejected({"integrate", graph, "-o", scratch / "m.bt", "--intrinsics", "1", "1", "1", "1"},
                 2, {"--intrinsics", "TUM RGB-D folder"}, scratch);
}

// ---- outputs: created before any work (exit 2 naming the path), never left half-written ----

// An output whose directory exists and is writable, so that only creating the file fails: a file
// name longer than any file system allows.
std::string uncreatableOutput(const Scratch& scratch, const std::string& ext) {
  return scratch / (std::string(300, 'n') + ext);
}

TEST(TumOutputs, UncreatableOutputIsExit2BeforeTheFolderIsRead) {
  Scratch scratch("tum");
  const Sequence seq = makeSequence(scratch.dir() / "seq");
  // A folder that fails while being read (exit 1): that error must not come first.
  replaceLine(seq.dir / "depth.txt", 5, "yesterday depth/a.png");
  expectRejected({"convert", seq.dir.string(), "-o", scratch / "scans.graph"}, 1,
                 {"depth.txt' line 5"}, scratch);
  for (const auto& [command, ext] : std::vector<std::pair<std::string, std::string>>{
           {"convert", ".graph"}, {"integrate", ".bt"}}) {
    SCOPED_TRACE(command);
    const std::string output = uncreatableOutput(scratch, ext);
    const std::vector<std::string> args = {command, seq.dir.string(), "-o", output};
    expectRejected(args, 2, {"cannot write '" + output + "'", "nothing was done"}, scratch);
    const RunResult r = runOctovk(args, scratch.dir());
    EXPECT_EQ(r.err.find(".tmp"), std::string::npos) << r.err;
    EXPECT_EQ(r.err.find("depth.txt"), std::string::npos) << r.err;
  }
}

TEST(TumOutputs, ConvertWriteFailureNamesTheUsersPathAndLeavesNothing) {
  Scratch scratch("tum");
  const Sequence seq = makeSequence(scratch.dir() / "seq");
  const std::string graph = scratch / "scans.graph";
  // No file may grow past 512 bytes (SIGXFSZ ignored, so the write fails instead): the graph of
  // the sequence is far larger, so writing it fails after the images are read.
  const RunResult r = runShell("trap '' XFSZ; ulimit -f 1; " + quote(OCTOVK_PATH(OCTOVK_CLI)) +
                                   " convert " + quote(seq.dir.string()) + " -o " + quote(graph),
                               scratch.dir());
  EXPECT_EQ(r.exit_code, 1) << r.err;
  EXPECT_EQ(r.err.rfind("octovk: error: ", 0), 0u) << r.err;
  EXPECT_EQ(std::count(r.err.begin(), r.err.end(), '\n'), 1) << r.err;
  EXPECT_NE(r.err.find("'" + graph + "'"), std::string::npos) << r.err;
  EXPECT_EQ(r.err.find(".tmp"), std::string::npos) << r.err;
  EXPECT_FALSE(fs::exists(graph));
  for (const auto& entry : fs::directory_iterator(scratch.dir()))
    EXPECT_EQ(entry.path().filename().string().find(".tmp"), std::string::npos)
        << "left behind: " << entry.path();
  // Without the limit the same command works and writes more than the limit allowed.
  const RunResult ok = runOctovk({"convert", seq.dir.string(), "-o", graph}, scratch.dir());
  EXPECT_EQ(ok.exit_code, 0) << ok.err;
  EXPECT_GT(fs::file_size(graph), 512u);
}

// ---- help ----

TEST(TumHelp, HelpDocumentsFoldersAndOptions) {
  Scratch scratch("tum");
  for (const std::vector<std::string>& args : {std::vector<std::string>{"integrate", "--help"},
                                               {"convert", "--help"},
                                               {"help", "convert"},
                                               {"help", "integrate"}}) {
    const RunResult r = runOctovk(args, scratch.dir());
    EXPECT_EQ(r.exit_code, 0);
    EXPECT_EQ(r.err, "");
    for (const char* word :
         {"DIR", "depth.txt", "groundtruth.txt", "timestamp tx ty tz qx qy qz qw", "16-bit",
          "0.02 s", "--intrinsics FX FY CX CY", "(default: 525 525 319.5 239.5)", "--depth-scale S",
          "(default: 5000)", "convert"})
      EXPECT_NE(r.out.find(word), std::string::npos) << args.front() << " help lacks " << word;
  }
  // The program's help is short: it names the folders and sends the reader to the commands' own.
  const RunResult top = runOctovk({"--help"}, scratch.dir());
  EXPECT_EQ(top.exit_code, 0);
  for (const char* word : {"TUM RGB-D folder", "\n  convert ", "octovk COMMAND --help"})
    EXPECT_NE(top.out.find(word), std::string::npos) << "--help lacks " << word;
}

}  // namespace
}  // namespace octovk::test
