// octovk export: a map's leaf cells (centre, edge, log-odds, colour) as an ASCII PLY point cloud
// for other viewers; all of them, the occupied ones, or those in a box (selected on the device).
#include <Eigen/Core>
#include <algorithm>
#include <array>
#include <cstdio>
#include <iostream>
#include <limits>
#include <optional>
#include <sstream>

#include "command.hpp"
#include "octovk/octovk.hpp"
#include "ply.hpp"
#include "png.hpp"

namespace octovk::cli {

namespace {

constexpr const char* kExportUsage =
    "octovk export MAP.bt|MAP.ot -o CELLS.ply [--occupied-only] "
    "[--box XMIN YMIN ZMIN XMAX YMAX ZMAX] [--color height|occupancy] "
    "[--max-device-memory BYTES]";

enum class Coloring { kHeight, kOccupancy };

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

void printExportHelp(std::ostream& out) {
  out << "octovk export MAP.bt|MAP.ot -o CELLS.ply [--occupied-only]\n"
         "              [--box XMIN YMIN ZMIN XMAX YMAX ZMAX] [--color height|occupancy]\n"
         "\n"
         "Writes the leaf cells of an OctoMap .bt or .ot map as an ASCII PLY point cloud, one\n"
         "vertex per leaf (a pruned leaf is one vertex with its larger size), for viewers such\n"
         "as MeshLab or CloudCompare. Each vertex has:\n"
         "  float x, y, z       centre of the cell, metres\n"
         "  float size          edge of the cell, metres\n"
         "  float log_odds      occupancy log-odds; occupied when >= 0 (probability 0.5)\n"
         "  uchar red, green, blue   the colour chosen by --color\n"
         "\n"
         "Options:\n"
         "  -o, --output FILE      the .ply file to write. Written to a temporary file beside\n"
         "                         it and renamed once complete. Required.\n"
         "      --occupied-only    only the occupied leaves (default: occupied and free)\n"
         "      --box XMIN YMIN ZMIN XMAX YMAX ZMAX\n"
         "                         only the leaves that OctoMap's leaf_bbx_iterator visits for\n"
         "                         this box (metres): every leaf overlapping the box's cells,\n"
         "                         selected on the device; corners beyond the map's domain are\n"
         "                         moved onto its border (default: the whole map)\n"
         "      --color MODE       height: occupied cells by height, blue (low) to red (high)\n"
         "                         over the z range of the exported occupied cells, free cells\n"
         "                         grey; occupancy: occupied red, free green (default: height)\n";
  printMaxDeviceMemoryHelp(out, "A map or a --box selection");
  out << "  -h, --help             show this help\n"
         "Options take their value as '--name VALUE' or '--name=VALUE'; --box also as\n"
         "'--box=XMIN,YMIN,ZMIN,XMAX,YMAX,ZMAX'.\n"
         "\n"
         "Output: the device used, then on stdout the cells written (occupied and free), the\n"
         "time taken and the file written.\n";
}

class Export final : public Command {
 public:
  bool option(const ParsedOption& opt) override {
    if (opt.name == "--occupied-only") {
      occupied_only_ = true;
    } else if (opt.name == "--box") {
      const std::vector<double> v = parseNumbers(opt, "-5 -5 0 5 5 2");
      for (int a = 0; a < 3; ++a)
        if (v[a] > v[a + 3])
          throw UsageError("--box: the minimum " + std::string(1, "xyz"[a]) + " (" + opt.values[a] +
                           ") is above the maximum (" + opt.values[a + 3] +
                           "); write --box XMIN YMIN ZMIN XMAX YMAX ZMAX");
      box_ = std::array<double, 6>{v[0], v[1], v[2], v[3], v[4], v[5]};
    } else if (opt.name == "--color") {
      if (opt.value == "height")
        coloring_ = Coloring::kHeight;
      else if (opt.value == "occupancy")
        coloring_ = Coloring::kOccupancy;
      else
        throw UsageError("--color expects 'height' or 'occupancy', got '" + opt.value + "'");
    } else {
      return false;
    }
    return true;
  }

  void check(Invocation& in) override {
    checkMapInput(in.input(), kExportUsage);
    in.checkDeviceMemoryCap();
    in.checkOutputs();
  }

  int run(Invocation& in) override;

