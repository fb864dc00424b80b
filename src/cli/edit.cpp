// octovk edit: map surgery on a map file, on the device, written as OctoMap writes it: clearing
// boxes as octomap_server's clear_bbx does (every leaf leaf_bbx_iterator visits set to the lower
// clamping bound, then updateInnerOccupancy) and keeping only a box (every node but the leaves
// leaf_bbx_iterator visits and the inner nodes above them deleted).
#include <Eigen/Core>
#include <algorithm>
#include <array>
#include <cstdio>
#include <filesystem>
#include <iostream>
#include <sstream>
#include <vector>

#include "command.hpp"
#include "octovk/octovk.hpp"

namespace octovk::cli {

namespace {

constexpr const char* kEditUsage =
    "octovk edit MAP.bt|MAP.ot --clear-box|--keep-box XMIN YMIN ZMIN XMAX YMAX ZMAX [...] "
    "-o OUT.bt|OUT.ot [--max-device-memory BYTES]";

void printEditHelp(std::ostream& out) {
  out << "octovk edit MAP.bt|MAP.ot --clear-box|--keep-box XMIN YMIN ZMIN XMAX YMAX ZMAX [...]\n"
         "            -o OUT.bt|OUT.ot\n"
         "\n"
         "Edits a map on the Vulkan device and writes it. --clear-box does what octomap_server's\n"
         "clear_bbx does: every leaf that OctoMap's leaf_bbx_iterator visits for the box (a\n"
         "pruned leaf reaching into it, whole) gets the lower clamping bound's log-odds, then\n"
         "the inner nodes are updated as updateInnerOccupancy does (no pruning). --keep-box\n"
         "keeps only a box: the leaves leaf_bbx_iterator visits for it (a pruned leaf reaching\n"
         "into it, whole) and the inner nodes above them, each the maximum of its children;\n"
         "every other node is deleted. A box reaching past the map's key range (each\n"
         "coordinate within 32767.5 cells of the origin) is clamped to it, as export --box does,\n"
         "so that a box larger than the map keeps or clears all of it; the summary shows the\n"
         "box used. The file is byte-identical to OctoMap doing the same with that box and\n"
         "writing it.\n"
         "\n"
         "Options:\n"
         "  -o, --output FILE      the map to write (.bt: max-likelihood, pruned, as OctoMap's\n"
         "                         writeBinary; .ot: full log-odds). Written to a temporary file\n"
         "                         beside it and renamed once complete. Required.\n"
         "      --clear-box XMIN YMIN ZMIN XMAX YMAX ZMAX\n"
         "                         a box in metres to clear (min <= max)\n"
         "      --keep-box XMIN YMIN ZMIN XMAX YMAX ZMAX\n"
         "                         a box in metres to keep (min <= max); everything outside it\n"
         "                         is deleted\n"
         "                         Both may be given several times, mixed; the edits are\n"
         "                         applied in the order given. At least one is required.\n";
  printMaxDeviceMemoryHelp(out, "The map");
  out << "  -h, --help             show this help\n"
         "Options take their value as '--name VALUE' or '--name=VALUE'; the boxes also as\n"
         "'--clear-box=XMIN,YMIN,ZMIN,XMAX,YMAX,ZMAX'.\n"
         "\n"
         "Output: the device used, then on stdout the edits made (for --clear-box the leaves set\n"
         "free, and how many of them were occupied), the nodes before and after\n"
         "in memory and in the file written (a .bt is max-likelihood and pruned, so it may hold\n"
         "fewer: the count 'octovk info' shows), the time taken and the file written.\n";
}

class Edit final : public Command {
 public:
  bool option(const ParsedOption& opt) override {
    const bool keep = opt.name == "--keep-box";
    if (!keep && opt.name != "--clear-box") return false;
    const std::vector<double> v = parseNumbers(opt, "-1 -1 0 1 1 2");
    for (int a = 0; a < 3; ++a)
      if (v[a] > v[a + 3])
        throw UsageError(opt.name + ": the minimum " + std::string(1, "xyz"[a]) + " (" +
                         opt.values[a] + ") is above the maximum (" + opt.values[a + 3] +
                         "); write " + opt.name + " XMIN YMIN ZMIN XMAX YMAX ZMAX");
    edits_.push_back({keep, {v[0], v[1], v[2], v[3], v[4], v[5]}, {}, false});
    return true;
  }

