// payload_cli_test: the program's colour and time paths (issue 29). A tiny TUM RGB-D folder with
// colour images (8-bit RGB, RGBA and grey PNGs written here) is integrated with
// `octovk integrate DIR --color` and must give the ColorOcTree file OctoMap gives doing the same
// steps; a small scan graph with `--stamps` (and `--degrade-after`) the OcTreeStamped file of an
// OcTreeStamped whose clock is the scans' stamps; `render` draws a ColorOcTree in its colours.
// Bad colour folders and stamp files give one error line and no file.
#include <gtest/gtest.h>
#include <octomap/ColorOcTree.h>
#include <octomap/OcTreeStamped.h>
#include <png.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdint>
#include <filesystem>
#include <fstream>
#include <iomanip>
#include <memory>
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

// ---- PNG files ----

// An 8-bit PNG of `color_type` from `samples` (row by row, the type's channels a pixel).
void writePng8(const fs::path& path, std::uint32_t width, std::uint32_t height, int color_type,
               std::vector<unsigned char> samples) {
  const std::size_t row_bytes = samples.size() / height;
  std::vector<png_bytep> rows(height);
  for (std::uint32_t y = 0; y < height; ++y) rows[y] = samples.data() + y * row_bytes;
  ASSERT_TRUE(
      writePngRows(path.c_str(), width, height, 8, color_type, PNG_INTERLACE_NONE, rows.data()))
      << path;
}

void writeDepthPng(const fs::path& path, std::uint32_t width, std::uint32_t height,
                   const std::vector<std::uint16_t>& depths) {
  std::vector<unsigned char> data(depths.size() * 2);
  for (std::size_t i = 0; i < depths.size(); ++i) {
    data[2 * i] = static_cast<unsigned char>(depths[i] >> 8);
    data[2 * i + 1] = static_cast<unsigned char>(depths[i] & 0xFF);
  }
  std::vector<png_bytep> rows(height);
  for (std::uint32_t y = 0; y < height; ++y) rows[y] = data.data() + y * width * 2;
  ASSERT_TRUE(writePngRows(path.c_str(), width, height, 16, PNG_COLOR_TYPE_GRAY, PNG_INTERLACE_NONE,
                           rows.data()))
      << path;
}

// ---- the tiny colour sequence ----

constexpr std::uint32_t kWidth = 32;
constexpr std::uint32_t kHeight = 24;
constexpr float kFx = 30.0f, kFy = 31.0f, kCx = 15.5f, kCy = 11.25f, kScale = 5000.0f;
constexpr int kImages = 3;

std::vector<std::string> cameraArgs() {
  return {"--intrinsics", "30", "31", "15.5", "11.25", "--depth-scale", "5000"};
}

std::string fixed(double v, int decimals) {
  std::ostringstream s;
  s << std::fixed << std::setprecision(decimals) << v;
  return s.str();
}

// Camera to world at time s, with TUM's optical frame (z forward).
Eigen::Matrix3d rotationAt(double s) {
  const Eigen::Matrix3d optical_to_body =
      (Eigen::Matrix3d() << 0, 0, 1, -1, 0, 0, 0, -1, 0).finished();
  return (Eigen::AngleAxisd(0.3 + 5.0 * s, Eigen::Vector3d::UnitZ()) *
          Eigen::AngleAxisd(0.2 - 1.5 * s, Eigen::Vector3d::UnitX()))
             .toRotationMatrix() *
         optical_to_body;
}

Eigen::Vector3d positionAt(double s) { return {0.3 * std::sin(3.0 * s), -0.1 + s, 0.3 + 0.5 * s}; }

struct ColorSequence {
  fs::path dir;
  std::vector<std::vector<std::uint16_t>> depths;  // per depth image
  std::vector<std::vector<Rgb>> colours;           // the colours its rgb image gives, per pixel
  std::vector<fs::path> rgb_files;                 // the rgb image each depth image takes
};