 private:
  bool occupied_only_ = false;
  std::optional<std::array<double, 6>> box_;
  Coloring coloring_ = Coloring::kHeight;
};

int Export::run(Invocation& in) {
  const std::string& map_path = in.input();
  Context& context = in.context();
  const auto start = Clock::now();
  OccupancyMap map = loadMap(context, map_path, in.maxDeviceBytes());
  const double read_s = secondsSince(start);

  const auto select_start = Clock::now();
  const double resolution = map.params().resolution;
  const float occupied_log_odds = occupancyLogOdds(map.params());
  std::vector<OccupancyMap::LeafBoxHost> cells;
  try {
    if (box_) {
      const std::array<double, 6>& b = *box_;
      cells = map.leavesInBox(clampToDomain(b[0], b[1], b[2], resolution),
                              clampToDomain(b[3], b[4], b[5], resolution), occupied_only_);
    } else {
      cells = map.downloadLeafBoxes();
      if (occupied_only_)
        std::erase_if(cells, [&](const OccupancyMap::LeafBoxHost& c) {
          return !(c.log_odds >= occupied_log_odds);
        });
    }
  } catch (const Error& e) {
    throw withOptionNames(e);
  }
  const double select_s = secondsSince(select_start);

  const auto write_start = Clock::now();
  std::size_t occupied = 0;
  float z_min = std::numeric_limits<float>::max(), z_max = std::numeric_limits<float>::lowest();
  for (const OccupancyMap::LeafBoxHost& c : cells) {
    if (c.log_odds < occupied_log_odds) continue;
    ++occupied;
    z_min = std::min(z_min, c.center[2]);
    z_max = std::max(z_max, c.center[2]);
  }
  std::vector<Rgb> colours(cells.size());
  for (std::size_t i = 0; i < cells.size(); ++i) {
    const bool is_occupied = cells[i].log_odds >= occupied_log_odds;
    if (coloring_ == Coloring::kOccupancy)
      colours[i] = is_occupied ? kOccupiedRed : kFreeGreen;
    else if (!is_occupied)
      colours[i] = kFreeGrey;
    else
      colours[i] =
          heightColor(z_max > z_min ? (cells[i].center[2] - z_min) / (z_max - z_min) : 0.5);
  }
  std::ostringstream comment;
  comment << "octovk export of " << map_path << " (resolution " << resolution
          << " m): leaf cells, centre x y z and edge size in metres, occupancy log-odds, colour by "
          << (coloring_ == Coloring::kHeight ? "height" : "occupancy");
  in.files().write(
      0, [&](const std::string& temporary) { writePly(temporary, cells, colours, comment.str()); });
  in.files().commit();
  const double write_s = secondsSince(write_start);

  std::ostringstream s;
  s << "device:  " << context.device().name << " (" << context.device().type << ")\n";
  s << "map:     " << map_path << "\n";
  if (box_) {
    const std::array<double, 6>& b = *box_;
    char line[256];
    std::snprintf(line, sizeof(line), "box:     min (%g, %g, %g) max (%g, %g, %g) m\n", b[0], b[1],
                  b[2], b[3], b[4], b[5]);
    s << line;
  }
  s << "cells:   " << cells.size() << " leaves (" << occupied << " occupied, "
    << cells.size() - occupied << " free)\n";
  char line[256];
  std::snprintf(line, sizeof(line),
                "time:    %.3f s (reading and upload %.3f s, selecting %.3f s, writing %.3f s)\n",
                read_s + select_s + write_s, read_s, select_s, write_s);
  s << line << "wrote:   " << in.output() << "\n";
  std::cout << s.str() << std::flush;
  return kExitOk;
}

}  // namespace

const Subcommand kExportCommand{
    .name = "export",
    .print_help = printExportHelp,
    .input = "map file",
    .second_input_hint = "; the PLY file goes after -o",
    .outputs = Subcommand::Outputs::kOne,
    .writes = "one file",
    .no_output = "no output file; add -o CELLS.ply",
    .output_extensions = {".ply"},
    .output_formats = ".ply (ASCII PLY point cloud)",
    .max_device_memory = true,
    .value_options = {"--color"},
    .multi_value_options = {{"--box", "XMIN YMIN ZMIN XMAX YMAX ZMAX"}},
    .make = []() -> std::unique_ptr<Command> { return std::make_unique<Export>(); },
    .examples =
        "  octovk export map.bt -o cells.ply --occupied-only\n"
        "  octovk export map.bt -o box.ply --box -2 -2 0 2 2 2 --color occupancy\n"};

}  // namespace octovk::cli
