// octovk edit: map surgery on a map file, on the device, written as OctoMap writes it: clearing
// boxes as octomap_server's clear_bbx does (every leaf leaf_bbx_iterator visits set to the lower
// clamping bound, then updateInnerOccupancy) and keeping only a box (every node but the leaves
// leaf_bbx_iterator visits and the inner nodes above them deleted).
#include <Eigen/Core>
#include <algorithm>
#include <array>
#include <filesystem>
#include <fstream>
#include <iostream>
#include <optional>
#include <vector>

#include "command.hpp"
#include "octovk/octovk.hpp"
#include "report.hpp"

namespace octovk::cli {

namespace {

// Whether `path` is an OctoMap file of tree type OcTreeStamped (its header's `id` line), whose
// stamps octovk keeps beside a .ot.
bool isStampedTreeFile(const std::string& path) {
  std::ifstream in(path, std::ios_base::binary);
  std::string line;
  for (int i = 0; i < 16 && std::getline(in, line); ++i) {
    if (line.rfind("id ", 0) == 0) return line == "id OcTreeStamped";
    if (line == "data") break;
  }
  return false;
}

}  // namespace

namespace {

constexpr const char* kEditUsage =
    "octovk edit MAP.bt|MAP.ot --clear-box|--keep-box XMIN YMIN ZMIN XMAX YMAX ZMAX [...] "
    "-o OUT.bt|OUT.ot [--max-device-memory BYTES]";

}  // namespace

void printEditHelp(std::ostream& out) {
  out << "octovk edit MAP.bt|MAP.ot --clear-box|--keep-box XMIN YMIN ZMIN XMAX YMAX ZMAX [...]\n"
         "            -o OUT.bt|OUT.ot\n"
         "\n"
         "Edits a map on the Vulkan device and writes it, byte-identical to OctoMap doing the "
         "same:\n"
         "--clear-box sets the leaves in a box free, as octomap_server's clear_bbx does;\n"
         "--keep-box deletes everything outside a box. Boxes apply in the order given, each\n"
         "clamped to the map's key range; the summary shows the box used.\n"
         "\n"
         "Options:\n"
         "  -o, --output FILE      the map to write (.bt: max-likelihood, pruned; .ot: full\n"
         "                         log-odds). Required.\n"
         "      --clear-box XMIN YMIN ZMIN XMAX YMAX ZMAX\n"
         "                         a box in metres to clear (min <= max); repeatable\n"
         "      --keep-box XMIN YMIN ZMIN XMAX YMAX ZMAX\n"
         "                         a box in metres to keep (min <= max); repeatable. At least one\n"
         "                         box of either kind is required.\n";
  printMaxDeviceMemoryHelp(out, "The map");
  out << "  -h, --help             show this help\n"
         "Values: '--name VALUE' or '--name=VALUE' "
         "('--clear-box=XMIN,YMIN,ZMIN,XMAX,YMAX,ZMAX').\n";
}

namespace {

class Edit final : public Command {
 public:
  bool option(const ParsedOption& opt) override {
    const bool keep = opt.name == "--keep-box";
    if (!keep && opt.name != "--clear-box") return false;
    edits_.push_back({keep, parseBox(opt, "-1 -1 0 1 1 2"), {}, false});
    return true;
  }

  void check(Invocation& in) override {
    checkMapInput(in.input(), kEditUsage);
    if (edits_.empty())
      throw UsageError(
          "edit: nothing to do; give --clear-box or --keep-box XMIN YMIN ZMIN XMAX YMAX ZMAX");
    in.checkDeviceMemoryCap();
    in.checkOutputs();
    // A stamped map's .ot keeps its stamps beside it (PATH.stamps), renamed with it.
    if (isStampedTreeFile(in.input()) && std::filesystem::path(in.output()).extension() == ".ot")
      stamps_output_ = in.addOptionOutput(in.output() + ".stamps");
  }