  void check(Invocation& in) override {
    checkMapInput(in.input(), kEditUsage);
    if (edits_.empty())
      throw UsageError(
          "edit: nothing to do; give --clear-box or --keep-box XMIN YMIN ZMIN XMAX YMAX ZMAX");
    in.checkDeviceMemoryCap();
    in.checkOutputs();
  }

  int run(Invocation& in) override {
    Context& context = in.context();
    const auto start = Clock::now();
    OccupancyMap map = loadMap(context, in.input(), in.maxDeviceBytes());
    const double read_s = secondsSince(start);
    const std::size_t nodes_before = map.nodeCount();
    const double resolution = map.params().resolution;
    const auto edit_start = Clock::now();
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
      if (e.keep)
        map.keepBox(lo, hi);
      else {
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
    const double edit_s = secondsSince(edit_start);
    const std::size_t nodes_after = map.nodeCount();
    const auto write_start = Clock::now();
    std::size_t nodes_written = 0;
    {
      StderrSilencer silenced;  // OctoMap's .bt writer reports on stderr
      in.files().write(
          0, [&](const std::string& temporary) { nodes_written = writeMap(map, temporary); });
      in.files().commit();
    }
    const double write_s = secondsSince(write_start);
    std::ostringstream s;
    s << "device:  " << context.device().name << " (" << context.device().type << ")\n";
    s << "map:     " << in.input() << "\n";
    for (const BoxEdit& e : edits_) {
      char line[512];
      std::snprintf(line, sizeof(line), "%s min (%g, %g, %g) max (%g, %g, %g) m",
                    e.keep ? "kept:   " : "cleared:", e.used[0], e.used[1], e.used[2], e.used[3],
                    e.used[4], e.used[5]);
      s << line;
      if (e.clamped) {
        std::snprintf(line, sizeof(line),
                      " (the box given, min (%g, %g, %g) max (%g, %g, %g), clamped to the "
                      "map's domain at resolution %g)",
                      e.box[0], e.box[1], e.box[2], e.box[3], e.box[4], e.box[5], resolution);
        s << line;
      }
      if (!e.keep)
        s << ": " << e.leaves << " leaves set free (" << e.occupied << " of them were occupied)";
      s << "\n";
    }
    // Edits do not prune the map in memory; a .bt is written pruned, so 'octovk info' counts
    // fewer nodes than the map held.
    const bool pruned = std::filesystem::path(in.output()).extension() == ".bt";
    s << "nodes:   " << nodes_before << " before, " << nodes_after << " after, in memory; "
      << nodes_written << " in " << in.output()
      << (pruned ? " (max-likelihood, pruned: as 'octovk info' counts)"
                 : " (as 'octovk info' counts)")
      << "\n";
    char line[256];
    std::snprintf(line, sizeof(line),
                  "time:    %.3f s (reading and upload %.3f s, editing %.3f s, writing %.3f s)\n",
                  read_s + edit_s + write_s, read_s, edit_s, write_s);
    s << line << "wrote:   " << in.output() << "\n";
    std::cout << s.str() << std::flush;
    return kExitOk;
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
};

}  // namespace

const Subcommand kEditCommand{
    .name = "edit",
    .print_help = printEditHelp,
    .input = "map file",
    .second_input_hint = "; the edited map goes after -o",
    .outputs = Subcommand::Outputs::kOne,
    .writes = "one map",
    .no_output = "no output file; add -o OUT.bt or -o OUT.ot",
    .output_extensions = {".bt", ".ot"},
    .output_formats = ".bt or .ot (OctoMap map)",
    .max_device_memory = true,
    .multi_value_options = {{"--clear-box", "XMIN YMIN ZMIN XMAX YMAX ZMAX"},
                            {"--keep-box", "XMIN YMIN ZMIN XMAX YMAX ZMAX"}},
    .make = []() -> std::unique_ptr<Command> { return std::make_unique<Edit>(); },
    .examples =
        "  octovk edit map.bt --clear-box 0 0 0 1 1 2 -o cleared.bt\n"
        "  octovk edit map.bt --keep-box -5 -5 -1 5 5 3 -o window.bt\n"};

}  // namespace octovk::cli