// Three depth images 1/30 s apart of a box-shaped room (with holes), each with a colour image
// 0.007 s later: 8-bit RGB, RGBA (its alpha dropped) and grey. The second depth image also has a
// colour image 0.012 s before it, farther than its own, and that file is not a PNG at all: only
// the nearest image is read. Ground truth at 100 Hz around them.
ColorSequence makeColorSequence(const fs::path& dir) {
  ColorSequence seq;
  seq.dir = dir;
  fs::create_directories(dir / "depth");
  fs::create_directories(dir / "rgb");
  const double t0 = 1305031102.175304;
  const Eigen::Vector3d room_min(-2.0, -1.8, -0.8), room_max(2.5, 2.0, 1.4);
  std::ofstream depth_txt(dir / "depth.txt");
  std::ofstream rgb_txt(dir / "rgb.txt");
  depth_txt << "# depth maps\n# timestamp filename\n";
  rgb_txt << "# color images\n# timestamp filename\n";
  for (int k = 0; k < kImages; ++k) {
    const double s = 0.0333 * k;
    const std::string stamp = fixed(t0 + s, 6);
    const std::string depth_name = "depth/" + stamp + ".png";
    depth_txt << stamp << " " << depth_name << "\n";
    const Eigen::Matrix3d r = rotationAt(s);
    const Eigen::Vector3d o = positionAt(s);
    std::vector<std::uint16_t> depths(kWidth * kHeight);
    for (std::uint32_t v = 0; v < kHeight; ++v)
      for (std::uint32_t u = 0; u < kWidth; ++u) {
        const Eigen::Vector3d d =
            r * Eigen::Vector3d((u - double{kCx}) / kFx, (v - double{kCy}) / kFy, 1.0);
        double t = 1e9;
        for (int i = 0; i < 3; ++i) {
          if (d[i] > 0) t = std::min(t, (room_max[i] - o[i]) / d[i]);
          if (d[i] < 0) t = std::min(t, (room_min[i] - o[i]) / d[i]);
        }
        const bool hole = (u + 5 * v) % 13 == 0;
        depths[v * kWidth + u] = hole ? 0 : static_cast<std::uint16_t>(std::round(t * kScale));
      }
    writeDepthPng(dir / depth_name, kWidth, kHeight, depths);
    seq.depths.push_back(std::move(depths));

    if (k == 1) {
      const std::string decoy = fixed(t0 + s - 0.012, 6);
      rgb_txt << decoy << " rgb/" << decoy << ".png\n";
      std::ofstream(dir / ("rgb/" + decoy + ".png")) << "not a PNG";
    }
    const std::string rgb_stamp = fixed(t0 + s + 0.007, 6);
    const std::string rgb_name = "rgb/" + rgb_stamp + ".png";
    rgb_txt << rgb_stamp << " " << rgb_name << "\n";
    seq.rgb_files.push_back(dir / rgb_name);
    std::vector<Rgb> colours(kWidth * kHeight);
    std::vector<unsigned char> samples;
    const int type = k == 0   ? PNG_COLOR_TYPE_RGB
                     : k == 1 ? PNG_COLOR_TYPE_RGB_ALPHA
                              : PNG_COLOR_TYPE_GRAY;
    for (std::uint32_t v = 0; v < kHeight; ++v)
      for (std::uint32_t u = 0; u < kWidth; ++u) {
        Rgb& c = colours[v * kWidth + u];
        if (type == PNG_COLOR_TYPE_GRAY) {
          const auto grey = static_cast<std::uint8_t>((u * 7 + v * 3) % 256);
          c = {grey, grey, grey};
          samples.push_back(grey);
          continue;
        }
        c = {static_cast<std::uint8_t>(8 * u), static_cast<std::uint8_t>(10 * v),
             static_cast<std::uint8_t>(90 * k + 20 * ((u + v) % 7))};
        samples.insert(samples.end(), {c.r, c.g, c.b});
        if (type == PNG_COLOR_TYPE_RGB_ALPHA) samples.push_back(static_cast<unsigned char>(u * v));
      }
    writePng8(dir / rgb_name, kWidth, kHeight, type, std::move(samples));
    seq.colours.push_back(std::move(colours));
  }
  std::ofstream gt(dir / "groundtruth.txt");
  gt << "# ground truth trajectory\n# timestamp tx ty tz qx qy qz qw\n";
  for (int j = 0; j < 18; ++j) {
    const double s = -0.05 + 0.01 * j + 0.0013;
    const Eigen::Quaterniond q(rotationAt(s));
    const Eigen::Vector3d p = positionAt(s);
    gt << fixed(t0 + s, 4) << " " << fixed(p.x(), 4) << " " << fixed(p.y(), 4) << " "
       << fixed(p.z(), 4) << " " << fixed(q.x(), 4) << " " << fixed(q.y(), 4) << " "
       << fixed(q.z(), 4) << " " << fixed(q.w(), 4) << "\n";
  }
  return seq;
}

// OctoMap doing what `integrate DIR --color` promises: each image as graph2tree inserts it
// (ColorOcTree::insertPointCloud of its camera-frame points with the pose), then
// averageNodeColor for each point, in pixel order, at the point in the world; then
// updateInnerOccupancy(). The .ot bytes ColorOcTree::write gives.
std::string colourOracleOt(const ColorSequence& seq, double resolution, const fs::path& out) {
  octomap::ColorOcTree tree(resolution);
  // The poses as the library reads them (the reader's pose parsing is tested in tum_test).
  const TumSequence read = readTumSequence(seq.dir.string());
  EXPECT_EQ(read.frames.size(), std::size_t{kImages});
  for (std::size_t k = 0; k < read.frames.size(); ++k) {
    const TumFrame& frame = read.frames[k];
    DepthImage image;
    image.width = kWidth;
    image.height = kHeight;
    image.depths = std::span<const std::uint16_t>(seq.depths[k]);
    image.fx = kFx;
    image.fy = kFy;
    image.cx = kCx;
    image.cy = kCy;
    image.depth_scale = kScale;
    const std::vector<Eigen::Vector3f> points = unprojectDepthImage(image);
    std::vector<Rgb> colours;  // of the pixels that give a point, in pixel order
    for (std::size_t p = 0; p < seq.depths[k].size(); ++p)
      if (seq.depths[k][p] != 0) colours.push_back(seq.colours[k][p]);
    EXPECT_EQ(points.size(), colours.size());
    const octomath::Pose6D pose = toPose6D(frame.T_world_camera);
    const octomap::Pointcloud camera_points = toPointcloud(points);
    tree.insertPointCloud(camera_points, toPoint(graph2treeSensorOrigin(frame.T_world_camera)),
                          pose, -1.0, false, false);
    octomap::Pointcloud world = camera_points;
    world.transform(pose);  // as insertPointCloud transforms them
    for (std::size_t i = 0; i < world.size() && i < colours.size(); ++i) {
      const octomap::point3d& q = world[i];
      tree.averageNodeColor(q.x(), q.y(), q.z(), colours[i].r, colours[i].g, colours[i].b);
    }
  }
  tree.updateInnerOccupancy();
  EXPECT_TRUE(tree.write(out.string()));
  return readFile(out);
}