  int run(Invocation& in) override {
    Steps steps;
    OccupancyMap map = steps.run("reading and upload", [&] { return loadMap(in); });
    const std::size_t nodes_before = map.nodeCount();
    steps.run("editing", [&] { applyEdits(map); });
    const std::size_t nodes_after = map.nodeCount();
    const std::size_t nodes_written = steps.run("writing", [&] {
      StderrSilencer silenced;  // OctoMap's .bt writer reports on stderr
      const std::size_t written = writeMapOutput(map, in.files(), 0, stamps_output_);
      in.files().commit();
      return written;
    });

    Report report(9);
    report.device(in.context()).line("map", in.input());
    for (const BoxEdit& e : edits_) report.line(e.keep ? "kept" : "cleared", editText(e, map));
    // Edits do not prune the map in memory; a .bt is written pruned, so 'octovk info' counts
    // fewer nodes than the map held.
    const bool pruned = std::filesystem::path(in.output()).extension() == ".bt";
    return report
        .line("nodes", std::to_string(nodes_before) + " before, " + std::to_string(nodes_after) +
                           " after, in memory; " + std::to_string(nodes_written) + " in " +
                           in.output() +
                           (pruned ? " (max-likelihood, pruned: as 'octovk info' counts)"
                                   : " (as 'octovk info' counts)"))
        .finish(steps, in.outputs());
  }

 private:
  struct BoxEdit {
    bool keep;                     // --keep-box; else --clear-box
    std::array<double, 6> box;     // as given
    std::array<double, 6> used{};  // clamped to the map's domain (run)
    bool clamped = false;
    std::size_t leaves = 0;    // --clear-box: the leaves it set free (run)
    std::size_t occupied = 0;  // of them, those that were occupied
  };
  std::vector<BoxEdit> edits_;
  std::optional<std::size_t> stamps_output_;  ///< a stamped .ot's PATH.stamps, by output index

  // Applies the edits in order, each box clamped to the map's domain (noted in its BoxEdit).
  void applyEdits(OccupancyMap& map) {
    const double resolution = map.params().resolution;
    for (BoxEdit& e : edits_) {
      // Clamped as export --box is: OctoMap's iterator visits nothing for a corner outside the
      // key range, which would silently delete the whole map for a generous --keep-box.
      const Eigen::Vector3f lo = clampToDomain(e.box[0], e.box[1], e.box[2], resolution);
      const Eigen::Vector3f hi = clampToDomain(e.box[3], e.box[4], e.box[5], resolution);
      for (int a = 0; a < 3; ++a) {
        e.used[a] = lo[a];
        e.used[a + 3] = hi[a];
        if (static_cast<float>(e.box[a]) != lo[a] || static_cast<float>(e.box[a + 3]) != hi[a])
          e.clamped = true;
      }
      if (e.keep) {
        map.keepBox(lo, hi);
        continue;
      }
      // Counted before: clearing keeps every leaf it visits, so afterwards none reads occupied.
      const std::vector<OccupancyMap::LeafBoxHost> leaves = map.leavesInBox(lo, hi);
      const float occupied = occupancyLogOdds(map.params());
      e.leaves = leaves.size();
      e.occupied = static_cast<std::size_t>(std::count_if(
          leaves.begin(), leaves.end(),
          [&](const OccupancyMap::LeafBoxHost& c) { return c.log_odds >= occupied; }));
      map.clearBox(lo, hi);
    }
  }

  // The report's words on one edit: the box used, the box given where it was clamped, and for
  // --clear-box the leaves it set free.
  static std::string editText(const BoxEdit& e, const OccupancyMap& map) {
    std::string text = boxText(e.used) + " m";
    if (e.clamped)
      text += " (the box given, " + boxText(e.box) +
              ", clamped to the map's domain at resolution " +
              format("%g", map.params().resolution) + ")";
    if (!e.keep)
      text += ": " + std::to_string(e.leaves) + " leaves set free (" + std::to_string(e.occupied) +
              " of them were occupied)";
    return text;
  }
};

}  // namespace

std::unique_ptr<Command> makeEdit() { return std::make_unique<Edit>(); }

}  // namespace octovk::cli
