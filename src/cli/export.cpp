// octovk export: a map's leaf cells (centre, edge, log-odds, colour) as an ASCII PLY point cloud
// for other viewers; all of them, the occupied ones, or those in a box (selected on the device).
#include <Eigen/Core>
#include <algorithm>
#include <array>
#include <iostream>
#include <limits>
#include <optional>
#include <sstream>

#include "command.hpp"
#include "octovk/octovk.hpp"
#include "ply.hpp"
#include "png.hpp"
#include "report.hpp"

namespace octovk::cli {

namespace {

constexpr const char* kExportUsage =
    "octovk export MAP.bt|MAP.ot -o CELLS.ply [--occupied-only] "
    "[--box XMIN YMIN ZMIN XMAX YMAX ZMAX] [--color map|height|occupancy] "
    "[--max-device-memory BYTES]";

// kMap: a ColorOcTree's own leaf colours (the default for one; other maps have none).
enum class Coloring { kMap, kHeight, kOccupancy };

const Rgb kFreeGrey{190, 190, 190};
const Rgb kOccupiedRed{210, 50, 40};
const Rgb kFreeGreen{70, 170, 90};

void writePly(const std::string& path, const std::vector<OccupancyMap::LeafBoxHost>& cells,
              const std::vector<Rgb>& colours, const std::string& comment) {
  writeAsciiPly(path, comment, cells.size(),
                {"float x", "float y", "float z", "float size", "float log_odds", "uchar red",
                 "uchar green", "uchar blue"},
                [&](std::string& text, std::size_t i) {
                  const OccupancyMap::LeafBoxHost& c = cells[i];
                  appendNumber(text, c.center[0], ' ');
                  appendNumber(text, c.center[1], ' ');
                  appendNumber(text, c.center[2], ' ');
                  appendNumber(text, c.size, ' ');
                  appendNumber(text, c.log_odds, ' ');
                  appendByte(text, colours[i][0], ' ');
                  appendByte(text, colours[i][1], ' ');
                  appendByte(text, colours[i][2], '\n');
                });
}

}  // namespace

void printExportHelp(std::ostream& out) {
  out << "octovk export MAP.bt|MAP.ot -o CELLS.ply [--occupied-only]\n"
         "              [--box XMIN YMIN ZMIN XMAX YMAX ZMAX] [--color map|height|occupancy]\n"
         "\n"
         "Writes the leaf cells of an OctoMap .bt or .ot map as an ASCII PLY point cloud (for\n"
         "MeshLab, CloudCompare, ...), one vertex per leaf: x y z (centre), size (edge),\n"
         "log_odds (occupied when >= 0) and red green blue, metres throughout.\n"
         "\n"
         "Options:\n"
         "  -o, --output FILE      the .ply file to write. Required.\n"
         "      --occupied-only    only the occupied leaves (default: occupied and free)\n"
         "      --box XMIN YMIN ZMIN XMAX YMAX ZMAX\n"
         "                         only the leaves OctoMap's leaf_bbx_iterator visits for this "
         "box\n"
         "                         in metres (default: the whole map)\n"
         "      --color MODE       map: each leaf's own colour (a ColorOcTree's; white where none\n"
         "                         is set); height: occupied cells blue (low) to red (high), free\n"
         "                         grey; occupancy: occupied red, free green (default: map for a\n"
         "                         ColorOcTree, else height)\n";
  printMaxDeviceMemoryHelp(out, "A map or selection");
  out << "  -h, --help             show this help\n"
         "Values: '--name VALUE' or '--name=VALUE' ('--box=XMIN,YMIN,ZMIN,XMAX,YMAX,ZMAX').\n";
}

namespace {

class Export final : public Command {
 public:
  bool option(const ParsedOption& opt) override {
    if (opt.name == "--occupied-only") {
      occupied_only_ = true;
    } else if (opt.name == "--box") {
      box_ = parseBox(opt, "-5 -5 0 5 5 2");
    } else if (opt.name == "--color") {
      if (opt.value == "map")
        coloring_ = Coloring::kMap;
      else if (opt.value == "height")
        coloring_ = Coloring::kHeight;
      else if (opt.value == "occupancy")
        coloring_ = Coloring::kOccupancy;
      else
        throw UsageError("--color expects 'map', 'height' or 'occupancy', got '" + opt.value + "'");
    } else {
      return false;
    }
    return true;
  }

  void check(Invocation& in) override { in.checkMapCommand(kExportUsage); }

  int run(Invocation& in) override;

 private:
  // The cells to write: all, the occupied ones, or those in the box.
  std::vector<OccupancyMap::LeafBoxHost> select(OccupancyMap& map) const;
  // Colours the cells and writes them (-o); returns how many are occupied.
  std::size_t write(Invocation& in, OccupancyMap& map,
                    const std::vector<OccupancyMap::LeafBoxHost>& cells) const;