// ---- the reader ----

TEST(PayloadCliReader, ColourPngsOfEveryEightBitKind) {
  Scratch scratch("payload");
  const ColorSequence seq = makeColorSequence(scratch.dir() / "seq");
  for (int k = 0; k < kImages; ++k) {
    const ColorPng png = readColorPng(seq.rgb_files[static_cast<std::size_t>(k)].string());
    EXPECT_EQ(png.width, kWidth);
    EXPECT_EQ(png.height, kHeight);
    EXPECT_TRUE(png.colors == seq.colours[static_cast<std::size_t>(k)]) << "image " << k;
    const DepthPngSize size = checkColorPng(seq.rgb_files[static_cast<std::size_t>(k)].string());
    EXPECT_EQ(size.width, kWidth);
    EXPECT_EQ(size.height, kHeight);
  }
  // Grey with alpha: grey colours, the alpha dropped.
  const fs::path ga = scratch.dir() / "ga.png";
  writePng8(ga, 2, 1, PNG_COLOR_TYPE_GRAY_ALPHA, {17, 0, 200, 255});
  EXPECT_TRUE(readColorPng(ga.string()).colors ==
              (std::vector<Rgb>{{17, 17, 17}, {200, 200, 200}}));
  // From memory as from the file.
  EXPECT_TRUE(io::decodeColorPng(readFile(seq.rgb_files[0]), "rgb0").colors == seq.colours[0]);
}

// Each refusal names the file, its format and what is accepted, from the header.
TEST(PayloadCliReader, RefusesSixteenBitColourAndOtherFormats) {
  Scratch scratch("payload");
  const fs::path rgb16 = scratch.dir() / "rgb16.png";
  {
    std::vector<unsigned char> samples(2 * 2 * 3 * 2, 0x80);
    std::vector<png_bytep> rows = {samples.data(), samples.data() + 12};
    ASSERT_TRUE(
        writePngRows(rgb16.c_str(), 2, 2, 16, PNG_COLOR_TYPE_RGB, PNG_INTERLACE_NONE, rows.data()));
  }
  const fs::path depth = scratch.dir() / "depth.png";
  writeDepthPng(depth, 2, 2, {1, 2, 3, 4});
  const fs::path text = scratch.dir() / "text.png";
  std::ofstream(text) << "hello";
  const auto message = [](const fs::path& path) {
    try {
      readColorPng(path.string());
    } catch (const Error& e) {
      EXPECT_EQ(e.code(), ErrorCode::kFormat) << e.what();
      return std::string(e.what());
    }
    ADD_FAILURE() << path << " was read";
    return std::string();
  };
  const std::string m16 = message(rgb16);
  EXPECT_NE(m16.find("'" + rgb16.string() + "' is a RGB colour PNG of bit depth 16"),
            std::string::npos)
      << m16;
  EXPECT_NE(m16.find("8-bit RGB, RGBA or grayscale"), std::string::npos) << m16;
  EXPECT_NE(m16.find("convert the images to 8 bits"), std::string::npos) << m16;
  EXPECT_NE(message(depth).find("grayscale PNG of bit depth 16"), std::string::npos);
  EXPECT_NE(message(text).find("is not a PNG file"), std::string::npos);
  EXPECT_THROW(checkColorPng(rgb16.string()), Error);
}

TEST(PayloadCliReader, EachImageTakesTheNearestColourImage) {
  Scratch scratch("payload");
  const ColorSequence seq = makeColorSequence(scratch.dir() / "seq");
  const TumSequence plain = readTumSequence(seq.dir.string());
  EXPECT_EQ(plain.color_images, 0u);
  EXPECT_EQ(plain.frames[0].color_path, "");
  const TumSequence read =
      readTumSequence(seq.dir.string(), kTumMaxTimeDifference, TumColor::kRgbTxt);
  ASSERT_EQ(read.frames.size(), std::size_t{kImages});
  EXPECT_EQ(read.color_images, std::size_t{kImages + 1});
  for (int k = 0; k < kImages; ++k) {
    const TumFrame& frame = read.frames[static_cast<std::size_t>(k)];
    EXPECT_EQ(fs::path(frame.color_path), seq.rgb_files[static_cast<std::size_t>(k)]);
    EXPECT_NEAR(frame.color_timestamp - frame.timestamp, 0.007, 1e-6);
    EXPECT_EQ(frame.color_line, std::size_t{k == 0 ? 3u : k == 1 ? 5u : 6u});
  }
  // A tie goes to the earlier image, and one image may serve two depth images.
  io::TumListNames names{
      .dir = "D", .depth = "D/depth.txt", .groundtruth = "D/gt", .rgb = "D/rgb.txt"};
  TumSequence two;
  two.frames.resize(2);
  two.frames[0].timestamp = 10.0;
  two.frames[1].timestamp = 10.004;
  io::associateColorImages(two, io::parseImageList("9.99 a.png\n10.01 b.png\n", "D/rgb.txt"), names,
                           kTumMaxTimeDifference);
  EXPECT_EQ(two.frames[0].color_path, (fs::path("D") / "a.png").string());
  EXPECT_EQ(two.frames[1].color_path, (fs::path("D") / "b.png").string());
  EXPECT_EQ(two.frames[1].color_line, 2u);
}

