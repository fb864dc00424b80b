// cli_query_test: `octovk info`, `render` and `export` run as a user runs them. Counts and cells
// must be OctoMap's on the same file (read with OctoMap here), pictures must be real PNGs of the
// requested size, and bad input must give one error line, a non-zero exit code and no file.
#include <gtest/gtest.h>
#include <octomap/AbstractOcTree.h>
#include <octomap/OcTree.h>
#include <png.h>
#include <sys/wait.h>
#include <unistd.h>

#include <algorithm>
#include <array>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <memory>
#include <random>
#include <set>
#include <sstream>
#include <string>
#include <vector>

#include "cli_support.hpp"
#include "test_support.hpp"

namespace octovk::test {
namespace {

namespace fs = std::filesystem;

const std::string kGeb079 = OCTOVK_PATH(OCTOVK_OCTOMAP_DATA_DIR) + "/geb079.bt";
const std::string kSphericalGraph = OCTOVK_PATH(OCTOVK_OCTOMAP_DATA_DIR) + "/spherical_scan.graph";

// The rest of the stdout line that starts with `label` ("nodes:"), trimmed; empty if none.
std::string field(const std::string& out, const std::string& label) {
  std::istringstream lines(out);
  for (std::string line; std::getline(lines, line);) {
    if (line.rfind(label, 0) != 0) continue;
    const std::size_t at = line.find_first_not_of(' ', label.size());
    return at == std::string::npos ? "" : line.substr(at);
  }
  return "";
}

// The leading integer of a field ("143729 leaves, 95.065 m^3" -> 143729); -1 when missing.
long long countField(const std::string& out, const std::string& label) {
  const std::string text = field(out, label);
  if (text.empty() || !std::isdigit(static_cast<unsigned char>(text[0]))) return -1;
  return std::stoll(text);
}

// ---- OctoMap's view of a file ----

struct OracleCounts {
  std::size_t nodes = 0, leaves = 0, occupied = 0;
  double min[3] = {}, max[3] = {};  // of all leaves (OctoMap's getMetricMin / getMetricMax)
};

std::unique_ptr<octomap::OcTree> readOracle(const std::string& path) {
  std::ifstream in(path, std::ios_base::binary);
  if (fs::path(path).extension() == ".bt") {
    auto tree = std::make_unique<octomap::OcTree>(0.1);
    if (!tree->readBinary(in)) return nullptr;
    return tree;
  }
  std::unique_ptr<octomap::AbstractOcTree> tree(octomap::AbstractOcTree::read(in));
  auto* as_tree = dynamic_cast<octomap::OcTree*>(tree.get());
  if (!as_tree) return nullptr;
  tree.release();
  return std::unique_ptr<octomap::OcTree>(as_tree);
}

OracleCounts oracleCounts(octomap::OcTree& tree) {
  OracleCounts c;
  c.nodes = tree.size();
  for (auto it = tree.begin_leafs(), end = tree.end_leafs(); it != end; ++it) {
    ++c.leaves;
    if (tree.isNodeOccupied(*it)) ++c.occupied;
  }
  tree.getMetricMin(c.min[0], c.min[1], c.min[2]);
  tree.getMetricMax(c.max[0], c.max[1], c.max[2]);
  return c;
}

// ---- PLY and PNG files ----

// One PLY vertex as bits: x, y, z, size, log-odds (floats), then red, green, blue.
using Vertex = std::array<std::uint32_t, 8>;

struct Ply {
  long long declared = -1;  // "element vertex N"
  std::vector<Vertex> vertices;
  std::string error;
};

Ply readPly(const fs::path& path) {
  Ply ply;
  std::ifstream in(path);
  std::string line;
  std::vector<std::string> header;
  while (std::getline(in, line) && line != "end_header") header.push_back(line);
  if (header.empty() || header[0] != "ply" || header.size() < 2 ||
      header[1] != "format ascii 1.0") {
    ply.error = "not an ASCII PLY file";
    return ply;
  }
  const std::vector<std::string> properties = {"property float x",        "property float y",
                                               "property float z",        "property float size",
                                               "property float log_odds", "property uchar red",
                                               "property uchar green",    "property uchar blue"};
  std::vector<std::string> found;
  for (const std::string& h : header) {
    if (h.rfind("element vertex ", 0) == 0) ply.declared = std::stoll(h.substr(15));
    if (h.rfind("property ", 0) == 0) found.push_back(h);
  }
  if (found != properties) {
    ply.error = "unexpected vertex properties";
    return ply;
  }
  while (std::getline(in, line)) {
    std::istringstream fields(line);
    float f[5];
    unsigned rgb[3];
    if (!(fields >> f[0] >> f[1] >> f[2] >> f[3] >> f[4] >> rgb[0] >> rgb[1] >> rgb[2]) ||
        rgb[0] > 255 || rgb[1] > 255 || rgb[2] > 255) {
      ply.error = "bad vertex line '" + line + "'";
      return ply;
    }
    Vertex v{};
    for (int i = 0; i < 5; ++i) v[i] = octovk::test::floatBits(f[i]);
    for (int i = 0; i < 3; ++i) v[5 + i] = rgb[i];
    ply.vertices.push_back(v);
  }
  return ply;
}

// Centre, size and log-odds bits of the leaves OctoMap visits, sorted (as the PLY's first 5).
using Cell = std::array<std::uint32_t, 5>;

template <class Iterator>
std::vector<Cell> oracleCells(const octomap::OcTree& tree, Iterator it, Iterator end,
                              bool occupied_only) {
  using octovk::test::floatBits;
  std::vector<Cell> out;
  for (; it != end; ++it) {
    if (occupied_only && !tree.isNodeOccupied(*it)) continue;
    const octomap::point3d c = it.getCoordinate();
    out.push_back({floatBits(c.x()), floatBits(c.y()), floatBits(c.z()),
                   floatBits(static_cast<float>(it.getSize())), floatBits(it->getLogOdds())});
  }
  std::sort(out.begin(), out.end());
  return out;
}

std::vector<Cell> plyCells(const Ply& ply) {
  std::vector<Cell> out;
  for (const Vertex& v : ply.vertices) out.push_back({v[0], v[1], v[2], v[3], v[4]});
  std::sort(out.begin(), out.end());
  return out;
}

std::uint32_t bigEndian32(const std::string& bytes, std::size_t at) {
  return (std::uint32_t{static_cast<unsigned char>(bytes[at])} << 24) |
         (std::uint32_t{static_cast<unsigned char>(bytes[at + 1])} << 16) |
         (std::uint32_t{static_cast<unsigned char>(bytes[at + 2])} << 8) |
         std::uint32_t{static_cast<unsigned char>(bytes[at + 3])};
}

// Checks the PNG signature and IHDR (size, 8-bit RGB), decodes the picture with libpng and
// returns its number of distinct colours.
::testing::AssertionResult isRgbPng(const fs::path& path, std::uint32_t width, std::uint32_t height,
                                    std::size_t* colours) {
  const std::string bytes = readFile(path);
  if (bytes.size() < 33) return ::testing::AssertionFailure() << path << " is too short";
  if (bytes.compare(0, 8, std::string("\x89PNG\r\n\x1a\n", 8)) != 0)
    return ::testing::AssertionFailure() << path << " lacks the PNG signature";
  if (bigEndian32(bytes, 8) != 13 || bytes.compare(12, 4, "IHDR") != 0)
    return ::testing::AssertionFailure() << path << ": the first chunk is not IHDR";
  const std::uint32_t w = bigEndian32(bytes, 16), h = bigEndian32(bytes, 20);
  if (w != width || h != height)
    return ::testing::AssertionFailure()
           << "IHDR says " << w << "x" << h << ", expected " << width << "x" << height;
  if (bytes[24] != 8 || bytes[25] != 2)
    return ::testing::AssertionFailure() << "bit depth " << int(bytes[24]) << ", colour type "
                                         << int(bytes[25]) << "; expected 8-bit RGB (8, 2)";
  png_image image{};
  image.version = PNG_IMAGE_VERSION;
  if (!png_image_begin_read_from_memory(&image, bytes.data(), bytes.size()))
    return ::testing::AssertionFailure() << "libpng: " << image.message;
  image.format = PNG_FORMAT_RGB;
  std::vector<std::uint8_t> pixels(PNG_IMAGE_SIZE(image));
  if (!png_image_finish_read(&image, nullptr, pixels.data(), 0, nullptr))
    return ::testing::AssertionFailure() << "libpng: " << image.message;
  std::set<std::uint32_t> distinct;
  for (std::size_t i = 0; i + 2 < pixels.size(); i += 3)
    distinct.insert(std::uint32_t{pixels[i]} << 16 | std::uint32_t{pixels[i + 1]} << 8 |
                    pixels[i + 2]);
  *colours = distinct.size();
  return ::testing::AssertionSuccess();
}

// What the legend strip of a picture (the columns from `x0` on) holds: the colours of the
// height bar (saturated pixels) and the light pixels of its text.
struct Legend {
  std::size_t bar_colours = 0, text_pixels = 0;
};

Legend legendOf(const fs::path& path, std::uint32_t x0) {
  Legend legend;
  const std::string bytes = readFile(path);
  png_image image{};
  image.version = PNG_IMAGE_VERSION;
  if (!png_image_begin_read_from_memory(&image, bytes.data(), bytes.size())) return legend;
  image.format = PNG_FORMAT_RGB;
  std::vector<std::uint8_t> pixels(PNG_IMAGE_SIZE(image));
  if (!png_image_finish_read(&image, nullptr, pixels.data(), 0, nullptr)) return legend;
  std::set<std::uint32_t> colours;
  for (std::uint32_t y = 0; y < image.height; ++y)
    for (std::uint32_t x = x0; x < image.width; ++x) {
      const std::uint8_t* c = &pixels[(std::size_t{y} * image.width + x) * 3];
      const int lo = std::min({c[0], c[1], c[2]}), hi = std::max({c[0], c[1], c[2]});
      if (hi - lo > 80) colours.insert(std::uint32_t{c[0]} << 16 | std::uint32_t{c[1]} << 8 | c[2]);
      legend.text_pixels += lo > 150;
    }
  legend.bar_colours = colours.size();
  return legend;
}

// A small map made once per test process by `octovk integrate` of the spherical scan at 0.2 m,
// as .bt and .ot; and one whose beams are all cut by --max-range, so it holds no occupied cell.
class SmallMaps {
 public:
  static const SmallMaps& get() {
    static SmallMaps instance;
    return instance;
  }
  std::string bt, ot, free_only_bt, error;
  ~SmallMaps() { fs::remove_all(dir_); }