  bool occupied_only_ = false;
  std::optional<std::array<double, 6>> box_;
  std::optional<Coloring> coloring_;  // unset: the map's colours for a ColorOcTree, else height
};

int Export::run(Invocation& in) {
  Steps steps;
  OccupancyMap map = steps.run("reading and upload", [&] { return loadMap(in); });
  const std::vector<OccupancyMap::LeafBoxHost> cells =
      steps.run("selecting", [&] { return select(map); });
  const std::size_t occupied = steps.run("writing", [&] { return write(in, map, cells); });

  Report report(9);
  report.device(in.context()).line("map", in.input());
  if (box_) report.line("box", boxText(*box_) + " m");
  return report
      .line("cells", format("%zu leaves (%zu occupied, %zu free)", cells.size(), occupied,
                            cells.size() - occupied))
      .finish(steps, in.outputs());
}

std::vector<OccupancyMap::LeafBoxHost> Export::select(OccupancyMap& map) const {
  try {
    if (box_) {
      const std::array<double, 6>& b = *box_;
      const double resolution = map.params().resolution;
      return map.leavesInBox(clampToDomain(b[0], b[1], b[2], resolution),
                             clampToDomain(b[3], b[4], b[5], resolution), occupied_only_);
    }
    std::vector<OccupancyMap::LeafBoxHost> cells = map.downloadLeafBoxes();
    const float occupied_log_odds = occupancyLogOdds(map.params());
    if (occupied_only_)
      std::erase_if(cells, [&](const OccupancyMap::LeafBoxHost& c) {
        return !(c.log_odds >= occupied_log_odds);
      });
    return cells;
  } catch (const Error& e) {
    throw withOptionNames(e);
  }
}

// The colour each cell's leaf holds (search() at its centre finds the leaf itself).
std::vector<Rgb> leafColours(OccupancyMap& map,
                             const std::vector<OccupancyMap::LeafBoxHost>& cells) {
  std::vector<Eigen::Vector3f> centres;
  centres.reserve(cells.size());
  for (const OccupancyMap::LeafBoxHost& c : cells)
    centres.emplace_back(c.center[0], c.center[1], c.center[2]);
  std::vector<Lookup> found;
  try {
    found = map.search(centres);
  } catch (const Error& e) {
    throw withOptionNames(e);
  }
  std::vector<Rgb> colours(cells.size());
  for (std::size_t i = 0; i < cells.size(); ++i)
    if (found[i].state != CellState::kUnknown) {
      const octovk::Rgb c = unpackRgb(found[i].payload);
      colours[i] = {c.r, c.g, c.b};
    } else {
      colours[i] = {255, 255, 255};  // no node: OctoMap's "no colour"
    }
  return colours;
}

std::size_t Export::write(Invocation& in, OccupancyMap& map,
                          const std::vector<OccupancyMap::LeafBoxHost>& cells) const {
  const bool has_colours = map.params().payload == Payload::kColor;
  const Coloring coloring = coloring_.value_or(has_colours ? Coloring::kMap : Coloring::kHeight);
  if (coloring == Coloring::kMap && !has_colours)
    throw UsageError("--color map: '" + in.input() + "' holds " +
                     (map.params().payload == Payload::kStamp ? "an OcTreeStamped" : "an OcTree") +
                     ", which has no colours (a ColorOcTree does); use --color height or "
                     "--color occupancy");
  const float occupied_log_odds = occupancyLogOdds(map.params());
  std::size_t occupied = 0;
  float z_min = std::numeric_limits<float>::max(), z_max = std::numeric_limits<float>::lowest();
  for (const OccupancyMap::LeafBoxHost& c : cells) {
    if (c.log_odds < occupied_log_odds) continue;
    ++occupied;
    z_min = std::min(z_min, c.center[2]);
    z_max = std::max(z_max, c.center[2]);
  }
  std::vector<Rgb> colours =
      coloring == Coloring::kMap ? leafColours(map, cells) : std::vector<Rgb>(cells.size());
  for (std::size_t i = 0; i < cells.size() && coloring != Coloring::kMap; ++i) {
    const bool is_occupied = cells[i].log_odds >= occupied_log_odds;
    if (coloring == Coloring::kOccupancy)
      colours[i] = is_occupied ? kOccupiedRed : kFreeGreen;
    else if (!is_occupied)
      colours[i] = kFreeGrey;
    else
      colours[i] =
          heightColor(z_max > z_min ? (cells[i].center[2] - z_min) / (z_max - z_min) : 0.5);
  }
  std::ostringstream comment;
  comment << "octovk export of " << in.input() << " (resolution " << map.params().resolution
          << " m): leaf cells, centre x y z and edge size in metres, occupancy log-odds, ";
  if (coloring == Coloring::kMap)
    comment << "colour: the map's (ColorOcTree)";
  else
    comment << "colour by " << (coloring == Coloring::kHeight ? "height" : "occupancy");
  in.files().write(
      0, [&](const std::string& temporary) { writePly(temporary, cells, colours, comment.str()); });
  in.files().commit();
  return occupied;
}

}  // namespace

std::unique_ptr<Command> makeExport() { return std::make_unique<Export>(); }

}  // namespace octovk::cli