TEST(PayloadCliReader, BadRgbListsNameTheLine) {
  const auto message = [](const std::string& text) {
    try {
      io::parseImageList(text, "DIR/rgb.txt");
    } catch (const Error& e) {
      EXPECT_EQ(e.code(), ErrorCode::kFormat);
      return std::string(e.what());
    }
    ADD_FAILURE() << "accepted: " << text;
    return std::string();
  };
  EXPECT_NE(message("# c\n1.0 a.png\n2.0\n").find("'DIR/rgb.txt' line 3: expected 2 fields"),
            std::string::npos);
  EXPECT_NE(message("1.0 a.png\nx b.png\n").find("line 2: the timestamp 'x'"), std::string::npos);
  EXPECT_NE(message("1.0 /etc/passwd\n").find("is absolute; rgb.txt names images"),
            std::string::npos);
  EXPECT_NE(message("1.0 ../a.png\n").find("has a '..' component; rgb.txt"), std::string::npos);
  EXPECT_NE(message("# only\n\n").find("lists no images"), std::string::npos);
}

// ---- integrate --color ----

// `integrate DIR --color` against OctoMap's ColorOcTree doing the same steps, byte for byte, and
// the file reads back as a ColorOcTree in OctoMap.
TEST(PayloadCli, IntegrateColorEqualsColorOcTree) {
  OCTOVK_REQUIRE_CONTEXT(ctx);
  (void)ctx;  // the program makes its own; a missing device skips (fails under CI)
  Scratch scratch("payload");
  const ColorSequence seq = makeColorSequence(scratch.dir() / "seq");
  const std::string ot = scratch / "map.ot";
  std::vector<std::string> args = {"integrate", seq.dir.string(), "--color", "-o", ot, "-r",
                                   "0.1",       "--quiet"};
  for (const std::string& a : cameraArgs()) args.push_back(a);
  const RunResult r = runOctovk(args, scratch.dir());
  ASSERT_EQ(r.exit_code, 0) << r.out << r.err;
  EXPECT_EQ(r.err, "");
  EXPECT_NE(r.out.find("colour:        ColorOcTree: each depth pixel coloured by rgb.txt's image "
                       "nearest in time (4 listed"),
            std::string::npos)
      << r.out;

  const std::string expected = colourOracleOt(seq, 0.1, scratch.dir() / "oracle.ot");
  ASSERT_GT(expected.size(), 1000u);
  EXPECT_TRUE(readFile(ot) == expected) << "the .ot differs from OctoMap's ColorOcTree";

  std::unique_ptr<octomap::AbstractOcTree> read(octomap::AbstractOcTree::read(ot));
  ASSERT_NE(read, nullptr);
  auto* tree = dynamic_cast<octomap::ColorOcTree*>(read.get());
  ASSERT_NE(tree, nullptr) << read->getTreeType();
  std::size_t coloured = 0;
  for (auto it = tree->begin_leafs(), end = tree->end_leafs(); it != end; ++it)
    coloured += it->isColorSet() ? 1 : 0;
  EXPECT_GT(coloured, 50u);
}

void expectNoMapLeft(const Scratch& scratch) {
  for (const auto& entry : fs::recursive_directory_iterator(scratch.dir())) {
    const std::string name = entry.path().filename().string();
    EXPECT_FALSE(entry.is_regular_file() && (name.ends_with(".ot") || name.ends_with(".bt") ||
                                             name.find(".tmp") != std::string::npos))
        << "left behind: " << entry.path();
  }
}

// One error line, exit `code`, naming each of `mentions`, and no map written.
void expectIntegrateRefused(const std::vector<std::string>& extra, int code,
                            const std::vector<std::string>& mentions, const Scratch& scratch,
                            const std::string& input) {
  std::vector<std::string> args = {"integrate", input, "-o", scratch / "map.ot", "--quiet"};
  args.insert(args.end(), extra.begin(), extra.end());
  const RunResult r = runOctovk(args, scratch.dir());
  expectOneErrorLine(r, code, mentions);
  expectNoMapLeft(scratch);
}

void replaceInFile(const fs::path& file, const std::string& from, const std::string& to) {
  std::string text = readFile(file);
  const std::size_t at = text.find(from);
  ASSERT_NE(at, std::string::npos) << from;
  text.replace(at, from.size(), to);
  std::ofstream(file, std::ios_base::binary | std::ios_base::trunc) << text;
}

TEST(PayloadCliBadInput, BadRgbTxtLine) {
  Scratch scratch("payload");
  const ColorSequence seq = makeColorSequence(scratch.dir() / "seq");
  std::ofstream(seq.dir / "rgb.txt", std::ios_base::app) << "1305031102.3 rgb/x.png extra\n";
  expectIntegrateRefused({"--color"}, 1, {"rgb.txt' line 7", "expected 2 fields"}, scratch,
                         seq.dir.string());
}

