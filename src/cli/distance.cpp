// octovk distance: a horizontal slice of the exact distance field over a box of a map
// (octovk/distance.hpp), computed on the device and drawn as a PNG: each cell of the slice
// coloured by its distance to the nearest obstacle, obstacles marked, a colour bar below.
#include <Eigen/Core>
#include <algorithm>
#include <array>
#include <cerrno>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <iostream>
#include <optional>
#include <sstream>
#include <vector>

#include "command.hpp"
#include "octovk/octovk.hpp"
#include "png.hpp"

namespace octovk::cli {

namespace {

constexpr const char* kDistanceUsage =
    "octovk distance MAP.bt|MAP.ot --box XMIN YMIN ZMIN XMAX YMAX ZMAX [--z HEIGHT] "
    "[--max-distance M] [--unknown occupied|free] [--cell-pixels N] -o SLICE.png "
    "[--max-device-memory BYTES]";

constexpr double kDefaultMaxDistanceM = 2.0;
constexpr std::uint32_t kMaxCellPixels = 64;
constexpr std::uint32_t kMaxSide = 8192;  // as render's
// The default picture's longer side, in pixels (as near as whole pixels per cell allow).
constexpr std::uint32_t kDefaultSide = 800;
constexpr std::uint32_t kDefaultMaxCellPixels = 16;
// Below the slice: a gap, the colour bar, and its tick marks.
constexpr std::uint32_t kBarGap = 4;
constexpr std::uint32_t kBarHeight = 14;
constexpr std::uint32_t kTickHeight = 6;
constexpr int kTicks = 4;  // marks at 0, 1/4, 1/2, 3/4 and all of the maximum distance

const Rgb kOccupiedBlack{0, 0, 0};
const Rgb kUnknownObstacleGrey{96, 96, 96};
const Rgb kBackground{24, 24, 24};
const Rgb kTickWhite{235, 235, 235};

void printDistanceHelp(std::ostream& out) {
  out << "octovk distance MAP.bt|MAP.ot --box XMIN YMIN ZMIN XMAX YMAX ZMAX [--z HEIGHT]\n"
         "                [--max-distance M] [--unknown occupied|free] [--cell-pixels N]\n"
         "                -o SLICE.png\n"
         "\n"
         "Computes the exact Euclidean distance field over a box of a map on the Vulkan device\n"
         "(the meaning of dynamicEDT3D's DynamicEDTOctomap: for every cell of the box at the\n"
         "finest resolution, the distance from its centre to the centre of the nearest occupied\n"
         "cell inside the box, capped at --max-distance) and draws one horizontal slice of it,\n"
         "the cells of the box at height --z, as an 8-bit RGB PNG: one square of N x N pixels\n"
         "per cell, x to the right, y up.\n"
         "\n"
         "Colours:\n"
         "  black                  an occupied cell (OctoMap's isNodeOccupied)\n"
         "  dark grey              an unknown cell counted as an obstacle (--unknown occupied)\n"
         "  red ... yellow ... green ... blue\n"
         "                         the distance to the nearest obstacle, from 0 (red) to\n"
         "                         --max-distance or farther (blue), on a reversed Turbo scale;\n"
         "                         a box without obstacles is all blue\n"
         "  the bar below the slice shows the scale from 0 (left) to --max-distance (right),\n"
         "  with white marks at 0, 1/4, 1/2, 3/4 and all of it (also printed on stdout)\n"
         "\n"
         "Options:\n"
         "  -o, --output FILE      the .png picture to write. Written to a temporary file beside\n"
         "                         it and renamed once complete. Required.\n"
         "      --box XMIN YMIN ZMIN XMAX YMAX ZMAX\n"
         "                         the field's box in metres (min <= max on every axis): the\n"
         "                         cells from the one holding the min corner to the one holding\n"
         "                         the max corner. Only obstacles inside it count. Required.\n"
         "      --z HEIGHT         height of the slice in metres, within the box; the slice is\n"
         "                         the layer of cells holding it (default: the box's middle)\n"
         "      --max-distance M   distances are capped at M metres, M > 0 (default: "
      << kDefaultMaxDistanceM
      << ")\n"
         "      --unknown occupied|free\n"
         "                         what cells the map does not know are (DynamicEDTOctomap's\n"
         "                         treatUnknownAsOccupied). occupied (default): obstacles, so no\n"
         "                         distance promises clearance through unseen space; free: only\n"
         "                         occupied cells are obstacles\n"
         "      --cell-pixels N    pixels per cell side, 1 to "
      << kMaxCellPixels
      << " (default: the most, up to\n"
         "                         "
      << kDefaultMaxCellPixels << ", that keep the longer side within " << kDefaultSide
      << " pixels)\n";
  printMaxDeviceMemoryHelp(out, "A map or a field");
  out << "                         The field takes 16 bytes per cell of the box.\n"
         "  -h, --help             show this help\n"
         "Options take their value as '--name VALUE' or '--name=VALUE'; --box also as\n"
         "'--box=XMIN,YMIN,ZMIN,XMAX,YMAX,ZMAX'.\n"
         "\n"
         "A field over --max-device-memory fails (exit 1) naming the bytes it needs; a box with\n"
         "more cells along a line than the device transforms in one dispatch, or beyond the\n"
         "map's key range, and a picture over "
      << kMaxSide << " pixels a side are usage errors (exit 2).\n"
         "\n"
         "Output: the device used, then on stdout the box in cells, the slice's height, its\n"
         "obstacles and distances, the colour scale, the time taken and the file written.\n";
}

class Distance final : public Command {
 public:
  bool option(const ParsedOption& opt) override {
    if (opt.name == "--box") {
      const std::vector<double> v = parseNumbers(opt, "-5 -5 0 5 5 2");
      for (int a = 0; a < 3; ++a)
        if (v[a] > v[a + 3])
          throw UsageError("--box: the minimum " + std::string(1, "xyz"[a]) + " (" + opt.values[a] +
                           ") is above the maximum (" + opt.values[a + 3] +
                           "); write --box XMIN YMIN ZMIN XMAX YMAX ZMAX");
      box_ = std::array<double, 6>{v[0], v[1], v[2], v[3], v[4], v[5]};
    } else if (opt.name == "--z") {
      z_ = parseNumber(opt, "0.5 (metres)");
    } else if (opt.name == "--max-distance") {
      max_distance_m_ = parseNumber(opt, "2 (metres)");
      if (!(max_distance_m_ > 0.0) || !std::isfinite(static_cast<float>(max_distance_m_)))
        throw UsageError("--max-distance " + opt.value +
                         ": give a distance in metres above 0, e.g. --max-distance 2");
    } else if (opt.name == "--unknown") {
      if (opt.value != "occupied" && opt.value != "free")
        throw UsageError("--unknown " + opt.value +
                         ": give --unknown occupied (unknown cells are obstacles, the default) "
                         "or --unknown free");
      unknown_occupied_ = opt.value == "occupied";
    } else if (opt.name == "--unknown-occupied") {  // the spelling before --unknown
      unknown_occupied_ = true;
    } else if (opt.name == "--cell-pixels") {
      const double n = parseNumber(opt, "4");
      if (n != std::floor(n) || n < 1 || n > kMaxCellPixels)
        throw UsageError("--cell-pixels " + opt.value + ": give a whole number from 1 to " +
                         std::to_string(kMaxCellPixels));
      cell_pixels_ = static_cast<std::uint32_t>(n);
    } else {
      return false;
    }
    return true;
  }