 private:
  SmallMaps() {
    dir_ = fs::path(OCTOVK_PATH(OCTOVK_TEST_TMP)) / ("cliquery.maps." + std::to_string(::getpid()));
    fs::create_directories(dir_);
    const std::string b = (dir_ / "spherical.bt").string(), o = (dir_ / "spherical.ot").string();
    const std::string f = (dir_ / "free_only.bt").string();
    RunResult made =
        runOctovk({"integrate", kSphericalGraph, "-r", "0.2", "-o", b, "-o", o, "-q"}, dir_);
    if (made.exit_code != 0) {
      error = made.err;
      return;
    }
    made = runOctovk({"integrate", kSphericalGraph, "-r", "0.2", "-m", "0.3", "-o", f, "-q"}, dir_);
    if (made.exit_code != 0) {
      error = made.err;
      return;
    }
    bt = b;
    ot = o;
    free_only_bt = f;
  }
  fs::path dir_;
};

#define REQUIRE_SMALL_MAPS()                \
  const SmallMaps& maps = SmallMaps::get(); \
  ASSERT_TRUE(maps.error.empty()) << "octovk integrate failed: " << maps.error

// ---- info ----

void expectInfoMatches(const std::string& map_path, const Scratch& scratch) {
  std::unique_ptr<octomap::OcTree> tree = readOracle(map_path);
  ASSERT_TRUE(tree) << "OctoMap cannot read " << map_path;
  const OracleCounts oracle = oracleCounts(*tree);
  const RunResult r = runOctovk({"info", map_path}, scratch.dir());
  ASSERT_EQ(r.exit_code, 0) << r.err;
  EXPECT_EQ(r.err, "");
  EXPECT_EQ(countField(r.out, "nodes:"), static_cast<long long>(oracle.nodes)) << r.out;
  EXPECT_EQ(countField(r.out, "leaves:"), static_cast<long long>(oracle.leaves)) << r.out;
  EXPECT_EQ(countField(r.out, "occupied:"), static_cast<long long>(oracle.occupied)) << r.out;
  EXPECT_EQ(countField(r.out, "free:"), static_cast<long long>(oracle.leaves - oracle.occupied))
      << r.out;
  double res = 0;
  EXPECT_EQ(std::sscanf(field(r.out, "resolution:").c_str(), "%lf", &res), 1) << r.out;
  EXPECT_NEAR(res, tree->getResolution(), 1e-12);
  double lo[3], hi[3];
  ASSERT_EQ(std::sscanf(field(r.out, "bounds:").c_str(), "min (%lf, %lf, %lf) max (%lf, %lf, %lf)",
                        &lo[0], &lo[1], &lo[2], &hi[0], &hi[1], &hi[2]),
            6)
      << r.out;
  for (int a = 0; a < 3; ++a) {
    EXPECT_NEAR(lo[a], oracle.min[a], 1e-3) << "axis " << a;
    EXPECT_NEAR(hi[a], oracle.max[a], 1e-3) << "axis " << a;
  }
  EXPECT_NE(field(r.out, "device memory:").find("MiB"), std::string::npos) << r.out;
}

TEST(cliQueryInfo, Geb079CountsAreOctoMaps) {
  OCTOVK_REQUIRE_CONTEXT(ctx);
  Scratch scratch;
  expectInfoMatches(kGeb079, scratch);
  const RunResult r = runOctovk({"info", kGeb079}, scratch.dir());
  EXPECT_NE(r.out.find("device:          " + ctx.device().name), std::string::npos) << r.out;
}

TEST(cliQueryInfo, SmallMapBtAndOt) {
  OCTOVK_REQUIRE_CONTEXT(ctx);
  (void)ctx;
  REQUIRE_SMALL_MAPS();
  Scratch scratch;
  expectInfoMatches(maps.bt, scratch);
  expectInfoMatches(maps.ot, scratch);
}

// ---- export ----

// Runs export with `extra` options and compares the PLY's cells with `expected`.
void expectExport(const std::vector<std::string>& extra, const std::vector<Cell>& expected,
                  const Scratch& scratch, const std::string& map_path = kGeb079) {
  const std::string ply_path = scratch / "cells.ply";
  fs::remove(ply_path);
  std::vector<std::string> args = {"export", map_path, "-o", ply_path};
  args.insert(args.end(), extra.begin(), extra.end());
  const RunResult r = runOctovk(args, scratch.dir());
  ASSERT_EQ(r.exit_code, 0) << r.err;
  EXPECT_EQ(r.err, "");
  const Ply ply = readPly(ply_path);
  ASSERT_EQ(ply.error, "");
  EXPECT_EQ(ply.declared, static_cast<long long>(expected.size()));
  EXPECT_EQ(ply.vertices.size(), expected.size());
  EXPECT_EQ(countField(r.out, "cells:"), static_cast<long long>(expected.size())) << r.out;
  EXPECT_TRUE(plyCells(ply) == expected) << "the PLY's cells differ from OctoMap's leaves";
  EXPECT_NE(r.out.find("wrote:   " + ply_path), std::string::npos) << r.out;
}

TEST(cliQueryExport, Geb079AllLeaves) {
  OCTOVK_REQUIRE_CONTEXT(ctx);
  (void)ctx;
  Scratch scratch;
  std::unique_ptr<octomap::OcTree> tree = readOracle(kGeb079);
  ASSERT_TRUE(tree);
  const auto all = oracleCells(*tree, tree->begin_leafs(), tree->end_leafs(), false);
  EXPECT_EQ(all.size(), oracleCounts(*tree).leaves);
  expectExport({}, all, scratch);
}

TEST(cliQueryExport, Geb079OccupiedOnly) {
  OCTOVK_REQUIRE_CONTEXT(ctx);
  (void)ctx;
  Scratch scratch;
  std::unique_ptr<octomap::OcTree> tree = readOracle(kGeb079);
  ASSERT_TRUE(tree);
  const auto occupied = oracleCells(*tree, tree->begin_leafs(), tree->end_leafs(), true);
  EXPECT_EQ(occupied.size(), oracleCounts(*tree).occupied);
  expectExport({"--occupied-only"}, occupied, scratch);
  // --color occupancy: occupied cells all get one colour.
  expectExport({"--occupied-only", "--color", "occupancy"}, occupied, scratch);
  const Ply ply = readPly(scratch / "cells.ply");
  ASSERT_FALSE(ply.vertices.empty());
  for (const Vertex& v : ply.vertices)
    ASSERT_TRUE(std::equal(v.begin() + 5, v.end(), ply.vertices.front().begin() + 5));
}

TEST(cliQueryExport, Geb079BoxIsLeafBbxIterator) {
  OCTOVK_REQUIRE_CONTEXT(ctx);
  (void)ctx;
  Scratch scratch;
  std::unique_ptr<octomap::OcTree> tree = readOracle(kGeb079);
  ASSERT_TRUE(tree);
  const octomap::point3d min(0.0f, -2.0f, 0.0f), max(5.0f, 2.0f, 1.5f);
  const auto in_box =
      oracleCells(*tree, tree->begin_leafs_bbx(min, max), tree->end_leafs_bbx(), false);
  const auto occupied_in_box =
      oracleCells(*tree, tree->begin_leafs_bbx(min, max), tree->end_leafs_bbx(), true);
  ASSERT_GT(occupied_in_box.size(), 0u);
  ASSERT_GT(in_box.size(), occupied_in_box.size());
  expectExport({"--box", "0", "-2", "0", "5", "2", "1.5"}, in_box, scratch);
  expectExport({"--box=0,-2,0,5,2,1.5", "--occupied-only"}, occupied_in_box, scratch);
  // A box larger than the map's domain is the whole map.
  const auto all = oracleCells(*tree, tree->begin_leafs(), tree->end_leafs(), false);
  expectExport({"--box", "-1e9", "-1e9", "-1e9", "1e9", "1e9", "1e9"}, all, scratch);
}

TEST(cliQueryExport, SmallMapOt) {
  OCTOVK_REQUIRE_CONTEXT(ctx);
  (void)ctx;
  REQUIRE_SMALL_MAPS();
  Scratch scratch;
  std::unique_ptr<octomap::OcTree> tree = readOracle(maps.ot);
  ASSERT_TRUE(tree);
  expectExport({}, oracleCells(*tree, tree->begin_leafs(), tree->end_leafs(), false), scratch,
               maps.ot);
}

// ---- render ----

TEST(cliQueryRender, Geb079DefaultCamera) {
  OCTOVK_REQUIRE_CONTEXT(ctx);
  (void)ctx;
  Scratch scratch;
  const std::string png = scratch / "view.png";
  const RunResult r = runOctovk({"render", kGeb079, "-o", png, "--size", "400x250"}, scratch.dir());
  ASSERT_EQ(r.exit_code, 0) << r.err;
  EXPECT_EQ(r.err, "");
  std::size_t colours = 0;
  EXPECT_TRUE(isRgbPng(png, 400, 250, &colours));
  EXPECT_GT(colours, 10u);
  std::size_t hits = 0;
  const std::string rays = field(r.out, "rays:");
  const std::size_t at = rays.find("cast");
  ASSERT_NE(at, std::string::npos) << r.out;
  ASSERT_EQ(std::sscanf(rays.c_str() + rays.find("), ") + 3, "%zu hit", &hits), 1) << r.out;
  // The default camera frames the map: a good part of the picture shows it, not all of it.
  EXPECT_GT(hits, 400u * 250u / 20) << r.out;
  EXPECT_LT(hits, 400u * 250u) << r.out;
  EXPECT_NE(field(r.out, "camera:").find("--eye"), std::string::npos) << r.out;
  EXPECT_NE(r.out.find("wrote:   " + png), std::string::npos) << r.out;
  // The numbers the picture carries, on stdout too: the heights its colours span and the scale.
  double z_lo = 0, z_hi = 0, bar_m = 0, bar_px = 0;
  EXPECT_EQ(std::sscanf(field(r.out, "heights:").c_str(), "%lf to %lf m", &z_lo, &z_hi), 2)
      << r.out;
  EXPECT_LT(z_lo, z_hi) << r.out;
  EXPECT_EQ(std::sscanf(field(r.out, "scale:").c_str(), "%lf m = %lf px", &bar_m, &bar_px), 2)
      << r.out;
  EXPECT_GT(bar_m, 0.0) << r.out;
  EXPECT_GT(bar_px, 10.0) << r.out;
  // The legend strip on the right: the height colour bar, and text.
  const Legend legend = legendOf(png, 400 - 140);
  EXPECT_GT(legend.bar_colours, 40u) << "the colour bar";
  EXPECT_GT(legend.text_pixels, 200u) << "the legend's numbers";
  EXPECT_NE(field(r.out, "image:").find("the legend 140 px on the right"), std::string::npos)
      << r.out;
}

TEST(cliQueryRender, DefaultSizeIs800x600) {
  OCTOVK_REQUIRE_CONTEXT(ctx);
  (void)ctx;
  Scratch scratch;
  const std::string png = scratch / "view.png";
  const RunResult r = runOctovk({"render", kGeb079, "-o", png, "--z-max", "2"}, scratch.dir());
  ASSERT_EQ(r.exit_code, 0) << r.err;
  std::size_t colours = 0;
  EXPECT_TRUE(isRgbPng(png, 800, 600, &colours));
  EXPECT_GT(colours, 10u);
  EXPECT_NE(field(r.out, "image:").find("800x600"), std::string::npos) << r.out;
}

TEST(cliQueryRender, ExplicitCameraOnSmallMap) {
  OCTOVK_REQUIRE_CONTEXT(ctx);
  (void)ctx;
  REQUIRE_SMALL_MAPS();
  Scratch scratch;
  const std::string png = scratch / "view.png";
  // From above the scan's origin, looking down at it.
  const RunResult r = runOctovk({"render", maps.ot, "-o", png, "--eye", "0", "-0.5", "12",
                                 "--look-at=0,0,0", "--size", "120x90", "--fov", "90"},
                                scratch.dir());
  ASSERT_EQ(r.exit_code, 0) << r.err;
  std::size_t colours = 0;
  EXPECT_TRUE(isRgbPng(png, 120, 90, &colours));
  EXPECT_GT(colours, 10u);
  EXPECT_NE(field(r.out, "camera:").find("--eye 0.000 -0.500 12.000 --look-at 0.000 0.000 0.000"),
            std::string::npos)
      << r.out;
  // Too small for a legend: all view, and the summary says so.
  EXPECT_NE(field(r.out, "image:").find("no legend"), std::string::npos) << r.out;
  EXPECT_NE(field(r.out, "heights:").find(" m"), std::string::npos) << r.out;
}

// ---- bad input: one error line, the right exit code, nothing written ----

// Runs octovk with `args` and expects exit code `exit_code`, one stderr line that starts with
// "octovk: error: " and mentions `mention`, no stdout, and no picture, PLY or temporary file.
void expectRejected(const std::vector<std::string>& args, int exit_code, const std::string& mention,
                    const Scratch& scratch) {
  const RunResult r = runOctovk(args, scratch.dir());
  EXPECT_EQ(r.exit_code, exit_code) << r.err;
  EXPECT_NE(r.exit_code, 0);
  EXPECT_EQ(r.err.rfind("octovk: error: ", 0), 0u) << r.err;
  EXPECT_EQ(std::count(r.err.begin(), r.err.end(), '\n'), 1) << r.err;
  EXPECT_NE(r.err.find(mention), std::string::npos) << "expected '" << mention << "' in: " << r.err;
  EXPECT_EQ(r.out, "");
  for (const auto& entry : fs::recursive_directory_iterator(scratch.dir())) {
    const std::string name = entry.path().filename().string();
    EXPECT_FALSE(entry.is_regular_file() && (name.ends_with(".png") || name.ends_with(".ply") ||
                                             name.find(".tmp") != std::string::npos))
        << "left behind: " << entry.path();
  }
}

// A .bt file cut in half, and one of random bytes behind a valid header line.
struct BadMaps {
  std::string truncated, garbage;
  explicit BadMaps(const Scratch& scratch) {
    truncated = scratch / "truncated.bt";
    garbage = scratch / "garbage.bt";
    const std::string whole = readFile(kGeb079);
    std::ofstream(truncated, std::ios_base::binary) << whole.substr(0, whole.size() / 2);
    std::ofstream out(garbage, std::ios_base::binary);
    out << "# Octomap OcTree binary file\n";
    std::mt19937 rng(7);
    for (int i = 0; i < 4096; ++i) out.put(static_cast<char>(rng() & 0xFF));
  }
};

TEST(cliQueryBadInput, InfoUsage) {
  Scratch scratch;
  expectRejected({"info"}, 2, "no map file", scratch);
  expectRejected({"info", scratch / "missing.bt"}, 2, "does not exist", scratch);
  std::ofstream(scratch / "map.txt") << "x";
  expectRejected({"info", scratch / "map.txt"}, 2, "'.txt'", scratch);
  expectRejected({"info", scratch.dir().string()}, 2, "directory", scratch);
  expectRejected({"info", kGeb079, "--bogus"}, 2, "--bogus", scratch);
  expectRejected({"info", kGeb079, kGeb079}, 2, "one map file", scratch);
}

TEST(cliQueryBadInput, CorruptMaps) {
  OCTOVK_REQUIRE_CONTEXT(ctx);
  (void)ctx;
  Scratch scratch;
  const BadMaps bad(scratch);
  for (const std::string& map : {bad.truncated, bad.garbage}) {
    expectRejected({"info", map}, 1, "corrupt", scratch);
    expectRejected({"render", map, "-o", scratch / "view.png"}, 1, "corrupt", scratch);
    expectRejected({"export", map, "-o", scratch / "cells.ply"}, 1, "corrupt", scratch);
  }
}

TEST(cliQueryBadInput, RenderUsage) {
  Scratch scratch;
  const std::string png = scratch / "view.png";
  expectRejected({"render", kGeb079}, 2, "-o", scratch);
  expectRejected({"render", "-o", png}, 2, "no map file", scratch);
  expectRejected({"render", scratch / "missing.ot", "-o", png}, 2, "does not exist", scratch);
  expectRejected({"render", kGeb079, "-o", scratch / "view.jpg"}, 2, "'.jpg'", scratch);
  expectRejected({"render", kGeb079, "-o", scratch / "no_such_dir/view.png"}, 2, "does not exist",
                 scratch);
  fs::create_directory(scratch.dir() / "taken.png");
  expectRejected({"render", kGeb079, "-o", scratch / "taken.png"}, 2, "directory", scratch);
  fs::remove(scratch.dir() / "taken.png");
  expectRejected({"render", kGeb079, "-o", png, "--size", "0x0"}, 2, "1 to 8192", scratch);
  expectRejected({"render", kGeb079, "-o", png, "--size", "100000x100000"}, 2, "1 to 8192",
                 scratch);
  expectRejected({"render", kGeb079, "-o", png, "--size", "800"}, 2, "WIDTHxHEIGHT", scratch);
  expectRejected({"render", kGeb079, "-o", png, "--size", "-8x6"}, 2, "WIDTHxHEIGHT", scratch);
  expectRejected({"render", kGeb079, "-o", png, "--size", "8x6x2"}, 2, "WIDTHxHEIGHT", scratch);
  expectRejected({"render", kGeb079, "-o", png, "--eye", "1", "2"}, 2, "3 values", scratch);
  expectRejected({"render", kGeb079, "-o", png, "--eye", "1", "2", "z"}, 2, "'z'", scratch);
  expectRejected({"render", kGeb079, "-o", png, "--look-at=1,2"}, 2, "3 values", scratch);
  expectRejected({"render", kGeb079, "-o", png, "--fov", "0"}, 2, "--fov", scratch);
  expectRejected({"render", kGeb079, "-o", png, "--fov", "nan"}, 2, "--fov", scratch);
  expectRejected({"render", kGeb079, "-o", png, "--eye", "1", "1", "1", "--look-at", "1", "1", "1"},
                 2, "same point", scratch);
  expectRejected({"render", kGeb079, "-o", png, "--bogus"}, 2, "--bogus", scratch);
}

TEST(cliQueryBadInput, RenderCameraOutsideTheMap) {
  OCTOVK_REQUIRE_CONTEXT(ctx);
  (void)ctx;
  Scratch scratch;
  expectRejected({"render", kGeb079, "-o", scratch / "view.png", "--eye", "1e5", "0", "0"}, 2,
                 "domain", scratch);
}

TEST(cliQueryBadInput, RenderOfAMapWithoutOccupiedCells) {
  OCTOVK_REQUIRE_CONTEXT(ctx);
  (void)ctx;
  REQUIRE_SMALL_MAPS();
  Scratch scratch;
  expectRejected({"render", maps.free_only_bt, "-o", scratch / "view.png"}, 1, "no occupied",
                 scratch);
}

TEST(cliQueryBadInput, ExportUsage) {
  Scratch scratch;
  const std::string ply = scratch / "cells.ply";
  expectRejected({"export", kGeb079}, 2, "-o", scratch);
  expectRejected({"export", scratch / "missing.bt", "-o", ply}, 2, "does not exist", scratch);
  expectRejected({"export", kGeb079, "-o", scratch / "cells.txt"}, 2, "'.txt'", scratch);
  expectRejected({"export", kGeb079, "-o", scratch / "no_such_dir/cells.ply"}, 2, "does not exist",
                 scratch);
  expectRejected({"export", kGeb079, "-o", ply, "--box", "1", "2", "3"}, 2, "6 values", scratch);
  expectRejected({"export", kGeb079, "-o", ply, "--box", "0", "0", "0", "1", "x", "1"}, 2, "'x'",
                 scratch);
  expectRejected({"export", kGeb079, "-o", ply, "--box", "0", "0", "2", "1", "1", "1"}, 2,
                 "minimum z", scratch);
  expectRejected({"export", kGeb079, "-o", ply, "--color", "pink"}, 2, "'pink'", scratch);
  expectRejected({"export", kGeb079, "-o", ply, "--occupied-only=yes"}, 2, "takes no value",
                 scratch);
  expectRejected({"export", kGeb079, "-o", ply, "--bogus"}, 2, "--bogus", scratch);
}

TEST(cliQueryBadInput, FailedRunKeepsTheOldFile) {
  OCTOVK_REQUIRE_CONTEXT(ctx);
  (void)ctx;
  Scratch scratch;
  const BadMaps bad(scratch);
  const std::string png = scratch / "old.png";
  const std::string ply = scratch / "old.ply";
  std::ofstream(png) << "old picture";
  std::ofstream(ply) << "old cells";
  EXPECT_EQ(runOctovk({"render", bad.truncated, "-o", png}, scratch.dir()).exit_code, 1);
  EXPECT_EQ(runOctovk({"export", bad.truncated, "-o", ply}, scratch.dir()).exit_code, 1);
  EXPECT_EQ(readFile(png), "old picture");
  EXPECT_EQ(readFile(ply), "old cells");
  for (const auto& entry : fs::directory_iterator(scratch.dir()))
    EXPECT_EQ(entry.path().string().find(".tmp"), std::string::npos) << entry.path();
}

// ---- help ----

TEST(cliQueryHelp, EachCommandHasHelp) {
  Scratch scratch;
  const std::vector<std::pair<std::string, std::vector<std::string>>> commands = {
      {"info", {"nodes", "leaves", "occupied", "free", "bounds", "device memory", ".bt", ".ot"}},
      {"render",
       {"-o", "--output", "--eye", "--look-at", "--size", "--fov", "--z-max", "800x600",
        "(default: 60)", "8192", ".png", "castRay"}},
      {"export",
       {"-o", "--output", "--occupied-only", "--box", "--color", "height", "occupancy", "log_odds",
        "size", ".ply", "leaf_bbx_iterator"}}};
  for (const auto& [command, words] : commands) {
    for (const std::vector<std::string>& args :
         {std::vector<std::string>{command, "--help"}, std::vector<std::string>{command, "-h"},
          std::vector<std::string>{"help", command}}) {
      const RunResult r = runOctovk(args, scratch.dir());
      EXPECT_EQ(r.exit_code, 0) << command;
      EXPECT_EQ(r.err, "");
      for (const std::string& word : words)
        EXPECT_NE(r.out.find(word), std::string::npos) << command << " help lacks '" << word << "'";
      EXPECT_NE(r.out.find("Exit codes"), std::string::npos) << command;
    }
  }
}

TEST(cliQueryHelp, TopLevelHelpListsTheCommands) {
  Scratch scratch;
  const RunResult r = runOctovk({"--help"}, scratch.dir());
  EXPECT_EQ(r.exit_code, 0);
  for (const char* word : {"\n  info ", "\n  render ", "\n  export ", "\n  integrate ",
                           "\n  devices ", "octovk info map.bt", "octovk render map.bt"})
    EXPECT_NE(r.out.find(word), std::string::npos) << "top-level help lacks '" << word << "'";
  const RunResult unknown = runOctovk({"frobnicate"}, scratch.dir());
  EXPECT_EQ(unknown.exit_code, 2);
  EXPECT_NE(unknown.err.find("info, render, export"), std::string::npos) << unknown.err;
}

}  // namespace
}  // namespace octovk::test
