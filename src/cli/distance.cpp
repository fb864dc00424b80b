// octovk distance: a horizontal slice of the exact distance field over a box of a map
// (octovk/distance.hpp), computed on the device and drawn as a PNG: each cell of the slice
// coloured by its distance to the nearest obstacle, obstacles and unknown cells marked, axes in
// metres and a colour bar below with its distances.
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
#include "picture.hpp"
#include "png.hpp"
#include "report.hpp"

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
// Around the slice: the y axis's numbers on its left, a line of titles above it, the x axis's
// numbers and title below it, then the colour bar (its title, the bar, its ticks and numbers)
// and the swatches; the picture is at least kMinWidth wide, for the bar's numbers.
constexpr std::uint32_t kAxisLeft = 64;
constexpr std::uint32_t kTitleTop = 24;
constexpr std::uint32_t kRightMargin = 28;
constexpr std::uint32_t kMinWidth = 420;
constexpr std::uint32_t kBarTop = 56;  // below the slice's bottom edge
constexpr std::uint32_t kBarHeight = 14;
constexpr std::uint32_t kTickHeight = 5;
constexpr std::uint32_t kBelowSlice = 116;

const Rgb kOccupiedBlack{0, 0, 0};
const Rgb kUnknownObstacleGrey{96, 96, 96};
// Unknown space that is no obstacle: a grey that no distance colour is (Turbo has none).
const Rgb kUnknownGrey{178, 178, 178};
const Rgb kBackground{24, 24, 24};
const Rgb kTickWhite{235, 235, 235};

}  // namespace

void printDistanceHelp(std::ostream& out) {
  out << "octovk distance MAP.bt|MAP.ot --box XMIN YMIN ZMIN XMAX YMAX ZMAX [--z HEIGHT]\n"
         "                [--max-distance M] [--unknown occupied|free] [--cell-pixels N]\n"
         "                -o SLICE.png\n"
         "\n"
         "Computes the exact distance field over a box of a map on the Vulkan device (as\n"
         "dynamicEDT3D's DynamicEDTOctomap: each cell's distance to the nearest obstacle in the\n"
         "box) and draws the layer of cells at height --z as an 8-bit RGB PNG, x to the right,\n"
         "y up: occupied cells black, unknown ones dark grey (--unknown occupied) or light grey\n"
         "(--unknown free), the others by distance from red (0) to blue (--max-distance), with\n"
         "the bar below giving the scale in metres.\n"
         "\n"
         "Options:\n"
         "  -o, --output FILE      the .png picture to write. Required.\n"
         "      --box XMIN YMIN ZMIN XMAX YMAX ZMAX\n"
         "                         the field's box in metres (min <= max). Required.\n"
         "      --z HEIGHT         height of the slice in metres, within the box (default: the\n"
         "                         box's middle)\n"
         "      --max-distance M   distances are capped at M metres, M > 0 (default: "
      << kDefaultMaxDistanceM
      << ")\n"
         "      --unknown occupied|free\n"
         "                         whether unknown cells are obstacles (default: occupied)\n"
         "      --cell-pixels N    pixels per cell side, 1 to "
      << kMaxCellPixels << " (default: the most, up to " << kDefaultMaxCellPixels
      << ",\n"
         "                         that keep the longer side within "
      << kDefaultSide << " pixels)\n";
  printMaxDeviceMemoryHelp(out, "A map or field");
  out << "  -h, --help             show this help\n"
         "Values: '--name VALUE' or '--name=VALUE' ('--box=XMIN,YMIN,ZMIN,XMAX,YMAX,ZMAX').\n";
}

namespace {

// Where the picture puts the slice, its axes and the colour bar: the slice at (slice_x,
// slice_y), `scale` pixels a cell, y up; axes in metres on its left and below it; the colour bar
// below them, and the swatches of the cells that have no distance colour.
struct Layout {
  std::uint32_t scale = 1, slice_x = kAxisLeft, slice_y = kTitleTop, slice_w = 0, slice_h = 0;
  std::uint32_t width = 0, height = 0, bar_x0 = 0, bar_x1 = 0, bar_y = 0;