  void check(Invocation& in) override {
    checkMapInput(in.input(), kDistanceUsage);
    if (!box_)
      throw UsageError("distance: no box; give --box XMIN YMIN ZMIN XMAX YMAX ZMAX (metres)");
    const std::array<double, 6>& b = *box_;
    if (!z_) z_ = 0.5 * (b[2] + b[5]);
    if (*z_ < b[2] || *z_ > b[5]) {
      char line[256];
      std::snprintf(line, sizeof(line),
                    "--z %g lies outside the box's heights %g to %g; give a height within them",
                    *z_, b[2], b[5]);
      throw UsageError(line);
    }
    in.checkDeviceMemoryCap();
    in.checkOutputs();
  }

  int run(Invocation& in) override;

 private:
  std::optional<std::array<double, 6>> box_;
  std::optional<double> z_;
  double max_distance_m_ = kDefaultMaxDistanceM;
  bool unknown_occupied_ = true;  // DistanceFieldOptions' default: unknown space is no clearance
  std::uint32_t cell_pixels_ = 0;  // 0: chosen from the box
};

int Distance::run(Invocation& in) {
  const std::string& map_path = in.input();
  Context& context = in.context();
  const auto start = Clock::now();
  OccupancyMap map = loadMap(context, map_path, in.maxDeviceBytes());
  const double read_s = secondsSince(start);
  const double resolution = map.params().resolution;
  const std::array<double, 6>& b = *box_;
  const Eigen::Vector3f box_min = Eigen::Vector3d(b[0], b[1], b[2]).cast<float>();
  const Eigen::Vector3f box_max = Eigen::Vector3d(b[3], b[4], b[5]).cast<float>();

  // The picture's size from the box's cells (OctoMap's coordToKey of the float corners, as the
  // field takes them), checked before the field is built. A corner outside the key range is
  // left for the field to refuse, with its own words.
  const auto key = [resolution](double v) {
    return static_cast<long>(std::floor(double(static_cast<float>(v)) * (1.0 / resolution))) +
           32768;
  };
  const std::array<long, 2> box_cells{key(b[3]) - key(b[0]) + 1, key(b[4]) - key(b[1]) + 1};
  const std::uint32_t scale =
      cell_pixels_ != 0
          ? cell_pixels_
          : static_cast<std::uint32_t>(std::clamp<long>(
                long{kDefaultSide} / std::max<long>(1, std::max(box_cells[0], box_cells[1])), 1,
                long{kDefaultMaxCellPixels}));
  const long width = box_cells[0] * long{scale};
  const long slice_height = box_cells[1] * long{scale};
  const long height = slice_height + long{kBarGap + kBarHeight + kTickHeight};
  const bool in_range = key(b[0]) >= 0 && key(b[1]) >= 0 && key(b[3]) < 65536 && key(b[4]) < 65536;
  if (in_range && (width > long{kMaxSide} || height > long{kMaxSide}))
    throw UsageError("the picture would be " + std::to_string(width) + " x " +
                     std::to_string(height) + " pixels (the box is " +
                     std::to_string(box_cells[0]) + " x " + std::to_string(box_cells[1]) +
                     " cells, " + std::to_string(scale) + " pixels each); at most " +
                     std::to_string(kMaxSide) + " a side: give a smaller --box or --cell-pixels");

  const auto field_start = Clock::now();
  std::optional<DistanceField> field;
  try {
    field.emplace(map, box_min, box_max,
                  DistanceFieldOptions{.max_distance_m = static_cast<float>(max_distance_m_),
                                       .treat_unknown_as_occupied = unknown_occupied_});
  } catch (const Error& e) {
    // The box's own faults (beyond the map's key range, lines longer than the device
    // transforms) are the user's to fix; the cap's are a failure of the run (exit 1).
    if (e.code() == ErrorCode::kOutOfDeviceMemory) {
      // The library's remedy "Shrink the box" is --box here, its class name no user's word.
      const Error named = withOptionNames(e);
      std::string why = named.what();
      if (why.rfind("DistanceField: ", 0) == 0) why.erase(0, 15);
      for (std::size_t at = why.find("Shrink the box"); at != std::string::npos;
           at = why.find("Shrink the box", at))
        why.replace(at, 14, "Shrink --box");
      throw Error(e.code(), why, e.scan());
    }
    if (e.code() != ErrorCode::kInvalidArgument) throw withOptionNames(e);
    std::string why = e.what();
    if (why.rfind("DistanceField: ", 0) == 0) why.erase(0, 15);
    throw UsageError("--box: " + why);
  }
  const double field_s = secondsSince(field_start);
  const std::array<std::uint32_t, 3> size = field->size();
  const std::array<std::uint32_t, 3> min_key = field->minKey();

  // The slice: the layer of cells holding --z (inside the box: check() kept z within it).
  const auto layer = static_cast<std::uint32_t>(
      std::clamp<long>(key(*z_) - long{min_key[2]}, 0, long{size[2]} - 1));
  const float slice_z = keyCentre(min_key[2] + layer, resolution);

  const auto query_start = Clock::now();
  std::vector<Eigen::Vector3f> centres;
  centres.reserve(std::size_t{size[0]} * size[1]);
  for (std::uint32_t y = 0; y < size[1]; ++y)
    for (std::uint32_t x = 0; x < size[0]; ++x)
      centres.emplace_back(keyCentre(min_key[0] + x, resolution),
                           keyCentre(min_key[1] + y, resolution), slice_z);
  std::vector<DistanceSample> samples;
  std::vector<Lookup> cells;
  try {
    samples = field->distances(centres);
    cells = map.search(centres);
  } catch (const Error& e) {
    throw withOptionNames(e);
  }
  const double query_s = secondsSince(query_start);

  // The field's own count of cells (the same as `box_cells` above).
  const std::uint32_t slice_rows = size[1] * scale;
  RgbImage image(size[0] * scale, slice_rows + kBarGap + kBarHeight + kTickHeight);
  for (std::size_t i = 0; i < image.pixels.size(); i += 3)
    std::copy(kBackground.begin(), kBackground.end(), image.pixels.begin() + std::ptrdiff_t(i));
  std::size_t occupied = 0, unknown_obstacles = 0, free_cells = 0, capped = 0;
  float nearest_free = -1.0f, farthest = -1.0f;
  const float max_d = static_cast<float>(max_distance_m_);
  for (std::uint32_t y = 0; y < size[1]; ++y)
    for (std::uint32_t x = 0; x < size[0]; ++x) {
      const std::size_t i = std::size_t{y} * size[0] + x;
      const DistanceSample& s = samples[i];
      Rgb colour;
      if (s.squared_cells == 0) {
        const bool is_occupied = cells[i].state == CellState::kOccupied;
        ++(is_occupied ? occupied : unknown_obstacles);
        colour = is_occupied ? kOccupiedBlack : kUnknownObstacleGrey;
      } else {
        // No obstacle in the box: as far as the cap.
        const float d = s.squared_cells == DistanceSample::kNoObstacleCells ? max_d : s.distance_m;
        ++free_cells;
        capped += d >= max_d;
        nearest_free = nearest_free < 0.0f ? d : std::min(nearest_free, d);
        farthest = std::max(farthest, d);
        colour = distanceColor(static_cast<double>(d) / max_distance_m_);
      }
      const std::uint32_t row0 = (size[1] - 1 - y) * scale;  // y up
      for (std::uint32_t r = 0; r < scale; ++r)
        for (std::uint32_t c = 0; c < scale; ++c) image.set(x * scale + c, row0 + r, colour);
    }
  // The colour bar: 0 at the left edge, the maximum distance at the right, with its marks.
  const std::uint32_t bar_top = slice_rows + kBarGap;
  for (std::uint32_t x = 0; x < image.width; ++x) {
    const double t = image.width > 1 ? double(x) / double(image.width - 1) : 0.0;
    for (std::uint32_t r = 0; r < kBarHeight; ++r) image.set(x, bar_top + r, distanceColor(t));
  }
  for (int k = 0; k <= kTicks; ++k) {
    const auto x = static_cast<std::uint32_t>(
        std::lround(double(k) / kTicks * double(image.width > 0 ? image.width - 1 : 0)));
    for (std::uint32_t r = 0; r < kTickHeight; ++r) {
      image.set(x, bar_top + kBarHeight + r, kTickWhite);
      if (x + 1 < image.width && k < kTicks) image.set(x + 1, bar_top + kBarHeight + r, kTickWhite);
      if (x > 0 && k == kTicks) image.set(x - 1, bar_top + kBarHeight + r, kTickWhite);
    }
  }
  const auto write_start = Clock::now();
  in.files().write(0, [&](const std::string& temporary) { writePng(image, temporary); });
  in.files().commit();
  const double write_s = secondsSince(write_start);

  std::ostringstream s;
  char line[512];
  s << "device:    " << context.device().name << " (" << context.device().type << ")\n";
  s << "map:       " << map_path << " (resolution " << resolution << " m)\n";
  std::snprintf(line, sizeof(line),
                "box:       min (%g, %g, %g) max (%g, %g, %g) m: %u x %u x %u cells, %.1f MiB "
                "on the device\n",
                b[0], b[1], b[2], b[3], b[4], b[5], size[0], size[1], size[2],
                static_cast<double>(field->deviceBytes()) / (1024.0 * 1024.0));
  s << line;
  std::snprintf(line, sizeof(line), "slice:     z = %g m (cell layer %u of %u, centre %g m)\n", *z_,
                layer + 1, size[2], static_cast<double>(slice_z));
  s << line;
  s << "cells:     " << std::size_t{size[0]} * size[1] << " in the slice: " << occupied
    << " occupied";
  if (unknown_obstacles > 0 || unknown_occupied_)
    s << ", " << unknown_obstacles << " unknown counted as obstacles";
  s << ", " << free_cells << " free of obstacles (" << capped << " at or beyond --max-distance)\n";
  if (free_cells > 0) {
    std::snprintf(line, sizeof(line), "distances: %.4g to %.4g m among the cells off obstacles\n",
                  static_cast<double>(nearest_free), static_cast<double>(farthest));
    s << line;
  }
  std::snprintf(line, sizeof(line),
                "colours:   black occupied%s; red (0 m) to blue (%g m or farther), reversed "
                "Turbo; the bar below runs 0 to %g m, marks every %g m\n",
                unknown_occupied_ ? ", dark grey unknown" : "", max_distance_m_, max_distance_m_,
                max_distance_m_ / kTicks);
  s << line;
  std::snprintf(line, sizeof(line), "picture:   %u x %u pixels, %u per cell\n", image.width,
                image.height, scale);
  s << line;
  std::snprintf(line, sizeof(line),
                "time:      %.3f s (reading and upload %.3f s, field %.3f s (device %.3f ms), "
                "queries %.3f s, writing %.3f s)\n",
                read_s + field_s + query_s + write_s, read_s, field_s, field->lastUpdateMs(),
                query_s, write_s);
  s << line << "wrote:     " << in.output() << "\n";
  std::cout << s.str() << std::flush;
  return kExitOk;
}

}  // namespace

const Subcommand kDistanceCommand{
    .name = "distance",
    .print_help = printDistanceHelp,
    .input = "map file",
    .second_input_hint = "; the picture goes after -o",
    .outputs = Subcommand::Outputs::kOne,
    .writes = "one picture",
    .no_output = "no output file; add -o SLICE.png",
    .output_extensions = {".png"},
    .output_formats = ".png (8-bit RGB picture)",
    .max_device_memory = true,
    .value_options = {"--z", "--max-distance", "--cell-pixels", "--unknown"},
    .multi_value_options = {{"--box", "XMIN YMIN ZMIN XMAX YMAX ZMAX"}},
    .make = []() -> std::unique_ptr<Command> { return std::make_unique<Distance>(); },
    .examples =
        "  octovk distance map.bt --box -5 -5 0 5 5 2 --z 0.5 -o slice.png\n"
        "  octovk distance map.bt --box -5 -5 0 5 5 2 --max-distance 1 --unknown free\n"
        "                  -o optimistic.png\n"};

}  // namespace octovk::cli
