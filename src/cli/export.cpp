// octovk export: a map's leaf cells (centre, edge, log-odds, colour) as an ASCII PLY point cloud
// for other viewers; all of them, the occupied ones, or those in a box (selected on the device).
#include <Eigen/Core>
#include <algorithm>
#include <array>
#include <cerrno>
#include <charconv>
#include <chrono>
#include <cstdio>
#include <cstring>
#include <fstream>
#include <iostream>
#include <limits>
#include <optional>
#include <sstream>

#include "cli.hpp"
#include "octovk/octovk.hpp"
#include "png.hpp"

namespace octovk::cli {

namespace {

using Clock = std::chrono::steady_clock;

constexpr const char* kExportUsage =
    "octovk export MAP.bt|MAP.ot -o CELLS.ply [--occupied-only] "
    "[--box XMIN YMIN ZMIN XMAX YMAX ZMAX] [--color height|occupancy] "
    "[--max-device-memory BYTES]";

enum class Coloring { kHeight, kOccupancy };

struct ExportOptions {
  std::string map_path;
  std::string output_path;
  bool occupied_only = false;
  std::optional<std::array<double, 6>> box;
  Coloring coloring = Coloring::kHeight;
  MapParams cap;  // only its max_device_bytes (--max-device-memory): the rest comes from the file
};

const Rgb kFreeGrey{190, 190, 190};
const Rgb kOccupiedRed{210, 50, 40};
const Rgb kFreeGreen{70, 170, 90};

double secondsSince(Clock::time_point start) {
  return std::chrono::duration<double>(Clock::now() - start).count();
}

ExportOptions parseExport(const std::vector<std::string>& args) {
  ExportOptions o;
  ArgReader reader(args, {"-o", "--output", "--color", kMaxDeviceMemoryOption},
                   {{"--box", "XMIN YMIN ZMIN XMAX YMAX ZMAX"}});
  while (reader.next()) {
    if (!reader.isOption()) {
      if (!o.map_path.empty())
        throw UsageError("unexpected argument '" + reader.positional() +
                         "': export takes one map file (" + o.map_path +
                         "); the PLY file goes after -o");
      o.map_path = reader.positional();
      continue;
    }
    const ParsedOption& opt = reader.option();
    if (opt.name == "-o" || opt.name == "--output") {
      if (!o.output_path.empty()) throw UsageError("export writes one file; -o is given twice");
      o.output_path = opt.value;
    } else if (opt.name == "--occupied-only") {
      o.occupied_only = true;
    } else if (opt.name == kMaxDeviceMemoryOption) {
      o.cap.max_device_bytes = parseByteCount(opt);
    } else if (opt.name == "--box") {
      const std::vector<double> v = parseNumbers(opt, "-5 -5 0 5 5 2");
      for (int a = 0; a < 3; ++a)
        if (v[a] > v[a + 3])
          throw UsageError("--box: the minimum " + std::string(1, "xyz"[a]) + " (" + opt.values[a] +
                           ") is above the maximum (" + opt.values[a + 3] +
                           "); write --box XMIN YMIN ZMIN XMAX YMAX ZMAX");
      o.box = std::array<double, 6>{v[0], v[1], v[2], v[3], v[4], v[5]};
    } else if (opt.name == "--color") {
      if (opt.value == "height")
        o.coloring = Coloring::kHeight;
      else if (opt.value == "occupancy")
        o.coloring = Coloring::kOccupancy;
      else
        throw UsageError("--color expects 'height' or 'occupancy', got '" + opt.value + "'");
    } else {
      throw UsageError("unknown option '" + opt.name +
                       "' for export; see 'octovk export --help' for the options");
    }
  }
  checkMapInput(o.map_path, kExportUsage);
  checkDeviceMemoryCap(o.cap);
  if (o.output_path.empty()) throw UsageError("no output file; add -o CELLS.ply");
  checkOutputFile(o.output_path, {".ply"}, ".ply (ASCII PLY point cloud)");
  return o;
}

// A box corner clamped into the map's domain (keys 0 … 65535, centred on 0), so that a box
// larger than the map means all of it rather than nothing.
Eigen::Vector3f clampToDomain(double x, double y, double z, double resolution) {
  const double limit = 32767.5 * resolution;  // the centre of the outermost cell
  const auto c = [limit](double v) { return static_cast<float>(std::clamp(v, -limit, limit)); };
  return {c(x), c(y), c(z)};
}

// Appends `value` in its shortest exact form and a separator.
void appendNumber(std::string& out, float value, char separator) {
  char text[32];
  const auto [end, ec] = std::to_chars(text, text + sizeof(text), value);
  (void)ec;  // 32 characters hold every float
  out.append(text, end);
  out += separator;
}

void appendByte(std::string& out, std::uint8_t value, char separator) {
  char text[4];
  const auto [end, ec] = std::to_chars(text, text + sizeof(text), static_cast<unsigned>(value));
  (void)ec;
  out.append(text, end);
  out += separator;
}

void writePly(const std::string& path, const std::vector<OccupancyMap::LeafBoxHost>& cells,
              const std::vector<Rgb>& colours, const std::string& comment) {
  std::ofstream out(path, std::ios_base::binary | std::ios_base::trunc);
  if (!out.is_open())
    throw Error(ErrorCode::kIo, "cannot write '" + path + "': " + std::strerror(errno));
  std::string text =
      "ply\n"
      "format ascii 1.0\n"
      "comment " +
      comment +
      "\n"
      "element vertex " +
      std::to_string(cells.size()) +
      "\n"
      "property float x\n"
      "property float y\n"
      "property float z\n"
      "property float size\n"
      "property float log_odds\n"
      "property uchar red\n"
      "property uchar green\n"
      "property uchar blue\n"
      "end_header\n";
  for (std::size_t i = 0; i < cells.size(); ++i) {
    const OccupancyMap::LeafBoxHost& c = cells[i];
    appendNumber(text, c.center[0], ' ');
    appendNumber(text, c.center[1], ' ');
    appendNumber(text, c.center[2], ' ');
    appendNumber(text, c.size, ' ');
    appendNumber(text, c.log_odds, ' ');
    appendByte(text, colours[i][0], ' ');
    appendByte(text, colours[i][1], ' ');
    appendByte(text, colours[i][2], '\n');
    if (text.size() > (1u << 20)) {
      out.write(text.data(), static_cast<std::streamsize>(text.size()));
      text.clear();
    }
  }
  out.write(text.data(), static_cast<std::streamsize>(text.size()));
  out.close();
  if (!out.good())
    throw Error(ErrorCode::kIo, "failed writing '" + path + "' (disk full or I/O error)");
}

}  // namespace

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

int runExport(const std::vector<std::string>& args) {
  if (printHelpIfAsked(args, printExportHelp)) return kExitOk;
  const ExportOptions o = parseExport(args);
  // Created now: an unwritable path is found before any work.
  OutputFiles output({o.output_path}, {o.map_path});

  std::unique_ptr<Context> context = createContext();
  const auto start = Clock::now();
  const OccupancyMap map = loadMap(*context, o.map_path, o.cap.max_device_bytes);
  const double read_s = secondsSince(start);

  const auto select_start = Clock::now();
  const double resolution = map.params().resolution;
  const float occupied_log_odds = occupancyLogOdds(map.params());
  std::vector<OccupancyMap::LeafBoxHost> cells;
  try {
    if (o.box) {
      const std::array<double, 6>& b = *o.box;
      cells = map.leavesInBox(clampToDomain(b[0], b[1], b[2], resolution),
                              clampToDomain(b[3], b[4], b[5], resolution), o.occupied_only);
    } else {
      cells = map.downloadLeafBoxes();
      if (o.occupied_only)
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
    if (o.coloring == Coloring::kOccupancy)
      colours[i] = is_occupied ? kOccupiedRed : kFreeGreen;
    else if (!is_occupied)
      colours[i] = kFreeGrey;
    else
      colours[i] =
          heightColor(z_max > z_min ? (cells[i].center[2] - z_min) / (z_max - z_min) : 0.5);
  }
  std::ostringstream comment;
  comment << "octovk export of " << o.map_path << " (resolution " << resolution
          << " m): leaf cells, centre x y z and edge size in metres, occupancy log-odds, colour by "
          << (o.coloring == Coloring::kHeight ? "height" : "occupancy");
  output.write(
      0, [&](const std::string& temporary) { writePly(temporary, cells, colours, comment.str()); });
  output.commit();
  const double write_s = secondsSince(write_start);

  std::ostringstream s;
  s << "device:  " << context->device().name << " (" << context->device().type << ")\n";
  s << "map:     " << o.map_path << "\n";
  if (o.box) {
    const std::array<double, 6>& b = *o.box;
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
  s << line << "wrote:   " << o.output_path << "\n";
  std::cout << s.str() << std::flush;
  return kExitOk;
}

}  // namespace octovk::cli