  Layout(std::uint32_t cells_x, std::uint32_t cells_y, std::uint32_t pixels_per_cell)
      : scale(pixels_per_cell),
        slice_w(cells_x * pixels_per_cell),
        slice_h(cells_y * pixels_per_cell) {
    width = std::max(slice_x + slice_w + kRightMargin, kMinWidth);
    height = slice_y + slice_h + kBelowSlice;
    bar_x0 = slice_x;
    bar_x1 = width - kRightMargin;
    bar_y = slice_y + slice_h + kBarTop;
  }
};

// The layer of the box's cells that holds --z, and its cells' centres.
struct Slice {
  std::uint32_t layer = 0;
  float z = 0.0f;
  std::vector<Eigen::Vector3f> centres;
  std::vector<DistanceSample> samples;
  std::vector<Lookup> cells;  // the map's state of each (unknown cells have no distance colour)
};

// What the slice's cells are, as the picture shows them.
struct SliceCounts {
  std::size_t occupied = 0, unknown_obstacles = 0, unknown = 0, free_cells = 0, capped = 0;
  float nearest_free = -1.0f, farthest = -1.0f;
};

class Distance final : public Command {
 public:
  bool option(const ParsedOption& opt) override {
    if (opt.name == "--box") {
      box_ = parseBox(opt, "-5 -5 0 5 5 2");
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
  // Pixels a cell: --cell-pixels, or the most that keep the picture within kDefaultSide.
  std::uint32_t cellPixels(long cells_x, long cells_y) const;
  // Refuses (UsageError) a box whose picture would be over kMaxSide, before the field is built.
  void checkPictureSize(double resolution) const;
  DistanceField field(OccupancyMap& map) const;
  Slice slice(OccupancyMap& map, const DistanceField& field) const;
  RgbImage drawCells(const Slice& slice, std::uint32_t cells_x, std::uint32_t cells_y,
                     std::uint32_t scale, SliceCounts& counts) const;
  void drawLegend(Canvas& canvas, const Layout& at, const Slice& slice, double resolution) const;

  std::optional<std::array<double, 6>> box_;
  std::optional<double> z_;
  double max_distance_m_ = kDefaultMaxDistanceM;
  bool unknown_occupied_ = true;   // DistanceFieldOptions' default: unknown space is no clearance
  std::uint32_t cell_pixels_ = 0;  // 0: chosen from the box
};

std::uint32_t Distance::cellPixels(long cells_x, long cells_y) const {
  if (cell_pixels_ != 0) return cell_pixels_;
  return static_cast<std::uint32_t>(
      std::clamp<long>(long{kDefaultSide} / std::max<long>(1, std::max(cells_x, cells_y)), 1,
                       long{kDefaultMaxCellPixels}));
}

void Distance::checkPictureSize(double resolution) const {
  // The box's cells as the field takes them (OctoMap's coordToKey of the float corners). A
  // corner outside the key range is left for the field to refuse, with its own words.
  const std::array<double, 6>& b = *box_;
  const std::optional<Key> lo =
      coordToKey(resolution, Eigen::Vector3d(b[0], b[1], b[2]).cast<float>());
  const std::optional<Key> hi =
      coordToKey(resolution, Eigen::Vector3d(b[3], b[4], b[5]).cast<float>());
  if (!lo || !hi) return;
  const long cells_x = long{(*hi)[0]} - (*lo)[0] + 1, cells_y = long{(*hi)[1]} - (*lo)[1] + 1;
  const long scale = cellPixels(cells_x, cells_y);
  const long width = std::max(long{kAxisLeft + kRightMargin} + cells_x * scale, long{kMinWidth});
  const long height = long{kTitleTop + kBelowSlice} + cells_y * scale;
  if (width > long{kMaxSide} || height > long{kMaxSide})
    throw UsageError("the picture would be " + std::to_string(width) + " x " +
                     std::to_string(height) + " pixels (the box is " + std::to_string(cells_x) +
                     " x " + std::to_string(cells_y) + " cells, " + std::to_string(scale) +
                     " pixels each, with its axes and colour bar); at most " +
                     std::to_string(kMaxSide) + " a side: give a smaller --box or --cell-pixels");
}

DistanceField Distance::field(OccupancyMap& map) const {
  const std::array<double, 6>& b = *box_;
  try {
    return DistanceField(map, Eigen::Vector3d(b[0], b[1], b[2]).cast<float>(),
                         Eigen::Vector3d(b[3], b[4], b[5]).cast<float>(),
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
}

Slice Distance::slice(OccupancyMap& map, const DistanceField& field) const {
  const double resolution = map.params().resolution;
  const std::array<std::uint32_t, 3> size = field.size();
  const std::array<std::uint32_t, 3> min_key = field.minKey();
  const auto key = [&](std::uint32_t x, std::uint32_t y, std::uint32_t z) {
    return Key{static_cast<std::uint16_t>(min_key[0] + x),
               static_cast<std::uint16_t>(min_key[1] + y),
               static_cast<std::uint16_t>(min_key[2] + z)};
  };
  // The layer of cells holding --z (inside the box: check() kept z within it).
  Slice slice;
  const std::array<double, 6>& b = *box_;
  const std::optional<Key> z_key =
      coordToKey(resolution, Eigen::Vector3d(b[0], b[1], *z_).cast<float>());
  slice.layer = static_cast<std::uint32_t>(
      std::clamp<long>(z_key ? long{(*z_key)[2]} - long{min_key[2]} : 0, 0, long{size[2]} - 1));
  slice.z = keyToCoord(resolution, key(0, 0, slice.layer)).z();
  slice.centres.reserve(std::size_t{size[0]} * size[1]);
  for (std::uint32_t y = 0; y < size[1]; ++y)
    for (std::uint32_t x = 0; x < size[0]; ++x)
      slice.centres.push_back(keyToCoord(resolution, key(x, y, slice.layer)));
  try {
    slice.samples = field.distances(slice.centres);
    slice.cells = map.search(slice.centres);
  } catch (const Error& e) {
    throw withOptionNames(e);
  }
  return slice;
}

// The slice's cells in their colours, one square of `scale` pixels each, y up; and their counts.
RgbImage Distance::drawCells(const Slice& slice, std::uint32_t cells_x, std::uint32_t cells_y,
                             std::uint32_t scale, SliceCounts& counts) const {
  RgbImage image(cells_x * scale, cells_y * scale);
  const float max_d = static_cast<float>(max_distance_m_);
  for (std::uint32_t y = 0; y < cells_y; ++y)
    for (std::uint32_t x = 0; x < cells_x; ++x) {
      const std::size_t i = std::size_t{y} * cells_x + x;
      const DistanceSample& s = slice.samples[i];
      const bool unknown = slice.cells[i].state == CellState::kUnknown;
      Rgb colour;
      if (s.squared_cells == 0) {
        const bool is_occupied = slice.cells[i].state == CellState::kOccupied;
        ++(is_occupied ? counts.occupied : counts.unknown_obstacles);
        colour = is_occupied ? kOccupiedBlack : kUnknownObstacleGrey;
      } else if (unknown) {
        // The map never saw it: a distance there is no clearance (issue 30).
        ++counts.unknown;
        colour = kUnknownGrey;
      } else {
        // No obstacle in the box: as far as the cap.
        const float d = s.squared_cells == DistanceSample::kNoObstacleCells ? max_d : s.distance_m;
        ++counts.free_cells;
        counts.capped += d >= max_d;
        counts.nearest_free = counts.nearest_free < 0.0f ? d : std::min(counts.nearest_free, d);
        counts.farthest = std::max(counts.farthest, d);
        colour = distanceColor(static_cast<double>(d) / max_distance_m_);
      }
      const std::uint32_t row0 = (cells_y - 1 - y) * scale;  // y up
      for (std::uint32_t r = 0; r < scale; ++r)
        for (std::uint32_t c = 0; c < scale; ++c) image.set(x * scale + c, row0 + r, colour);
    }
  return image;
}

// The axes in metres around the slice, the colour bar with its distances, the swatches.
void Distance::drawLegend(Canvas& canvas, const Layout& at, const Slice& slice,
                          double resolution) const {
  const double cell_px = at.scale / resolution;  // pixels a metre
  const Eigen::Vector3f first = slice.centres.front(), last = slice.centres.back();
  const double x_lo = first.x() - 0.5 * resolution, x_hi = last.x() + 0.5 * resolution;
  const double y_lo = first.y() - 0.5 * resolution, y_hi = last.y() + 0.5 * resolution;
  const double left = at.slice_x, top = at.slice_y;
  const double bottom = top + at.slice_h, right = left + at.slice_w;
  canvas.line(left - 0.5, top, left - 0.5, bottom + 1, kTickWhite);
  canvas.line(left - 1, bottom + 0.5, right, bottom + 0.5, kTickWhite);
  // Every tick gets its mark; its number where it does not run into the one before.
  double step = 1.0, free_from = -1e9;
  for (const double x : niceTicks(x_lo, x_hi, std::max(3, int(at.slice_w / 45)), &step)) {
    const double px = left + (x - x_lo) * cell_px;
    const std::string words = tickText(x, step);
    const double half = 0.5 * canvas.textWidth(words, 11);
    canvas.line(px, bottom + 1, px, bottom + 6, kTickWhite);
    if (px - half < free_from) continue;
    canvas.text(words, px, bottom + 14, 11, kTickWhite, Canvas::Align::kCentre);
    free_from = px + half + 6;
  }
  canvas.text("x (m)", left + 0.5 * at.slice_w, bottom + 30, 11, kTickWhite,
              Canvas::Align::kCentre);
  free_from = 1e9;
  for (const double y : niceTicks(y_lo, y_hi, std::max(3, int(at.slice_h / 30)), &step)) {
    const double py = bottom - (y - y_lo) * cell_px;
    canvas.line(left - 6, py, left - 1, py, kTickWhite);
    if (py + 7 > free_from) continue;
    canvas.text(tickText(y, step), left - 9, py, 11, kTickWhite, Canvas::Align::kEnd);
    free_from = py - 7;
  }
  canvas.text("y (m)", left - 9, top - 12, 11, kTickWhite, Canvas::Align::kEnd);
  canvas.text(format("slice at z = %g m", static_cast<double>(slice.z)), left, top - 12, 11,
              kTickWhite);

  // The colour bar: 0 at the left end, the maximum distance at the right, ticks in metres.
  canvas.text("distance to the nearest obstacle", at.bar_x0, at.bar_y - 10, 11, kTickWhite);
  const double bar_w = at.bar_x1 - at.bar_x0;
  for (std::uint32_t x = at.bar_x0; x < at.bar_x1; ++x)
    canvas.fill(x, at.bar_y, 1, kBarHeight,
                distanceColor(bar_w > 1 ? (x - at.bar_x0) / (bar_w - 1) : 0.0));
  // The cap's number at the right end; the round distances before it where they have room.
  const double tick_y = at.bar_y + kBarHeight + kTickHeight + 9;
  const std::string cap = format("%g m or more", max_distance_m_);
  canvas.line(at.bar_x1 - 0.5, at.bar_y + kBarHeight, at.bar_x1 - 0.5,
              at.bar_y + kBarHeight + kTickHeight, kTickWhite);
  canvas.text(cap, at.bar_x1, tick_y, 11, kTickWhite, Canvas::Align::kEnd);
  const double cap_left = at.bar_x1 - canvas.textWidth(cap, 11);
  for (const double d : niceTicks(0.0, max_distance_m_, std::clamp(int(bar_w / 60), 2, 9), &step)) {
    if (d >= max_distance_m_ * (1 - 1e-9)) continue;
    const double px = at.bar_x0 + d / max_distance_m_ * bar_w + 0.5;
    const std::string words = tickText(d, step, "m");
    canvas.line(px, at.bar_y + kBarHeight, px, at.bar_y + kBarHeight + kTickHeight, kTickWhite);
    if (px + 0.5 * canvas.textWidth(words, 11) + 8 < cap_left)
      canvas.text(words, px, tick_y, 11, kTickWhite,
                  d == 0.0 ? Canvas::Align::kStart : Canvas::Align::kCentre);
  }
  // The cells drawn without a distance colour.
  const double y = at.bar_y + kBarHeight + kTickHeight + 30;
  double x = at.bar_x0;
  const auto swatch = [&](const Rgb& colour, const std::string& words) {
    canvas.fill(x, y - 6, 12, 12, colour);
    canvas.line(x, y - 6.5, x + 12, y - 6.5, kTickWhite);  // a frame, for black
    canvas.line(x, y + 6.5, x + 12, y + 6.5, kTickWhite);
    canvas.text(words, x + 17, y, 11, kTickWhite);
    x += 17 + canvas.textWidth(words, 11) + 14;
  };
  swatch(kOccupiedBlack, "occupied");
  if (unknown_occupied_)
    swatch(kUnknownObstacleGrey, "unknown, an obstacle");
  else
    swatch(kUnknownGrey, "unknown (no distance)");
}

int Distance::run(Invocation& in) {
  Steps steps;
  OccupancyMap map = steps.run("reading and upload", [&] { return loadMap(in); });
  const double resolution = map.params().resolution;
  checkPictureSize(resolution);
  const DistanceField distances = steps.run("field", [&] { return field(map); });
  steps.note("field", format("device %.3f ms", distances.lastUpdateMs()));
  const Slice cut = steps.run("queries", [&] { return slice(map, distances); });

  const std::array<std::uint32_t, 3> size = distances.size();
  const Layout at(size[0], size[1], cellPixels(size[0], size[1]));
  SliceCounts counts;
  steps.run("writing", [&] {
    Canvas canvas(at.width, at.height, kBackground);
    canvas.paste(drawCells(cut, size[0], size[1], at.scale, counts), at.slice_x, at.slice_y);
    drawLegend(canvas, at, cut, resolution);
    in.files().write(0, [&](const std::string& temporary) { canvas.writePng(temporary); });
    in.files().commit();
  });

  const std::array<double, 6>& b = *box_;
  Report report(11);
  report.device(in.context())
      .line("map", in.input() + format(" (resolution %g m)", resolution))
      .line("box",
            boxText(b) + format(" m: %u x %u x %u cells, %.1f MiB on the device", size[0], size[1],
                                size[2],
                                static_cast<double>(distances.deviceBytes()) / (1024.0 * 1024.0)))
      .line("slice", format("z = %g m (cell layer %u of %u, centre %g m)", *z_, cut.layer + 1,
                            size[2], static_cast<double>(cut.z)));
  std::string cells =
      format("%zu in the slice: %zu occupied", std::size_t{size[0]} * size[1], counts.occupied);
  if (counts.unknown_obstacles > 0 || unknown_occupied_)
    cells += format(", %zu unknown counted as obstacles", counts.unknown_obstacles);
  if (counts.unknown > 0)
    cells += format(", %zu unknown (grey: no distance shown)", counts.unknown);
  report.line("cells", cells + format(", %zu free of obstacles (%zu at or beyond --max-distance)",
                                      counts.free_cells, counts.capped));
  if (counts.free_cells > 0)
    report.line("distances", format("%.4g to %.4g m among the free cells",
                                    static_cast<double>(counts.nearest_free),
                                    static_cast<double>(counts.farthest)));
  return report
      .line("colours",
            format("black occupied, %s; red (0 m) to blue (%g m or farther), reversed Turbo; the "
                   "bar below runs 0 to %g m",
                   unknown_occupied_ ? "dark grey unknown (an obstacle)" : "light grey unknown",
                   max_distance_m_, max_distance_m_))
      .line("picture",
            format("%u x %u pixels, %u per cell; the slice at (%u, %u) to (%u, %u), axes in "
                   "metres; the colour bar from (%u, %u) to (%u, %u)",
                   at.width, at.height, at.scale, at.slice_x, at.slice_y,
                   at.slice_x + at.slice_w - 1, at.slice_y + at.slice_h - 1, at.bar_x0, at.bar_y,
                   at.bar_x1 - 1, at.bar_y + kBarHeight - 1))
      .finish(steps, in.outputs());
}

}  // namespace

std::unique_ptr<Command> makeDistance() { return std::make_unique<Distance>(); }

}  // namespace octovk::cli