TEST(PayloadCliBadInput, MissingColourImage) {
  Scratch scratch("payload");
  const ColorSequence seq = makeColorSequence(scratch.dir() / "seq");
  fs::remove(seq.rgb_files[2]);
  expectIntegrateRefused(
      {"--color"}, 1,
      {"rgb.txt' line 6: colour image '" + seq.rgb_files[2].string() + "' does not exist"}, scratch,
      seq.dir.string());
}

TEST(PayloadCliBadInput, SixteenBitColourImage) {
  Scratch scratch("payload");
  const ColorSequence seq = makeColorSequence(scratch.dir() / "seq");
  std::vector<unsigned char> samples(kWidth * kHeight * 6, 0x40);
  std::vector<png_bytep> rows(kHeight);
  for (std::uint32_t y = 0; y < kHeight; ++y) rows[y] = samples.data() + y * kWidth * 6;
  ASSERT_TRUE(writePngRows(seq.rgb_files[1].c_str(), kWidth, kHeight, 16, PNG_COLOR_TYPE_RGB,
                           PNG_INTERLACE_NONE, rows.data()));
  expectIntegrateRefused({"--color"}, 1,
                         {"colour image '" + seq.rgb_files[1].string() + "'", "bit depth 16",
                          "8-bit RGB, RGBA or grayscale"},
                         scratch, seq.dir.string());
}

TEST(PayloadCliBadInput, NoColourImageWithinTheLimit) {
  Scratch scratch("payload");
  const ColorSequence seq = makeColorSequence(scratch.dir() / "seq");
  // The third image's colour image moved 0.03 s later: none within 0.02 s of it.
  const std::string name = seq.rgb_files[2].filename().string();
  const std::string stamp = name.substr(0, name.size() - 4);
  replaceInFile(seq.dir / "rgb.txt", stamp + " ", fixed(std::stod(stamp) + 0.03, 6) + " ");
  expectIntegrateRefused({"--color"}, 1,
                         {"depth.txt' line 5: depth image 1305031102.241904", "no colour image",
                          "less than 0.020000 s away", "the nearest, 1305031102.215604 on line 5"},
                         scratch, seq.dir.string());
}

TEST(PayloadCliBadInput, ColourImageOfAnotherSize) {
  Scratch scratch("payload");
  const ColorSequence seq = makeColorSequence(scratch.dir() / "seq");
  writePng8(seq.rgb_files[0], 4, 2, PNG_COLOR_TYPE_GRAY, std::vector<unsigned char>(8, 9));
  expectIntegrateRefused({"--color"}, 1,
                         {"its colour image '" + seq.rgb_files[0].string() + "'", "is 4 x 2 pixels",
                          "the depth image 32 x 24"},
                         scratch, seq.dir.string());
}

TEST(PayloadCliBadInput, ColourOptionsInTheWrongPlace) {
  Scratch scratch("payload");
  const ColorSequence seq = makeColorSequence(scratch.dir() / "seq");
  const std::string graph = scratch / "scans.graph";
  writeScanGraph(graph, 1, [](std::size_t) {
    GraphScan scan;
    scan.points_sensor = {{1, 0, 0}};
    return scan;
  });
  expectIntegrateRefused({"--color"}, 2, {"--color", "holds no colours"}, scratch, graph);
  expectIntegrateRefused({"--color", "-o", scratch / "map.bt"}, 2,
                         {"map.bt': a .bt file holds occupancy only", "ColorOcTree", "MAP.ot"},
                         scratch, seq.dir.string());
  expectIntegrateRefused({"--color", "--stamped"}, 2, {"colours or time stamps, not both"}, scratch,
                         seq.dir.string());
  fs::remove(seq.dir / "rgb.txt");
  expectIntegrateRefused({"--color"}, 2, {"has no rgb.txt, which --color reads"}, scratch,
                         seq.dir.string());
}

// ---- integrate --stamps, --stamped, --degrade-after ----

// OcTreeStamped whose clock is the scan's stamp: every node a scan updates takes `now`, as
// OcTreeStamped's updateNodeLogOdds does with time(NULL).
class StampClockTree : public octomap::OcTreeStamped {
 public:
  using OcTreeStamped::OcTreeStamped;
  unsigned int now = 0;
  void updateNodeLogOdds(octomap::OcTreeNodeStamped* node, const float& update) const override {
    octomap::OccupancyOcTreeBase<octomap::OcTreeNodeStamped>::updateNodeLogOdds(node, update);
    node->setTimestamp(now);
  }
  // degradeOutdatedNodes at query time `now` instead of time(NULL), then updateInnerOccupancy()
  // (octovk's degradeOutdated).
  void degradeAt(unsigned int query_time, unsigned int threshold) {
    for (auto it = begin_leafs(), end = end_leafs(); it != end; ++it)
      if (isNodeOccupied(*it) && query_time - it->getTimestamp() > threshold)
        integrateMissNoTime(&*it);
    updateInnerOccupancy();
  }
};

