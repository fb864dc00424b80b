// octovk info: what a map file holds (resolution, nodes, leaves by state, bounds, device memory),
// counted on the device from the map's leaf boxes.
#include <algorithm>
#include <iostream>
#include <limits>
#include <vector>

#include "command.hpp"
#include "octovk/octovk.hpp"
#include "report.hpp"

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
  return format("min (%.3f, %.3f, %.3f) max (%.3f, %.3f, %.3f) m, size %.3f x %.3f x %.3f m",
                b.min[0], b.min[1], b.min[2], b.max[0], b.max[1], b.max[2], b.max[0] - b.min[0],
                b.max[1] - b.min[1], b.max[2] - b.min[2]);
}

}  // namespace

void printInfoHelp(std::ostream& out) {
  out << kInfoUsage
      << "\n"
         "\n"
         "Reads an OctoMap .bt or .ot file onto the Vulkan device and prints its resolution,\n"
         "nodes (inner ones included), leaves, occupied and free leaves (OctoMap's\n"
         "isNodeOccupied) with their volume, the bounds of all and of the occupied leaves, and\n"
         "the device memory it holds, with the device used and the time taken.\n"
         "\n"
         "Options:\n";
  printMaxDeviceMemoryHelp(out, "A map");
  out << "  -h, --help             show this help\n";
}

namespace {

class Info final : public Command {
 public:
  void check(Invocation& in) override { in.checkMapCommand(kInfoUsage); }
  int run(Invocation& in) override;
};

// What the leaves hold, by state.
struct LeafCounts {
  std::size_t nodes = 0, leaves = 0, occupied = 0;
  double occupied_m3 = 0.0, free_m3 = 0.0;
  Bounds all, occupied_bounds;
};

LeafCounts countLeaves(OccupancyMap& map) {
  LeafCounts counts;
  std::vector<OccupancyMap::LeafBoxHost> leaves;
  try {
    counts.nodes = map.nodeCount();
    leaves = map.downloadLeafBoxes();
  } catch (const Error& e) {
    throw withOptionNames(e);
  }
  counts.leaves = leaves.size();
  const float occupied_log_odds = occupancyLogOdds(map.params());
  for (const OccupancyMap::LeafBoxHost& leaf : leaves) {
    const double volume = static_cast<double>(leaf.size) * leaf.size * leaf.size;
    counts.all.add(leaf);
    if (leaf.log_odds >= occupied_log_odds) {
      ++counts.occupied;
      counts.occupied_m3 += volume;
      counts.occupied_bounds.add(leaf);
    } else {
      counts.free_m3 += volume;
    }
  }
  return counts;
}

int Info::run(Invocation& in) {
  Steps steps;
  OccupancyMap map = steps.run(
      "reading and upload", [&] { return loadMap(in.context(), in.input(), in.maxDeviceBytes()); });
  const LeafCounts c = steps.run("counting", [&] { return countLeaves(map); });

  const OccupancyMap::DeviceBytes bytes = map.deviceBytesByUse();
  const auto mib = [](std::size_t n) { return static_cast<double>(n) / (1024.0 * 1024.0); };
  return Report(17)
      .device(in.context())
      .line("map", in.input())
      .line("resolution", format("%g m", map.params().resolution))
      .line("nodes", std::to_string(c.nodes))
      .line("leaves", std::to_string(c.leaves))
      .line("occupied", format("%zu leaves, %.3f m^3", c.occupied, c.occupied_m3))
      .line("free", format("%zu leaves, %.3f m^3", c.leaves - c.occupied, c.free_m3))
      .line("bounds", describe(c.all))
      .line("occupied bounds", describe(c.occupied_bounds))
      .line("device memory",
            format("%.1f MiB (node pool %.1f MiB, leaf boxes %.1f MiB, scan scratch %.1f MiB, "
                   "query buffers %.1f MiB)",
                   mib(bytes.total()), mib(bytes.pool), mib(bytes.leaf_boxes), mib(bytes.scratch),
                   mib(bytes.queries)))
      .finish(steps);
}

}  // namespace

std::unique_ptr<Command> makeInfo() { return std::make_unique<Info>(); }

}  // namespace octovk::cli
