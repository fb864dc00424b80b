// octovk info: what a map file holds (resolution, nodes, leaves by state, bounds, device memory),
// counted on the device from the map's leaf boxes.
#include <algorithm>
#include <cstdio>
#include <iostream>
#include <limits>
#include <sstream>

#include "command.hpp"
#include "octovk/octovk.hpp"

namespace octovk::cli {

namespace {

constexpr const char* kInfoUsage = "octovk info MAP.bt|MAP.ot [--max-device-memory BYTES]";

// Metric bounds of a set of leaves: the outer faces of their cells.
struct Bounds {
  double min[3] = {std::numeric_limits<double>::max(), std::numeric_limits<double>::max(),
                   std::numeric_limits<double>::max()};
  double max[3] = {std::numeric_limits<double>::lowest(), std::numeric_limits<double>::lowest(),
                   std::numeric_limits<double>::lowest()};
  bool empty = true;

  void add(const OccupancyMap::LeafBoxHost& leaf) {
    const double half = 0.5 * leaf.size;
    for (int a = 0; a < 3; ++a) {
      min[a] = std::min(min[a], leaf.center[a] - half);
      max[a] = std::max(max[a], leaf.center[a] + half);
    }
    empty = false;
  }
};

std::string describe(const Bounds& b) {
  if (b.empty) return "none";
  char text[256];
  std::snprintf(text, sizeof(text),
                "min (%.3f, %.3f, %.3f) max (%.3f, %.3f, %.3f) m, size %.3f x %.3f x %.3f m",
                b.min[0], b.min[1], b.min[2], b.max[0], b.max[1], b.max[2], b.max[0] - b.min[0],
                b.max[1] - b.min[1], b.max[2] - b.min[2]);
  return text;
}

void printInfoHelp(std::ostream& out) {
  out << kInfoUsage
      << "\n"
         "\n"
         "Reads an OctoMap .bt or .ot file onto the Vulkan device and prints what it holds:\n"
         "  resolution      edge of the smallest voxel\n"
         "  nodes           nodes of the tree, inner nodes included (OctoMap's size())\n"
         "  leaves          leaf nodes (pruned leaves count once, whatever their size)\n"
         "  occupied, free  leaves by state: occupied = log-odds at or above the occupancy\n"
         "                  threshold (probability 0.5, log-odds 0; OctoMap's isNodeOccupied),\n"
         "                  with the volume they cover\n"
         "  bounds          min and max corner of all leaf cells (centre -/+ half the edge)\n"
         "  occupied bounds the same for the occupied leaves only\n"
         "  device memory   bytes the map holds on the device, and of those the node\n"
         "                  pool, the leaf boxes, the scan scratch and the query buffers\n"
         "                  (scratch and queries are at an empty map's sizes: info runs\n"
         "                  no scan)\n"
         "and the device used and the time taken.\n"
         "\n"
         "Options:\n";
  printMaxDeviceMemoryHelp(out, "A map");
  out << "  -h, --help             show this help\n";
}

class Info final : public Command {
 public:
  void check(Invocation& in) override {
    checkMapInput(in.input(), kInfoUsage);
    in.checkDeviceMemoryCap();
  }
  int run(Invocation& in) override;
};

int Info::run(Invocation& in) {
  const std::string& map_path = in.input();
  Context& context = in.context();
  const auto start = Clock::now();
  OccupancyMap map = loadMap(context, map_path, in.maxDeviceBytes());
  const double read_s = secondsSince(start);

  const auto count_start = Clock::now();
  std::size_t nodes = 0;
  std::vector<OccupancyMap::LeafBoxHost> leaves;
  try {
    nodes = map.nodeCount();
    leaves = map.downloadLeafBoxes();
  } catch (const Error& e) {
    throw withOptionNames(e);
  }
  const float occupied_log_odds = occupancyLogOdds(map.params());
  std::size_t occupied = 0;
  double occupied_m3 = 0.0, free_m3 = 0.0;
  Bounds all, occupied_bounds;
  for (const OccupancyMap::LeafBoxHost& leaf : leaves) {
    const double volume = static_cast<double>(leaf.size) * leaf.size * leaf.size;
    all.add(leaf);
    if (leaf.log_odds >= occupied_log_odds) {
      ++occupied;
      occupied_m3 += volume;
      occupied_bounds.add(leaf);
    } else {
      free_m3 += volume;
    }
  }
  const double count_s = secondsSince(count_start);

  std::ostringstream s;
  char line[256];
  s << "device:          " << context.device().name << " (" << context.device().type << ")\n";
  s << "map:             " << map_path << "\n";
  std::snprintf(line, sizeof(line), "resolution:      %g m\n", map.params().resolution);
  s << line;
  s << "nodes:           " << nodes << "\n"
    << "leaves:          " << leaves.size() << "\n";
  std::snprintf(line, sizeof(line), "occupied:        %zu leaves, %.3f m^3\n", occupied,
                occupied_m3);
  s << line;
  std::snprintf(line, sizeof(line), "free:            %zu leaves, %.3f m^3\n",
                leaves.size() - occupied, free_m3);
  s << line;
  s << "bounds:          " << describe(all) << "\n"
    << "occupied bounds: " << describe(occupied_bounds) << "\n";
  const OccupancyMap::DeviceBytes bytes = map.deviceBytesByUse();
  constexpr double kMiB = 1024.0 * 1024.0;
  std::snprintf(line, sizeof(line),
                "device memory:   %.1f MiB (node pool %.1f MiB, leaf boxes %.1f MiB, scan "
                "scratch %.1f MiB, query buffers %.1f MiB)\n",
                static_cast<double>(bytes.total()) / kMiB, static_cast<double>(bytes.pool) / kMiB,
                static_cast<double>(bytes.leaf_boxes) / kMiB,
                static_cast<double>(bytes.scratch) / kMiB,
                static_cast<double>(bytes.queries) / kMiB);
  s << line;
  std::snprintf(line, sizeof(line),
                "time:            %.3f s (reading and upload %.3f s, counting %.3f s)\n",
                read_s + count_s, read_s, count_s);
  s << line;
  std::cout << s.str() << std::flush;
  return kExitOk;
}

}  // namespace

const Subcommand kInfoCommand{
    .name = "info",
    .print_help = printInfoHelp,
    .input = "map file",
    .max_device_memory = true,
    .unknown_option_tail = "",
    .make = []() -> std::unique_ptr<Command> { return std::make_unique<Info>(); },
    .examples =
        "  octovk info map.bt\n"
        "  octovk info map.ot --max-device-memory 512M\n"};

}  // namespace octovk::cli