// Four one-ray scans along -x through the 2 x 2 rows of cells at y, z in [0, 0.2): side by side
// they give 8 sibling cells one miss each, which merge only where their stamps are equal
// (OcTreeNodeStamped::operator==); then two scans of a wall at +x (out of the rays' cells, which
// they would otherwise make unequal again) from sensors a little apart.
std::vector<GraphScan> stampScans() {
  std::vector<GraphScan> scans(6);
  for (std::size_t i = 0; i < 4; ++i) {
    scans[i].points_sensor = {{-2.0f, 0.0f, 0.0f}};
    scans[i].T_world_sensor.translation = {0.0f, i % 2 == 0 ? 0.05f : 0.15f, i < 2 ? 0.05f : 0.15f};
  }
  for (std::size_t i = 4; i < scans.size(); ++i) {
    for (float y = -0.8f; y <= 0.8f; y += 0.05f)
      for (float z = -0.6f; z <= 0.6f; z += 0.05f)
        scans[i].points_sensor.emplace_back(1.6f + 0.1f * static_cast<float>(i), y, z);
    scans[i].T_world_sensor.translation = {0.1f * static_cast<float>(i - 4), 0.05f, 0.0f};
    scans[i].T_world_sensor.rotation = Eigen::Quaternionf(
        Eigen::AngleAxisf(0.1f * static_cast<float>(i - 4), Eigen::Vector3f::UnitZ()));
  }
  return scans;
}

// The stamps the tests give the scans: the one-ray scans a second apart, the walls later.
const std::vector<unsigned int> kStamps = {100, 101, 102, 103, 120, 135};

std::string writeStampGraph(const Scratch& scratch) {
  const std::string graph = scratch / "scans.graph";
  const std::vector<GraphScan> scans = stampScans();
  writeScanGraph(graph, scans.size(), [&](std::size_t i) { return scans[i]; });
  return graph;
}

// The oracle: each scan as graph2tree inserts it with the clock at its stamp, after a degrade at
// that stamp when `degrade_after` is not negative.
std::unique_ptr<StampClockTree> stampOracle(const std::vector<unsigned int>& stamps,
                                            long degrade_after) {
  auto tree = std::make_unique<StampClockTree>(0.1);
  const std::vector<GraphScan> scans = stampScans();
  for (std::size_t i = 0; i < scans.size(); ++i) {
    if (degrade_after >= 0) tree->degradeAt(stamps[i], static_cast<unsigned int>(degrade_after));
    tree->now = stamps[i];
    tree->insertPointCloud(toPointcloud(scans[i].points_sensor),
                           toPoint(graph2treeSensorOrigin(scans[i].T_world_sensor)),
                           toPose6D(scans[i].T_world_sensor), -1.0, false, false);
  }
  return tree;
}

// The oracle's .ot (written to `out`).
std::string stampOracleOt(const std::vector<unsigned int>& stamps, long degrade_after,
                          const fs::path& out) {
  EXPECT_TRUE(stampOracle(stamps, degrade_after)->write(out.string()));
  return readFile(out);
}

TEST(PayloadCli, IntegrateStampsEqualsOcTreeStamped) {
  OCTOVK_REQUIRE_CONTEXT(ctx);
  Scratch scratch("payload");
  const std::string graph = writeStampGraph(scratch);
  const std::string stamps = scratch / "stamps.txt";
  std::ofstream(stamps) << "# scan stamps\n100\n101\n\n102\r\n103\n  120 \n135\n";
  for (const long degrade : {-1L, 10L}) {
    SCOPED_TRACE(degrade);
    const std::string ot = scratch / "map.ot";
    std::vector<std::string> args = {"integrate", graph, "--stamps", stamps,   "-o",
                                     ot,          "-r",  "0.1",      "--quiet"};
    if (degrade >= 0) args.insert(args.end(), {"--degrade-after", std::to_string(degrade)});
    const RunResult r = runOctovk(args, scratch.dir());
    ASSERT_EQ(r.exit_code, 0) << r.out << r.err;
    EXPECT_NE(r.out.find("stamps:        OcTreeStamped: 100 to 135 s, from " + stamps),
              std::string::npos)
        << r.out;
    EXPECT_EQ(r.out.find("degraded:") != std::string::npos, degrade >= 0) << r.out;
    EXPECT_NE(r.out.find("wrote:         " + ot + ".stamps\n"), std::string::npos) << r.out;
    EXPECT_EQ(temporariesIn(scratch.dir()), std::vector<std::string>{});
    const std::unique_ptr<StampClockTree> oracle = stampOracle(kStamps, degrade);
    const std::string expected = stampOracleOt(kStamps, degrade, scratch.dir() / "oracle.ot");
    EXPECT_TRUE(readFile(ot) == expected) << "the .ot differs from OctoMap's OcTreeStamped";
    std::unique_ptr<octomap::AbstractOcTree> read(octomap::AbstractOcTree::read(ot));
    ASSERT_NE(read, nullptr);
    EXPECT_NE(dynamic_cast<octomap::OcTreeStamped*>(read.get()), nullptr) << read->getTreeType();
    // The stamps themselves, which the .ot lacks, come back from MAP.ot.stamps: every leaf's.
    StampedMap map(readMapFile(ctx, ot));
    std::vector<Eigen::Vector3f> centres;
    std::vector<unsigned int> expected_stamps;
    for (auto it = oracle->begin_leafs(), end = oracle->end_leafs(); it != end; ++it) {
      const octomap::point3d c = it.getCoordinate();
      centres.emplace_back(c.x(), c.y(), c.z());
      expected_stamps.push_back(it->getTimestamp());
    }
    const std::vector<std::uint32_t> got = map.stamps(centres);
    ASSERT_EQ(got.size(), expected_stamps.size());
    std::size_t differ = 0;
    for (std::size_t i = 0; i < got.size(); ++i) differ += got[i] != expected_stamps[i] ? 1 : 0;
    EXPECT_EQ(differ, 0u) << "of " << got.size() << " leaves";
  }
}

