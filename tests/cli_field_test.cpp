// cli_field_test: `octovk distance` (a slice of the distance field as a PNG; issue 21) and
// `octovk integrate --changes` (the keys changed over a run as a PLY; issue 19), run as a user
// runs them. The slice's pixels must show OctoMap's obstacles and the brute-force distances of the
// map read with OctoMap here, cell for cell; the PLY's vertices must be OctoMap's changed keys
// (KeyBoolMap) after graph2tree's inserts of the same scans, key for key and flag for flag.
#include <gtest/gtest.h>
#include <octomap/OcTree.h>
#include <octomap/ScanGraph.h>
#include <png.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <limits>
#include <map>
#include <memory>
#include <random>
#include <regex>
#include <sstream>
#include <string>
#include <vector>

#include "cli/png.hpp"
#include "cli_support.hpp"
#include "test_support.hpp"

namespace octovk::test {
namespace {

namespace fs = std::filesystem;
using octovk::cli::distanceColor;
using octovk::cli::Rgb;

const std::string kSphericalGraph = OCTOVK_PATH(OCTOVK_OCTOMAP_DATA_DIR) + "/spherical_scan.graph";

// ---- the picture ----

struct Picture {
  std::uint32_t width = 0, height = 0;
  std::vector<std::uint8_t> rgb;
  std::string error;
  Rgb at(std::uint32_t x, std::uint32_t y) const {
    const std::size_t i = (std::size_t{y} * width + x) * 3;
    return {rgb[i], rgb[i + 1], rgb[i + 2]};
  }
};

Picture readPng(const std::string& path) {
  Picture p;
  const std::string bytes = readFile(path);
  png_image image{};
  image.version = PNG_IMAGE_VERSION;
  if (!png_image_begin_read_from_memory(&image, bytes.data(), bytes.size())) {
    p.error = std::string("libpng: ") + image.message;
    return p;
  }
  image.format = PNG_FORMAT_RGB;
  p.rgb.resize(PNG_IMAGE_SIZE(image));
  if (!png_image_finish_read(&image, nullptr, p.rgb.data(), 0, nullptr)) {
    p.error = std::string("libpng: ") + image.message;
    return p;
  }
  p.width = image.width;
  p.height = image.height;
  return p;
}

std::string show(const Rgb& c) {
  return "(" + std::to_string(c[0]) + ", " + std::to_string(c[1]) + ", " + std::to_string(c[2]) +
         ")";
}

// A room made with OctoMap at 0.1 m and written as .bt: walls 4 x 3 m and 1.2 m high, a pillar,
// free space inside but for an unknown pocket, unknown outside.
std::string writeRoomMap(const Scratch& scratch) {
  octomap::OcTree tree(0.1);
  for (int k = 0; k < 12; ++k)
    for (int j = -15; j < 15; ++j)
      for (int i = -20; i < 20; ++i) {
        const octomap::point3d p(0.1f * (float(i) + 0.5f), 0.1f * (float(j) + 0.5f),
                                 0.1f * (float(k) + 0.5f));
        const bool wall = i == -20 || i == 19 || j == -15 || j == 14;
        const bool pillar = i >= 4 && i <= 6 && j >= -4 && j <= -2;
        const bool pocket = i < -10 && j > 6;
        if (wall || pillar)
          tree.updateNode(p, true);
        else if (!pocket)
          tree.updateNode(p, false);
      }
  const std::string path = scratch / "room.bt";
  octovk::test::QuietCout quiet;
  EXPECT_TRUE(tree.writeBinary(path));
  return path;
}

std::unique_ptr<octomap::OcTree> readTree(const std::string& path) {
  auto tree = std::make_unique<octomap::OcTree>(0.1);
  octovk::test::QuietCout quiet;
  if (!tree->readBinary(path)) return nullptr;
  return tree;
}

// What the slice must show, from OctoMap's tree: the box's cells (DynamicEDTOctomap's box), its
// obstacles, and for each cell of the slice layer the brute-force squared distance and whether it
// is occupied.
struct ExpectedSlice {
  std::array<int, 3> min_key{}, size{};
  int layer = 0;
  std::vector<std::uint32_t> squared;  // per slice cell (x + size_x * y); max where no obstacle
  std::vector<char> occupied, unknown;
  std::size_t obstacles = 0;
};

ExpectedSlice expectedSlice(const octomap::OcTree& tree, const std::array<double, 6>& box, double z,
                            bool unknown_occupied) {
  ExpectedSlice e;
  const octomap::OcTreeKey lo =
      tree.coordToKey(octomap::point3d(float(box[0]), float(box[1]), float(box[2])));
  const octomap::OcTreeKey hi =
      tree.coordToKey(octomap::point3d(float(box[3]), float(box[4]), float(box[5])));
  for (int a = 0; a < 3; ++a) {
    e.min_key[a] = lo[a];
    e.size[a] = hi[a] - lo[a] + 1;
  }
  e.layer = int(tree.coordToKey(float(z))) - e.min_key[2];
  std::vector<std::array<int, 3>> sites;
  const std::size_t slice = std::size_t(e.size[0]) * e.size[1];
  e.occupied.assign(slice, 0);
  e.unknown.assign(slice, 0);
  for (int kz = 0; kz < e.size[2]; ++kz)
    for (int ky = 0; ky < e.size[1]; ++ky)
      for (int kx = 0; kx < e.size[0]; ++kx) {
        const octomap::OcTreeKey k(static_cast<octomap::key_type>(e.min_key[0] + kx),
                                   static_cast<octomap::key_type>(e.min_key[1] + ky),
                                   static_cast<octomap::key_type>(e.min_key[2] + kz));
        const octomap::OcTreeNode* node = tree.search(k);
        const bool occupied = node != nullptr && tree.isNodeOccupied(node);
        if (kz == e.layer) {
          e.occupied[std::size_t(kx) + std::size_t(e.size[0]) * ky] = occupied;
          e.unknown[std::size_t(kx) + std::size_t(e.size[0]) * ky] = node == nullptr;
        }
        if (occupied || (node == nullptr && unknown_occupied)) sites.push_back({kx, ky, kz});
      }
  e.obstacles = sites.size();
  e.squared.assign(slice, std::numeric_limits<std::uint32_t>::max());
  for (int ky = 0; ky < e.size[1]; ++ky)
    for (int kx = 0; kx < e.size[0]; ++kx) {
      std::uint32_t best = std::numeric_limits<std::uint32_t>::max();
      for (const auto& s : sites) {
        const int dx = s[0] - kx, dy = s[1] - ky, dz = s[2] - e.layer;
        best = std::min(best, std::uint32_t(dx * dx + dy * dy + dz * dz));
      }
      e.squared[std::size_t(kx) + std::size_t(e.size[0]) * ky] = best;
    }
  return e;
}

// Light grey: what the slice shows for unknown cells that are not obstacles.
const Rgb kUnknownGrey{178, 178, 178};

// Where the picture's parts lie, from the summary's "picture:" line.
struct Layout {
  bool found = false;
  std::uint32_t width = 0, height = 0, scale = 0;
  std::uint32_t slice_x0 = 0, slice_y0 = 0, slice_x1 = 0, slice_y1 = 0;
  std::uint32_t bar_x0 = 0, bar_y = 0, bar_x1 = 0, bar_y1 = 0;
};

Layout layoutOf(const std::string& out) {
  Layout at;
  const std::size_t line = out.find("picture:");
  if (line == std::string::npos) return at;
  at.found = std::sscanf(out.c_str() + line,
                         "picture: %u x %u pixels, %u per cell; the slice at (%u, %u) to (%u, "
                         "%u), axes in metres; the colour bar from (%u, %u) to (%u, %u)",
                         &at.width, &at.height, &at.scale, &at.slice_x0, &at.slice_y0, &at.slice_x1,
                         &at.slice_y1, &at.bar_x0, &at.bar_y, &at.bar_x1, &at.bar_y1) == 11;
  return at;
}

// Pixels brighter than 150 on every channel in the rectangle [x0, x1] x [y0, y1] (text).
std::size_t lightPixels(const Picture& p, std::uint32_t x0, std::uint32_t y0, std::uint32_t x1,
                        std::uint32_t y1) {
  std::size_t n = 0;
  for (std::uint32_t y = y0; y <= y1 && y < p.height; ++y)
    for (std::uint32_t x = x0; x <= x1 && x < p.width; ++x) {
      const Rgb c = p.at(x, y);
      n += c[0] > 150 && c[1] > 150 && c[2] > 150;
    }
  return n;
}

std::string formatG(double v) {
  char text[32];
  std::snprintf(text, sizeof(text), "%g", v);
  return text;
}

// Runs `octovk distance` on `map` and checks every cell of the slice (the centre pixel of its
// square) and the picture's size.
void expectSlice(const std::string& map, const std::array<double, 6>& box, double z,
                 double max_distance, bool unknown_occupied, const Scratch& scratch) {
  const std::string png = scratch / "slice.png";
  constexpr std::uint32_t kCell = 3;
  std::vector<std::string> args = {"distance", map, "--box"};
  for (double v : box) args.push_back(std::to_string(v));
  args.insert(args.end(), {"--z", std::to_string(z), "--max-distance", std::to_string(max_distance),
                           "--cell-pixels", std::to_string(kCell), "-o", png});
  args.insert(args.end(), {"--unknown", unknown_occupied ? "occupied" : "free"});
  const RunResult r = runOctovk(args, scratch.dir());
  ASSERT_EQ(r.exit_code, 0) << r.err;
  EXPECT_NE(r.out.find("wrote:     " + png), std::string::npos) << r.out;
  EXPECT_NE(r.out.find("colours:"), std::string::npos) << r.out;

  const std::unique_ptr<octomap::OcTree> tree = readTree(map);
  ASSERT_TRUE(tree);
  const ExpectedSlice e = expectedSlice(*tree, box, z, unknown_occupied);
  const Picture p = readPng(png);
  ASSERT_TRUE(p.error.empty()) << p.error;
  // Where the program says the slice and the colour bar lie: the slice's cells, kCell pixels
  // each, with room around them for the axes and the bar.
  const Layout at = layoutOf(r.out);
  ASSERT_TRUE(at.found) << r.out;
  ASSERT_EQ(p.width, at.width);
  ASSERT_EQ(p.height, at.height);
  ASSERT_EQ(at.slice_x1 - at.slice_x0 + 1, std::uint32_t(e.size[0]) * kCell) << r.out;
  ASSERT_EQ(at.slice_y1 - at.slice_y0 + 1, std::uint32_t(e.size[1]) * kCell) << r.out;
  ASSERT_GE(at.slice_x0, 40u) << "no room for the y axis's numbers: " << r.out;
  ASSERT_GE(at.bar_y, at.slice_y1 + 30) << "no room for the x axis's numbers: " << r.out;
  const double resolution = tree->getResolution();
  std::size_t occupied = 0, unknown_obstacles = 0, unknown = 0, free_cells = 0, capped = 0;
  std::vector<float> distances;
  for (int ky = 0; ky < e.size[1]; ++ky)
    for (int kx = 0; kx < e.size[0]; ++kx) {
      const std::size_t i = std::size_t(kx) + std::size_t(e.size[0]) * ky;
      Rgb want;
      if (e.squared[i] == 0) {
        want = e.occupied[i] ? Rgb{0, 0, 0} : Rgb{96, 96, 96};
        ++(e.occupied[i] ? occupied : unknown_obstacles);
      } else if (e.unknown[i]) {
        // Space the map never saw has no distance colour: it may hold anything.
        want = kUnknownGrey;
        ++unknown;
      } else {
        float d = static_cast<float>(max_distance);
        if (e.squared[i] != std::numeric_limits<std::uint32_t>::max())
          d = std::min(static_cast<float>(std::sqrt(double(e.squared[i])) * resolution), d);
        want = distanceColor(double(d) / max_distance);
        ++free_cells;
        capped += d >= static_cast<float>(max_distance);
        distances.push_back(d);
      }
      // y up: the top row of the picture is the box's last row of cells.
      const std::uint32_t px = at.slice_x0 + std::uint32_t(kx) * kCell + kCell / 2;
      const std::uint32_t py = at.slice_y0 + std::uint32_t(e.size[1] - 1 - ky) * kCell + kCell / 2;
      ASSERT_EQ(show(p.at(px, py)), show(want))
          << "cell (" << kx << ", " << ky << ") of the slice, squared distance " << e.squared[i]
          << (e.occupied[i] ? ", occupied" : "") << (e.unknown[i] ? ", unknown" : "");
    }
  // The slice holds obstacles and cells at several distances, some capped.
  EXPECT_GT(occupied, 5u);
  EXPECT_GT(free_cells, 50u);
  if (!unknown_occupied) {
    EXPECT_GT(capped, 0u);
  }
  std::sort(distances.begin(), distances.end());
  distances.erase(std::unique(distances.begin(), distances.end()), distances.end());
  EXPECT_GT(distances.size(), 5u);
  // The room's unknown pocket and the space around it: obstacles with --unknown-occupied, else
  // light grey, and never a distance colour.
  if (unknown_occupied) {
    EXPECT_GT(unknown_obstacles, 0u);
    EXPECT_EQ(unknown, 0u);
  } else {
    EXPECT_EQ(unknown_obstacles, 0u);
    EXPECT_GT(unknown, 0u);
    EXPECT_NE(r.out.find(std::to_string(unknown) + " unknown (grey"), std::string::npos) << r.out;
  }
  for (std::uint32_t t = 0; t <= 20; ++t)
    EXPECT_NE(show(distanceColor(t / 20.0)), show(kUnknownGrey)) << "unknown looks like a distance";
  // The colour bar: 0 m at its left end, the maximum at its right.
  EXPECT_EQ(show(p.at(at.bar_x0, at.bar_y + 7)), show(distanceColor(0.0)));
  EXPECT_EQ(show(p.at(at.bar_x1, at.bar_y + 7)), show(distanceColor(1.0)));
  // The numbers: text (light pixels on the dark background) left of the slice (the y axis),
  // below it (the x axis) and below the bar (its distances).
  EXPECT_GT(lightPixels(p, 0, at.slice_y0, at.slice_x0 - 8, at.slice_y1), 20u);
  EXPECT_GT(lightPixels(p, at.slice_x0, at.slice_y1 + 8, at.slice_x1, at.slice_y1 + 22), 20u);
  EXPECT_GT(lightPixels(p, at.bar_x0, at.bar_y + 21, at.bar_x1, at.bar_y + 35), 20u);
  // The units the picture and the summary give.
  EXPECT_NE(r.out.find("axes in metres"), std::string::npos) << r.out;
  EXPECT_NE(r.out.find(std::string("the bar below runs 0 to ") + formatG(max_distance) + " m"),
            std::string::npos)
      << r.out;
}

// The room and some unknown space around it; the slice at 0.55 m.
const std::array<double, 6> kRoomBox{-2.5, -2.0, -0.2, 2.5, 2.0, 1.4};

TEST(cliDistance, SliceShowsOctoMapsObstaclesAndExactDistances) {
  OCTOVK_REQUIRE_CONTEXT(ctx);
  (void)ctx;  // the program makes its own; this requires the device as the other tests do
  Scratch scratch("clifield");
  expectSlice(writeRoomMap(scratch), kRoomBox, 0.55, 0.8, false, scratch);
}

TEST(cliDistance, UnknownOccupiedMarksUnknownCellsAndCountsThem) {
  OCTOVK_REQUIRE_CONTEXT(ctx);
  (void)ctx;
  Scratch scratch("clifield");
  expectSlice(writeRoomMap(scratch), kRoomBox, 0.55, 0.8, true, scratch);
}

void expectRefused(const std::vector<std::string>& args, int exit_code, const std::string& mention,
                   const Scratch& scratch) {
  const RunResult r = runOctovk(args, scratch.dir());
  EXPECT_EQ(r.exit_code, exit_code) << r.out << r.err;
  EXPECT_EQ(r.err.rfind("octovk: error: ", 0), 0u) << r.err;
  EXPECT_EQ(std::count(r.err.begin(), r.err.end(), '\n'), 1) << r.err;
  EXPECT_NE(r.err.find(mention), std::string::npos) << "'" << mention << "' not in: " << r.err;
  EXPECT_FALSE(fs::exists(scratch / "slice.png"));
  EXPECT_TRUE(octovk::test::temporariesIn(scratch.dir()).empty());
}

// As expectRefused, with several mentions, and never a Vulkan call, a source path or the
// library's names for what the program calls an option.
void expectRefusedText(const std::vector<std::string>& args, int exit_code,
                       const std::vector<std::string>& mentions, const Scratch& scratch) {
  for (const std::string& m : mentions) expectRefused(args, exit_code, m, scratch);
  const RunResult r = runOctovk(args, scratch.dir());
  EXPECT_FALSE(std::regex_search(r.err, std::regex("vk[A-Z]"))) << r.err;
  EXPECT_EQ(r.err.find("src/"), std::string::npos) << r.err;
  EXPECT_EQ(r.err.find("MapParams"), std::string::npos) << r.err;
  EXPECT_EQ(r.err.find("DistanceField"), std::string::npos) << r.err;
  EXPECT_EQ(r.err.find("split the scan"), std::string::npos) << r.err;
}

TEST(cliDistance, BadInputIsOneErrorLineAndNoPicture) {
  OCTOVK_REQUIRE_CONTEXT(ctx);
  (void)ctx;  // the program makes its own; this requires the device as the other tests do
  Scratch scratch("clifield");
  const std::string out = scratch / "slice.png";
  const std::string m = writeRoomMap(scratch);
  using V = std::vector<std::string>;
  expectRefused({"distance", m, "-o", out}, 2, "--box", scratch);
  expectRefused({"distance", m, "--box", "1", "0", "0", "0", "1", "1", "-o", out}, 2,
                "minimum x (1) is above the maximum", scratch);
  expectRefused({"distance", m, "--box", "0", "0", "nan", "1", "1", "1", "-o", out}, 2, "--box",
                scratch);
  expectRefused(
      {"distance", m, "--box", "0", "0", "0", "1", "1", "1", "--max-distance", "0", "-o", out}, 2,
      "--max-distance 0", scratch);
  expectRefused(
      {"distance", m, "--box", "0", "0", "0", "1", "1", "1", "--max-distance", "-1", "-o", out}, 2,
      "above 0", scratch);
  expectRefused(
      {"distance", m, "--box", "0", "0", "0", "1", "1", "1", "--max-distance", "nan", "-o", out}, 2,
      "--max-distance", scratch);
  expectRefused({"distance", m, "--box", "0", "0", "0", "1", "1", "1", "--z", "1.5", "-o", out}, 2,
                "outside the box", scratch);
  expectRefused(
      {"distance", m, "--box", "0", "0", "0", "1", "1", "1", "--cell-pixels", "0", "-o", out}, 2,
      "--cell-pixels", scratch);
  expectRefused({"distance", m, "--box", "0", "0", "0", "1", "1", "1", "-o", scratch / "slice.ppm"},
                2, ".png", scratch);
  expectRefused(
      {"distance", m, "--box", "-30", "-2", "0", "30", "2", "1", "--cell-pixels", "64", "-o", out},
      2, "at most 8192", scratch);
  // The library's refusals: a box beyond the map's key range (the user's to fix: exit 2), and a
  // field over the device-memory cap (exit 1, naming the bytes and the option).
  expectRefused(V{"distance", m, "--box", "0", "0", "0", "1", "1", "1e5", "-o", out}, 2,
                "key range", scratch);
  expectRefused(V{"distance", m, "--box", "-20", "-20", "-5", "20", "20", "5",
                  "--max-device-memory", "4M", "-o", out},
                1, "bytes", scratch);
  const RunResult capped = runOctovk(V{"distance", m, "--box", "-20", "-20", "-5", "20", "20", "5",
                                       "--max-device-memory", "4M", "-o", out},
                                     scratch.dir());
  EXPECT_NE(capped.err.find("--max-device-memory"), std::string::npos) << capped.err;
  EXPECT_NE(capped.err.find("401 x 401 x 101 cells"), std::string::npos) << capped.err;
}

// Issue 30.5: without --unknown, the cells the map does not know are obstacles (the safe rule);
// --unknown free asks for the other, and the old flag --unknown-occupied still means the default.
TEST(cliDistance, UnknownSpaceIsAnObstacleUnlessToldOtherwise) {
  OCTOVK_REQUIRE_CONTEXT(ctx);
  (void)ctx;
  Scratch scratch("clifield");
  const std::string m = writeRoomMap(scratch);
  const auto run = [&](std::vector<std::string> extra) {
    std::vector<std::string> args = {
        "distance", m,     "--box", "-2.5", "-2", "-0.2",           "2.5",
        "2",        "1.4", "--z",   "0.55", "-o", scratch / "s.png"};
    args.insert(args.end(), extra.begin(), extra.end());
    const RunResult r = runOctovk(args, scratch.dir());
    EXPECT_EQ(r.exit_code, 0) << r.err;
    return r.out;
  };
  // The counts of the slice's cells (the line without the timings).
  const auto cells = [](const std::string& out) {
    const std::size_t at = out.find("cells:");
    return at == std::string::npos ? std::string() : out.substr(at, out.find('\n', at) - at);
  };
  const std::string safe = cells(run({}));
  EXPECT_NE(safe.find("unknown counted as obstacles"), std::string::npos) << safe;
  EXPECT_EQ(safe.find(" 0 unknown"), std::string::npos) << safe;
  EXPECT_EQ(cells(run({"--unknown", "occupied"})), safe);
  EXPECT_EQ(cells(run({"--unknown-occupied"})), safe);
  const std::string free = cells(run({"--unknown", "free"}));
  EXPECT_FALSE(free.empty());
  EXPECT_EQ(free.find("unknown counted as obstacles"), std::string::npos) << free;
  expectRefusedText({"distance", m, "--box", "0", "0", "0", "1", "1", "1", "--unknown", "maybe",
                     "-o", scratch / "slice.png"},
                    2, {"--unknown maybe", "occupied", "free"}, scratch);
}

// Issue 30.4: a field the device or the cap cannot hold is one line in the user's words (no
// Vulkan call, no source path), naming the box, the bytes and both options, cap or no cap.
TEST(cliDistance, OutOfMemorySaysWhatToChange) {
  OCTOVK_REQUIRE_CONTEXT(ctx);  // the program's device: the box must exceed its memory
  Scratch scratch("clifield");
  const std::string m = writeRoomMap(scratch);
  // A box beyond the device (200 m square on lavapipe's 2 GiB); on a device that holds the
  // largest field a box may have, the 200 m box still exceeds the cap below.
  const int beyond = octovk::test::fieldHalfSideBeyondDevice(ctx);
  const int h = beyond > 0 ? beyond : 100;
  const std::string lo = std::to_string(-h), hi = std::to_string(h);
  const std::vector<std::string> huge = {
      "distance", m, "--box", lo, lo, "-10", hi, hi, "10", "-o", scratch / "slice.png"};
  const std::string cells = octovk::test::fieldBoxCells(h);
  if (beyond > 0)
    expectRefusedText(huge, 1, {cells, "GiB", "Shrink --box", "--max-device-memory"}, scratch);
  std::vector<std::string> capped = huge;
  capped.insert(capped.end(), {"--max-device-memory", "100M"});
  expectRefusedText(capped, 1, {cells, "Shrink --box", "raise --max-device-memory"}, scratch);
}

TEST(cliDistance, HelpSaysWhatThePictureShows) {
  Scratch scratch("clifield");
  const RunResult r = runOctovk({"distance", "--help"}, scratch.dir());
  ASSERT_EQ(r.exit_code, 0) << r.err;
  for (const char* words : {"--box XMIN YMIN ZMIN XMAX YMAX ZMAX", "--z HEIGHT", "--max-distance M",
                            "--unknown occupied|free", "--cell-pixels N", "--max-device-memory",
                            "DynamicEDTOctomap", "black", "light grey", "dark grey", "red", "blue",
                            "the bar below", "in metres", "y up", "Exit codes"})
    EXPECT_NE(r.out.find(words), std::string::npos) << words;
  const RunResult top = runOctovk({"--help"}, scratch.dir());
  EXPECT_NE(top.out.find("\n  distance   "), std::string::npos) << top.out;
}

// ---- integrate --changes ----

// A scan graph whose scans revisit cells: occupied ones that later rays pass through (the longer
// scans) and free ones that later scans hit (the short scans again), so that occupancies flip.
std::string writeRevisitingGraph(const Scratch& scratch) {
  octomap::ScanGraph graph;
  std::mt19937 rng(5);
  std::normal_distribution<float> n(0.0f, 1.0f);
  const auto add = [&](float radius, octomath::Vector3 position, float yaw) {
    auto* cloud = new octomap::Pointcloud();  // the graph owns it
    for (int i = 0; i < 600; ++i) {
      octomath::Vector3 d(n(rng), n(rng), 0.3f * n(rng));
      d.normalize();
      cloud->push_back(d * radius);
    }
    graph.addNode(cloud, octomath::Pose6D(position, octomath::Quaternion(0.0, 0.0, yaw)));
  };
  add(2.0f, {0.0f, 0.0f, 0.0f}, 0.0f);
  for (int i = 0; i < 3; ++i) add(3.0f, {0.05f * float(i), 0.0f, 0.0f}, 0.3f * float(i));
  for (int i = 0; i < 3; ++i) add(2.0f, {0.0f, 0.05f * float(i), 0.0f}, 0.2f * float(i));
  const std::string path = scratch / "revisiting.graph";
  octovk::test::QuietCout quiet;
  EXPECT_TRUE(graph.writeBinary(path));
  return path;
}

// OctoMap's changed keys after graph2tree's inserts of every scan, change detection on from the
// first: (x, y, z centre bits, flag) sorted.
using Change = std::array<std::uint32_t, 4>;

std::vector<Change> oracleChanges(const std::string& graph_path, double resolution,
                                  double max_range) {
  octomap::ScanGraph graph;
  {
    octovk::test::QuietCout quiet;
    EXPECT_TRUE(graph.readBinary(graph_path));
  }
  octomap::OcTree tree(resolution);
  tree.enableChangeDetection(true);
  for (octomap::ScanNode* node : graph) {
    const octomath::Pose6D frame = node->pose;
    const octomap::point3d sensor_origin = frame.inv().transform(frame.trans());
    tree.insertPointCloud(*node->scan, sensor_origin, frame, max_range);
  }
  std::vector<Change> out;
  for (auto it = tree.changedKeysBegin(); it != tree.changedKeysEnd(); ++it) {
    const octomap::point3d c = tree.keyToCoord(it->first);
    out.push_back({octovk::test::floatBits(c.x()), octovk::test::floatBits(c.y()),
                   octovk::test::floatBits(c.z()), it->second ? 1u : 0u});
  }
  std::sort(out.begin(), out.end());
  return out;
}

struct ChangesPly {
  std::vector<Change> vertices;
  std::vector<std::array<float, 3>> centres;  // in the file's order
  long long declared = -1;
  std::string error;
};

ChangesPly readChangesPly(const std::string& path) {
  ChangesPly ply;
  std::ifstream in(path);
  std::string line;
  std::vector<std::string> properties;
  std::getline(in, line);
  if (line != "ply") ply.error = "not a PLY file";
  while (std::getline(in, line) && line != "end_header") {
    if (line.rfind("element vertex ", 0) == 0) ply.declared = std::stoll(line.substr(15));
    if (line.rfind("property ", 0) == 0) properties.push_back(line);
  }
  const std::vector<std::string> want = {
      "property float x",   "property float y",     "property float z",   "property uchar created",
      "property uchar red", "property uchar green", "property uchar blue"};
  if (properties != want) ply.error = "unexpected vertex properties";
  while (ply.error.empty() && std::getline(in, line)) {
    std::istringstream fields(line);
    float x, y, z;
    unsigned created, r, g, b;
    if (!(fields >> x >> y >> z >> created >> r >> g >> b) || created > 1 || r > 255 || g > 255 ||
        b > 255) {
      ply.error = "bad vertex line '" + line + "'";
      break;
    }
    ply.vertices.push_back({octovk::test::floatBits(x), octovk::test::floatBits(y),
                            octovk::test::floatBits(z), created});
    ply.centres.push_back({x, y, z});
  }
  return ply;
}

void expectChanges(const std::string& graph, const std::string& resolution, double max_range,
                   const Scratch& scratch) {
  const std::string bt = scratch / "map.bt", ply = scratch / "changes.ply";
  std::vector<std::string> args = {"integrate", graph,       "-r", resolution, "-o",
                                   bt,          "--changes", ply,  "-q"};
  if (max_range > 0) args.insert(args.end(), {"-m", std::to_string(max_range)});
  const RunResult r = runOctovk(args, scratch.dir());
  ASSERT_EQ(r.exit_code, 0) << r.err;
  EXPECT_NE(r.out.find("wrote:         " + ply), std::string::npos) << r.out;
  const ChangesPly got = readChangesPly(ply);
  ASSERT_TRUE(got.error.empty()) << got.error;
  EXPECT_EQ(got.declared, static_cast<long long>(got.vertices.size()));
  // Sorted by key (x, then y, then z), which orders the centres the same way.
  EXPECT_TRUE(std::is_sorted(got.centres.begin(), got.centres.end()));
  std::vector<Change> mine = got.vertices;
  std::sort(mine.begin(), mine.end());
  const std::vector<Change> want = oracleChanges(graph, std::stod(resolution), max_range);
  ASSERT_EQ(mine.size(), want.size());
  EXPECT_TRUE(mine == want) << "the PLY's changed keys differ from OctoMap's";
  const auto flipped = static_cast<std::size_t>(
      std::count_if(want.begin(), want.end(), [](const Change& c) { return c[3] == 0; }));
  EXPECT_GT(want.size(), 100u);
  // From an empty map with detection on from the first scan, every changed leaf was created in
  // the run and OctoMap keeps its `true` when its occupancy flips later (only a key first seen
  // by a flip is entered `false`), so no key is flagged 0 here.
  EXPECT_EQ(flipped, 0u);
  EXPECT_NE(r.out.find("changes:       " + std::to_string(want.size()) + " keys (" +
                       std::to_string(want.size() - flipped) + " created, " +
                       std::to_string(flipped) + " flipped)"),
            std::string::npos)
      << r.out;
}

TEST(cliChanges, PlyIsOctoMapsChangedKeysOverTheRun) {
  OCTOVK_REQUIRE_CONTEXT(ctx);
  (void)ctx;  // the program makes its own; this requires the device as the other tests do
  Scratch scratch("clifield");
  const std::string graph = writeRevisitingGraph(scratch);
  expectChanges(graph, "0.1", -1.0, scratch);
}

TEST(cliChanges, WithAMaxRangeAndOnTheSphericalScan) {
  OCTOVK_REQUIRE_CONTEXT(ctx);
  (void)ctx;  // the program makes its own; this requires the device as the other tests do
  Scratch scratch("clifield");
  expectChanges(writeRevisitingGraph(scratch), "0.05", 2.5, scratch);
  expectChanges(kSphericalGraph, "0.2", -1.0, scratch);
}

TEST(cliChanges, BadChangesOutputIsRefusedBeforeAnyWork) {
  Scratch scratch("clifield");
  const std::string bt = scratch / "map.bt";
  RunResult r =
      runOctovk({"integrate", kSphericalGraph, "-o", bt, "--changes", scratch / "changes.txt"},
                scratch.dir());
  EXPECT_EQ(r.exit_code, 2) << r.err;
  EXPECT_NE(r.err.find(".ply"), std::string::npos) << r.err;
  r = runOctovk({"integrate", kSphericalGraph, "-o", bt, "--changes"}, scratch.dir());
  EXPECT_EQ(r.exit_code, 2) << r.err;
  EXPECT_NE(r.err.find("--changes"), std::string::npos) << r.err;
  r = runOctovk(
      {"integrate", kSphericalGraph, "-o", bt, "--changes", scratch / "no-such-dir/changes.ply"},
      scratch.dir());
  EXPECT_EQ(r.exit_code, 2) << r.err;
  EXPECT_FALSE(fs::exists(bt));
  EXPECT_TRUE(octovk::test::temporariesIn(scratch.dir()).empty());
  r = runOctovk({"integrate", "--help"}, scratch.dir());
  EXPECT_NE(r.out.find("--changes FILE.ply"), std::string::npos);
  EXPECT_NE(r.out.find("uchar created"), std::string::npos);
}

}  // namespace
}  // namespace octovk::test
