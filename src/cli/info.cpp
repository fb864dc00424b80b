// octovk info: what a map file holds (tree type, resolution, nodes, leaves by state, bounds,
// colours or stamps, device memory), counted on the device from the map's leaf boxes.
#include <algorithm>
#include <filesystem>
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
         "Reads an OctoMap .bt or .ot file onto the Vulkan device and prints its tree type\n"
         "(OcTree, ColorOcTree or OcTreeStamped), resolution, nodes (inner ones included),\n"
         "leaves, occupied and free leaves (OctoMap's isNodeOccupied) with their volume, the\n"
         "bounds of all and of the occupied leaves, and the device memory it holds, with the\n"
         "device used and the time taken. A ColorOcTree: how many leaves have a colour (white is\n"
         "none); an OcTreeStamped .ot: its leaves' oldest and newest stamps, where MAP.ot.stamps\n"
         "(written by octovk beside it) holds them.\n"
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

// What the leaves' payload says (colour or stamp), from the downloaded tree: "" for none.
std::string payloadText(OccupancyMap& map, const std::string& path) {
  const Payload payload = map.params().payload;
  if (payload == Payload::kNone) return {};
  // readMapFile takes a stamped .ot's stamps from beside it; a .bt never has any.
  const bool is_ot = std::filesystem::path(path).extension() == ".ot";
  if (payload == Payload::kStamp && !is_ot) return "none stored (a .bt holds none: every stamp 0)";
  if (payload == Payload::kStamp && !std::filesystem::exists(path + ".stamps"))
    return "none stored (no " + path + ".stamps beside the map: every stamp 0)";
  HostTree tree;
  try {
    tree = map.download();
  } catch (const Error& e) {
    throw withOptionNames(e);
  }
  std::size_t leaves = 0, coloured = 0;
  std::uint32_t oldest = std::numeric_limits<std::uint32_t>::max(), newest = 0;
  // The leaves hanging from the root: nodes without children.
  std::vector<std::uint32_t> stack;
  if (tree.root_exists && !tree.nodes.empty()) stack.push_back(0);
  while (!stack.empty()) {
    const HostTree::Node& n = tree.nodes.at(stack.back());
    stack.pop_back();
    if (n.mask == 0) {
      ++leaves;
      coloured += n.payload != packRgb(octovk::Rgb{});
      oldest = std::min(oldest, n.payload);
      newest = std::max(newest, n.payload);
      continue;
    }
    for (std::uint32_t c = 0; c < 8; ++c)
      if (n.mask & (1u << c)) stack.push_back(n.children * 8 + c);
  }
  if (payload == Payload::kColor)
    return format("%zu of %zu leaves with a colour (the rest white: none)", coloured, leaves);
  if (leaves == 0) return "none (an empty map)";
  return format("leaves' oldest %u, newest %u (seconds, from %s.stamps)", oldest, newest,
                path.c_str());
}

int Info::run(Invocation& in) {
  Steps steps;
  OccupancyMap map = steps.run("reading and upload", [&] { return loadMap(in); });
  const LeafCounts c = steps.run("counting", [&] { return countLeaves(map); });
  const std::string payload =
      map.params().payload == Payload::kNone
          ? std::string()
          : steps.run("payload", [&] { return payloadText(map, in.input()); });

  const OccupancyMap::DeviceBytes bytes = map.deviceBytesByUse();
  const auto mib = [](std::size_t n) { return static_cast<double>(n) / (1024.0 * 1024.0); };
  Report report(17);
  report.device(in.context())
      .line("map", in.input())
      .line("tree type", treeTypeName(map.params().payload))
      .line("resolution", format("%g m", map.params().resolution))
      .line("nodes", std::to_string(c.nodes))
      .line("leaves", std::to_string(c.leaves))
      .line("occupied", format("%zu leaves, %.3f m^3", c.occupied, c.occupied_m3))
      .line("free", format("%zu leaves, %.3f m^3", c.leaves - c.occupied, c.free_m3))
      .line("bounds", describe(c.all))
      .line("occupied bounds", describe(c.occupied_bounds));
  if (!payload.empty())
    report.line(map.params().payload == Payload::kColor ? "colours" : "stamps", payload);
  return report
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