// edit keeps a stamped map's stamps: the edited .ot gets its own PATH.stamps, renamed with it, and
// no temporary is left behind.
TEST(PayloadCli, EditKeepsAStampedMapsStamps) {
  OCTOVK_REQUIRE_CONTEXT(ctx);
  Scratch scratch("payload");
  const std::string graph = writeStampGraph(scratch);
  const std::string stamps = scratch / "stamps.txt";
  std::ofstream(stamps) << "100\n101\n102\n103\n120\n135\n";
  const std::string ot = scratch / "map.ot", edited = scratch / "e.ot";
  RunResult r = runOctovk({"integrate", graph, "--stamps", stamps, "-o", ot, "-r", "0.1", "-q"},
                          scratch.dir());
  ASSERT_EQ(r.exit_code, 0) << r.out << r.err;
  r = runOctovk(
      {"edit", ot, "--clear-box", "-100", "-100", "-100", "-99", "-99", "-99", "-o", edited},
      scratch.dir());
  ASSERT_EQ(r.exit_code, 0) << r.out << r.err;
  EXPECT_EQ(temporariesIn(scratch.dir()), std::vector<std::string>{});
  ASSERT_TRUE(std::filesystem::exists(edited + ".stamps")) << r.out;
  // A box outside the scans changes nothing: the same tree, the same stamps.
  EXPECT_TRUE(readFile(edited) == readFile(ot));
  EXPECT_TRUE(readFile(edited + ".stamps") == readFile(ot + ".stamps"));
  StampedMap map(readMapFile(ctx, edited));
  EXPECT_EQ(map.lastUpdateTime() != 0, true);
}

// The oracle comparison above can tell: stamps change the tree (pruning compares them), and so
// does the degrade.
TEST(PayloadCliOracle, StampsAndDegradeChangeTheFile) {
  Scratch scratch("payload");
  const std::string stamped = stampOracleOt(kStamps, -1, scratch.dir() / "a.ot");
  EXPECT_TRUE(stamped != stampOracleOt({7, 7, 7, 7, 7, 7}, -1, scratch.dir() / "b.ot"));
  EXPECT_TRUE(stamped != stampOracleOt(kStamps, 10, scratch.dir() / "c.ot"));
}

TEST(PayloadCliBadInput, WrongStampCountOrLine) {
  Scratch scratch("payload");
  const std::string graph = writeStampGraph(scratch);
  const std::string stamps = scratch / "stamps.txt";
  std::ofstream(stamps) << "1\n2\n3\n4\n5\n";
  expectIntegrateRefused({"--stamps", stamps}, 1,
                         {"stamps file '" + stamps + "' holds 5 stamps", "holds 6 scans"}, scratch,
                         graph);
  std::ofstream(stamps) << "1\n2\n3\n4\n5\n# c\n6\n7\n";
  expectIntegrateRefused({"--stamps", stamps}, 1,
                         {"stamps file '" + stamps + "' line 8", "a stamp for scan 7"}, scratch,
                         graph);
  std::ofstream(stamps) << "100\n10.5\n130\n";
  expectIntegrateRefused({"--stamps", stamps}, 1,
                         {"line 2: '10.5' is not a time stamp", "whole seconds"}, scratch, graph);
  std::ofstream(stamps) << "100\n-3\n130\n";
  expectIntegrateRefused({"--stamps", stamps}, 1, {"line 2: '-3' is not a time stamp"}, scratch,
                         graph);
  std::ofstream(stamps) << "100\n4294967296\n130\n";
  expectIntegrateRefused({"--stamps", stamps}, 1, {"line 2: '4294967296'"}, scratch, graph);
}

TEST(PayloadCliBadInput, StampOptionsInTheWrongPlace) {
  Scratch scratch("payload");
  const std::string graph = writeStampGraph(scratch);
  const ColorSequence seq = makeColorSequence(scratch.dir() / "seq");
  expectIntegrateRefused({"--stamps", scratch / "none.txt"}, 2,
                         {"stamps file '" + scratch / "none.txt" + "' does not exist"}, scratch,
                         graph);
  expectIntegrateRefused({"--stamped"}, 2, {"--stamped", "give --stamps FILE"}, scratch, graph);
  expectIntegrateRefused({"--stamps", graph}, 2, {"--stamps", "use --stamped"}, scratch,
                         seq.dir.string());
  expectIntegrateRefused({"--degrade-after", "5"}, 2, {"--degrade-after needs"}, scratch, graph);
  expectIntegrateRefused({"--stamped", "--degrade-after", "5s"}, 2,
                         {"--degrade-after 5s", "whole seconds"}, scratch, seq.dir.string());
  expectIntegrateRefused({"--stamped", "-o", scratch / "map.bt"}, 2,
                         {"a .bt file holds occupancy only", "OcTreeStamped"}, scratch,
                         seq.dir.string());
}

// A folder's images carry their own time: --stamped gives each scan its image's whole seconds
// (the images here lie in 1305031102 s).
TEST(PayloadCli, IntegrateStampedTakesTheImagesSeconds) {
  OCTOVK_REQUIRE_CONTEXT(ctx);
  (void)ctx;  // the program makes its own; a missing device skips (fails under CI)
  Scratch scratch("payload");
  const ColorSequence seq = makeColorSequence(scratch.dir() / "seq");
  const std::string ot = scratch / "map.ot";
  std::vector<std::string> args = {"integrate", seq.dir.string(), "--stamped", "-o", ot, "--quiet"};
  for (const std::string& a : cameraArgs()) args.push_back(a);
  const RunResult r = runOctovk(args, scratch.dir());
  ASSERT_EQ(r.exit_code, 0) << r.out << r.err;
  EXPECT_NE(r.out.find("stamps:        OcTreeStamped: 1305031102 to 1305031102 s, the images' "
                       "time stamps in whole seconds"),
            std::string::npos)
      << r.out;
  std::unique_ptr<octomap::AbstractOcTree> read(octomap::AbstractOcTree::read(ot));
  ASSERT_NE(read, nullptr);
  EXPECT_NE(dynamic_cast<octomap::OcTreeStamped*>(read.get()), nullptr) << read->getTreeType();
}

// ---- render ----

// The pixels of an 8-bit RGB PNG (libpng's simplified reader).
std::vector<std::uint8_t> readRgbPng(const std::string& path, std::uint32_t* width) {
  png_image image{};
  image.version = PNG_IMAGE_VERSION;
  if (!png_image_begin_read_from_file(&image, path.c_str())) return {};
  image.format = PNG_FORMAT_RGB;
  std::vector<std::uint8_t> pixels(PNG_IMAGE_SIZE(image));
  if (!png_image_finish_read(&image, nullptr, pixels.data(), 0, nullptr)) return {};
  *width = image.width;
  return pixels;
}

// A ColorOcTree floor, its left half red and its right half green, drawn in those colours (a
// plain map's flat floor would be one height colour).
TEST(PayloadCli, RenderDrawsAColorOcTreeInItsColours) {
  OCTOVK_REQUIRE_CONTEXT(ctx);
  (void)ctx;  // the program makes its own; a missing device skips (fails under CI)
  Scratch scratch("payload");
  octomap::ColorOcTree tree(0.1);
  for (int x = -10; x < 10; ++x)
    for (int y = -8; y < 8; ++y) {
      const octomap::point3d p(0.1f * static_cast<float>(x) + 0.05f,
                               0.1f * static_cast<float>(y) + 0.05f, 0.05f);
      octomap::ColorOcTreeNode* node = tree.updateNode(p, true);
      ASSERT_NE(node, nullptr);
      if (x < 0)
        node->setColor(220, 30, 30);
      else
        node->setColor(30, 220, 30);
    }
  tree.updateInnerOccupancy();
  const std::string ot = scratch / "floor.ot", png = scratch / "floor.png";
  ASSERT_TRUE(tree.write(ot));
  const RunResult r = runOctovk({"render", ot, "-o", png, "--size", "160x120"}, scratch.dir());
  ASSERT_EQ(r.exit_code, 0) << r.out << r.err;
  EXPECT_NE(r.out.find("colours: the map's own (ColorOcTree); 0 of the hits white"),
            std::string::npos)
      << r.out;
  std::uint32_t width = 0;
  const std::vector<std::uint8_t> pixels = readRgbPng(png, &width);
  ASSERT_EQ(width, 160u);
  std::size_t red = 0, green = 0;
  for (std::size_t p = 0; p + 2 < pixels.size(); p += 3) {
    const int cr = pixels[p], cg = pixels[p + 1], cb = pixels[p + 2];
    red += cr > cg + 50 && cr > cb + 50 ? 1 : 0;
    green += cg > cr + 50 && cg > cb + 50 ? 1 : 0;
  }
  EXPECT_GT(red, 1000u);
  EXPECT_GT(green, 1000u);
}

// ---- help and docs ----

TEST(PayloadCliHelp, HelpAndDocsNameTheFlags) {
  Scratch scratch("payload");
  const RunResult help = runOctovk({"integrate", "--help"}, scratch.dir());
  ASSERT_EQ(help.exit_code, 0);
  const std::string docs = readFile(fs::path(OCTOVK_SOURCE_DIR) / "docs" / "cli.md");
  for (const std::string flag : {"--color", "--stamps FILE", "--stamped", "--degrade-after S"}) {
    EXPECT_NE(help.out.find("      " + flag + " "), std::string::npos) << flag << help.out;
    EXPECT_NE(docs.find("`" + flag.substr(0, flag.find(' '))), std::string::npos) << flag;
  }
  const RunResult render = runOctovk({"render", "--help"}, scratch.dir());
  EXPECT_NE(render.out.find("ColorOcTree"), std::string::npos) << render.out;
}

}  // namespace
}  // namespace octovk::test
