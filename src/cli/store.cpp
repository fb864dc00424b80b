// octovk store export|follow|log|info, and integrate's --store / --map: a map kept as tiles in a
// store (src/store, docs/store.md), committed scan by scan. Reading a store needs no Vulkan device.
#include "store.hpp"

#include <octomap/OcTree.h>

#include <algorithm>
#include <cerrno>
#include <cmath>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <iostream>

#include "command.hpp"
#include "io/parse.hpp"
#include "octovk/store.hpp"
#include "store/store.hpp"

namespace octovk::cli {

namespace {

namespace fs = std::filesystem;

constexpr const char* kDefaultMap = "default";

void checkStoreInput(const std::string& path, const std::string& usage) {
  if (path.empty()) throw UsageError("no store given; usage: " + usage);
  if (store::isPostgresLocation(path)) return;  // a server's, not a file
  checkRegularInput(path, "store", "give the SQLite file 'octovk integrate ... --store' wrote");
}

std::string mib(std::uint64_t bytes) {
  return format("%.2f MiB", static_cast<double>(bytes) / (1024.0 * 1024.0));
}

// ---- store export ----

void printStoreExportHelp(std::ostream& out) {
  out << "octovk store export STORE [--map NAME] -o OUT.bt|OUT.ot\n"
         "\n"
         "Writes a map of a store as OctoMap writes the same tree: .bt max-likelihood and\n"
         "pruned, .ot full log-odds (byte-identical to graph2tree on the committed scans); a\n"
         "ColorOcTree or OcTreeStamped map as that type, a stamped map's stamps in OUT.ot.stamps.\n"
         "Reads the last committed scan; a writer may go on meanwhile. No Vulkan device needed.\n"
         "\n"
         "Options:\n"
         "  -o, --output FILE      the map file, .bt or .ot. Required.\n"
         "      --map NAME         which map of the store (default: default)\n"
         "  -h, --help             show this help\n";
}

// The files a store command writes `tree` (of `payload`) into: `out`, and beside a stamped map's
// .ot its stamps (OUT.stamps, as writeMapFile writes them: OctoMap's .ot holds none).
std::unique_ptr<OutputFiles> outputsFor(const std::string& out, const std::string& input,
                                        Payload payload) {
  std::vector<std::string> paths{out};
  if (payload == Payload::kStamp && fs::path(out).extension() == ".ot")
    paths.push_back(out + ".stamps");
  return std::make_unique<OutputFiles>(paths, std::vector<std::string>{input});
}

// Writes `tree` as OctoMap writes a tree of its type (by output 0's extension: .bt or .ot), a
// stamped tree's stamps into output 1 when there is one, and renames them into place; the node
// count written.
std::size_t writeTree(OutputFiles& files, const HostTree& tree, const MapParams& params) {
  const std::string& path = files.path(0);
  std::size_t nodes = 0;
  {
    StderrSilencer silenced;  // OctoMap's .bt writer reports on stderr
    files.write(0, [&](const std::string& temporary) {
      const std::unique_ptr<octomap::AbstractOccupancyOcTree> ot = io::octomapTreeOf(tree, params);
      std::ofstream out(temporary, std::ios_base::binary | std::ios_base::trunc);
      if (!out.is_open())
        throw Error(ErrorCode::kIo, "cannot write '" + path + "': " + std::strerror(errno));
      bool ok = fs::path(path).extension() == ".bt" ? ot->writeBinary(out) : ot->write(out);
      out.close();
      if (!ok || !out.good())
        throw Error(ErrorCode::kIo, "failed writing '" + path + "' (disk full or I/O error)");
      nodes = ot->size();
    });
  }
  if (files.size() > 1)
    files.write(1, [&](const std::string& temporary) {
      const std::string bytes = io::stampsFile(tree);
      std::ofstream out(temporary, std::ios_base::binary | std::ios_base::trunc);
      out.write(bytes.data(), static_cast<std::streamsize>(bytes.size()));
      out.close();
      if (!out.good())
        throw Error(ErrorCode::kIo,
                    "failed writing '" + files.path(1) + "' (disk full or I/O error)");
    });
  files.commit();
  return nodes;
}

// A store command that reads one map of the store: --map NAME (default: default).
class StoreMapCommand : public Command {
 public:
  bool option(const ParsedOption& opt) override {
    if (opt.name != "--map") return false;
    map_ = opt.value;
    return true;
  }

 protected:
  std::string map_ = kDefaultMap;
};

class StoreExport final : public StoreMapCommand {
 public:
  void check(Invocation& in) override {
    checkStoreInput(in.input(), "octovk store export STORE -o OUT.bt");
    in.checkOutputs();
  }
  int run(Invocation& in) override {
    const auto store = store::Store::open(in.input(), /*create=*/false);
    const store::MapInfo info = store::requireMap(*store, map_);
    const HostTree tree = store::loadTree(*store, map_);
    const std::unique_ptr<OutputFiles> files =
        outputsFor(in.output(), in.input(), info.params.payload);
    const std::size_t nodes = writeTree(*files, tree, info.params);
    Report report(10);
    report
        .line("map", map_ + format(" (resolution %g m), %llu scans", info.params.resolution,
                                   static_cast<unsigned long long>(info.scans)))
        .line("nodes", std::to_string(nodes) + " in the file")
        .wrote(in.output());
    return report.print();
  }
};

// ---- store follow ----

void printStoreFollowHelp(std::ostream& out) {
  out << "octovk store follow STORE [--map NAME] -o OUT.bt|OUT.ot [--until-seq N]\n"
         "\n"
         "Keeps a local copy of a map of a store current while writers commit scans to it. At\n"
         "each look it reads the keys of the map's tiles and the bodies of only the tiles\n"
         "written since its last look, rebuilds the tree and replaces OUT as 'store export'\n"
         "writes it (a whole new file renamed into place: a reader never sees a partial one).\n"
         "One line per update on standard output:\n"
         "  seq SEQ: T tiles read (B bytes), D dropped; N nodes in OUT\n"
         "A PostgreSQL store tells it of each commit at once (LISTEN/NOTIFY); an SQLite one is\n"
         "looked at every --interval. It runs until interrupted (Ctrl-C or SIGTERM; OUT stays\n"
         "as last written) or, with --until-seq, until scan N of the map is committed and\n"
         "written. No Vulkan device.\n"
         "\n"
         "Options:\n"
         "  -o, --output FILE      the map file, .bt or .ot. Required.\n"
         "      --map NAME         which map of the store (default: default)\n"
         "      --until-seq N      end once the map's committed scans reach N (see 'store log')\n"
         "      --interval S       seconds between looks at an SQLite store, and at most between\n"
         "                         looks at a PostgreSQL one (default: 0.5)\n"
         "  -h, --help             show this help\n";
}

class StoreFollow final : public StoreMapCommand {
 public:
  bool option(const ParsedOption& opt) override {
    if (opt.name == "--until-seq") {
      const double n = parseNumber(opt, "--until-seq 120");
      if (n < 1 || n != std::floor(n) || n > 9e15)
        throw UsageError("--until-seq " + opt.value +
                         ": give a scan's sequence number, a whole number from 1 ('octovk store "
                         "log' lists them)");
      until_seq_ = static_cast<std::uint64_t>(n);
      return true;
    }
    if (opt.name == "--interval") {
      interval_s_ = parseNumber(opt, "--interval 0.5");
      if (!(interval_s_ >= 0.001 && interval_s_ <= 3600))
        throw UsageError("--interval " + opt.value + ": give seconds from 0.001 to 3600");
      return true;
    }
    return StoreMapCommand::option(opt);
  }
  void check(Invocation& in) override {
    checkStoreInput(in.input(), "octovk store follow STORE -o OUT.ot");
    in.checkOutputs();
  }
  int run(Invocation& in) override {
    StoreFollower follower(in.input(), map_);
    for (;;) {
      if (const std::optional<StoreFollower::Update> update = follower.poll()) {
        // Each update through a fresh set of the outputs (a stamped .ot's stamps beside it).
        const std::size_t nodes =
            writeTree(*outputsFor(in.output(), in.input(), follower.params().payload),
                      follower.tree(), follower.params());
        std::cout << "seq " << update->seq << ": " << update->changed.size() << " tiles read ("
                  << update->bytes_read << " bytes), " << update->dropped.size() << " dropped; "
                  << nodes << " nodes in " << in.output() << std::endl;
        if (!std::cout)
          throw Error(ErrorCode::kIo,
                      std::string("cannot write to standard output: ") + std::strerror(errno));
      }
      const std::uint64_t seq = follower.seq();
      if (until_seq_ != 0 && seq >= until_seq_) return kExitOk;
      (void)follower.wait(interval_s_);  // a PostgreSQL store wakes it at a commit
    }
  }

 private:
  std::uint64_t until_seq_ = 0;
  double interval_s_ = 0.5;
};

// ---- store log ----

void printStoreLogHelp(std::ostream& out) {
  out << "octovk store log STORE [--map NAME]\n"
         "\n"
         "Prints the committed scans of a map, one line each, in commit order:\n"
         "  SEQ SOURCE SCAN\n"
         "SEQ counts the map's commits from 1, SOURCE is the input as integrate was given it, "
         "SCAN\n"
         "the scan's 0-based index in it.\n"
         "\n"
         "Options:\n"
         "      --map NAME         which map of the store (default: default)\n"
         "  -h, --help             show this help\n";
}

class StoreLog final : public StoreMapCommand {
 public:
  void check(Invocation& in) override {
    checkStoreInput(in.input(), "octovk store log STORE [--map NAME]");
  }
  int run(Invocation& in) override {
    const auto store = store::Store::open(in.input(), /*create=*/false);
    for (const store::LogEntry& e : store->log(map_))
      std::cout << e.seq << ' ' << e.source << ' ' << e.scan << '\n';
    if (!flushStdout())
      throw Error(ErrorCode::kIo,
                  std::string("cannot write the log to standard output: ") + std::strerror(errno));
    return kExitOk;
  }
};

// ---- store info ----

void printStoreInfoHelp(std::ostream& out) {
  out << "octovk store info STORE\n"
         "\n"
         "Prints each map of a store: its tree type (OcTree, ColorOcTree, OcTreeStamped), its\n"
         "resolution and sensor model, the scans committed, and its tiles (count, bytes, depth).\n"
         "\n"
         "Options:\n"
         "  -h, --help             show this help\n";
}

class StoreInfo final : public Command {
 public:
  void check(Invocation& in) override { checkStoreInput(in.input(), "octovk store info STORE"); }
  int run(Invocation& in) override {
    const auto store = store::Store::open(in.input(), /*create=*/false);
    const std::vector<store::MapInfo> maps = store->maps();
    Report report(10);
    report.line("store", store->location() +
                             format(" (%s), %zu map(s)",
                                    store::isPostgresLocation(in.input()) ? "PostgreSQL" : "SQLite",
                                    maps.size()));
    for (const store::MapInfo& m : maps) {
      const MapParams& p = m.params;
      report.line("map", m.name)
          .line("  tree type", treeTypeName(p.payload))
          .line("  params", format("resolution %g m, prob hit %g miss %g, clamping %g..%g, "
                                   "occupancy threshold %g",
                                   p.resolution, p.prob_hit, p.prob_miss, p.clamping_min,
                                   p.clamping_max, p.occupancy_threshold))
          .line("  scans",
                format("%llu committed (last seq %llu)", static_cast<unsigned long long>(m.scans),
                       static_cast<unsigned long long>(m.last_seq)))
          .line("  tiles", format("%llu, %s of node records, depth %u",
                                  static_cast<unsigned long long>(m.tiles),
                                  mib(m.tile_bytes).c_str(), m.tile_depth));
    }
    return report.print();
  }
};

// The actions, each run by the common driver as a command of its own.
const Subcommand kActions[] = {
    {.name = "store export",
     .summary = "a map of a store as a .bt / .ot file",
     .print_help = printStoreExportHelp,
     .input = "store",
     .second_input_hint = "; the map file goes after -o",
     .outputs = Subcommand::Outputs::kOne,
     .writes = "one map",
     .no_output = "no output file; add -o OUT.bt or -o OUT.ot",
     .output_extensions = {".bt", ".ot"},
     .output_formats = ".bt or .ot (OctoMap map)",
     .value_options = {"--map"},
     .make = [] { return std::unique_ptr<Command>(new StoreExport); },
     .examples = "  octovk store export map.sqlite -o map.bt\n"
                 "  octovk store export map.sqlite --map lab -o lab.ot\n"},
    {.name = "store follow",
     .summary = "keep a local .bt / .ot copy of a map current, tile by tile",
     .print_help = printStoreFollowHelp,
     .input = "store",
     .second_input_hint = "; the map file goes after -o",
     .outputs = Subcommand::Outputs::kOne,
     .writes = "one map",
     .no_output = "no output file; add -o OUT.bt or -o OUT.ot",
     .output_extensions = {".bt", ".ot"},
     .output_formats = ".bt or .ot (OctoMap map)",
     .value_options = {"--map", "--until-seq", "--interval"},
     .make = [] { return std::unique_ptr<Command>(new StoreFollow); },
     .examples = "  octovk store follow map.sqlite -o live.ot\n"
                 "  octovk store follow postgresql:///fleet --map lab -o lab.bt --interval 2\n"},
    {.name = "store log",
     .summary = "the committed scans of a map: SEQ SOURCE SCAN",
     .print_help = printStoreLogHelp,
     .input = "store",
     .value_options = {"--map"},
     .make = [] { return std::unique_ptr<Command>(new StoreLog); },
     .examples = "  octovk store log map.sqlite\n"
                 "  octovk store log map.sqlite --map lab | tail -1\n"},
    {.name = "store info",
     .summary = "the maps of a store: parameters, scans, tiles",
     .print_help = printStoreInfoHelp,
     .input = "store",
     .make = [] { return std::unique_ptr<Command>(new StoreInfo); },
     .examples = "  octovk store info map.sqlite\n"},
};

}  // namespace

void printStoreHelp(std::ostream& out) {
  out << "octovk store export|follow|log|info STORE [options]\n"
         "\n"
         "A store keeps maps as tiles in an SQLite file or a PostgreSQL database, written scan\n"
         "by scan by 'octovk integrate INPUT --store STORE'; each scan commits its changed tiles\n"
         "and its log row together, so a killed run loses no committed scan. See docs/store.md.\n"
         "\n"
         "Actions:\n";
  for (const Subcommand& action : kActions) {
    std::string name = std::string(action.name).substr(6);
    name.resize(9, ' ');
    out << "  " << name << action.summary << "\n";
  }
  out << "\n'octovk store ACTION --help' gives an action's options.\n";
}

int runStoreActions(const std::vector<std::string>& args) {
  if (args.empty())
    throw UsageError(
        "no action given; usage: octovk store export|follow|log|info STORE (see "
        "'octovk store --help')");
  const std::string& action = args.front();
  if (action == "-h" || action == "--help" || action == "help") {
    printStoreHelp(std::cout);
    std::cout << "\nExamples:\n";
    for (const Subcommand& s : kActions) std::cout << s.examples;
    std::cout << "\n";
    printEnvironmentPointer(std::cout);
    std::cout << "Details: docs/store.md.\n";
    return kExitOk;
  }
  for (const Subcommand& s : kActions)
    if (action == std::string(s.name).substr(6))
      return runSubcommand(s, std::vector<std::string>(args.begin() + 1, args.end()));
  throw UsageError("unknown store action '" + action +
                   "'; actions: export, follow, log, info (see 'octovk store --help')");
}

// ---- integrate --store ----

IntegrateStore::IntegrateStore() = default;
IntegrateStore::~IntegrateStore() = default;

bool IntegrateStore::option(const ParsedOption& opt) {
  if (opt.name == "--store") {
    if (opt.value.empty()) throw UsageError("--store needs a file: --store map.sqlite");
    path_ = opt.value;
    return true;
  }
  if (opt.name == "--map") {
    if (opt.value.empty()) throw UsageError("--map needs a name: --map lab");
    map_name_ = opt.value;
    return true;
  }
  for (const char* name :
       {"-r", "--resolution", "--prob-hit", "--prob-miss", "--clamping-min", "--clamping-max"})
    if (opt.name == name) sensor_options_.push_back(opt.name);
  return false;
}

void IntegrateStore::open(MapParams& params) {
  if (!enabled()) return;
  store_ = store::Store::open(path_, /*create=*/true);
  writer_ = std::make_unique<store::MapWriter>(*store_, map_name_, params);
  existed_ = writer_->existed();
  if (!existed_) return;
  const MapParams& stored = writer_->info().params;
  if (stored.payload != params.payload)
    throw UsageError(format(
        "map '%s' of store '%s' is %s, and this run makes %s; %s, or name another map (--map)",
        map_name_.c_str(), store_->location().c_str(), treeTypeName(stored.payload),
        treeTypeName(params.payload),
        stored.payload == Payload::kColor   ? "give --color as when it was made"
        : stored.payload == Payload::kStamp ? "give --stamps (or --stamped) as when it was made"
                                            : "leave out --color and --stamps"));
  const auto refuse = [&](const char* option, double given, double kept) {
    if (given == kept) return;
    for (const std::string& name : sensor_options_)
      if (name == option || (std::string(option) == "--resolution" && name == "-r"))
        throw UsageError(
            format("%s %g: map '%s' of store '%s' has %s %g; give that or leave "
                   "%s out (a map keeps its parameters)",
                   option, given, map_name_.c_str(), store_->location().c_str(), option + 2, kept,
                   option));
  };
  refuse("--resolution", params.resolution, stored.resolution);
  refuse("--prob-hit", params.prob_hit, stored.prob_hit);
  refuse("--prob-miss", params.prob_miss, stored.prob_miss);
  refuse("--clamping-min", params.clamping_min, stored.clamping_min);
  refuse("--clamping-max", params.clamping_max, stored.clamping_max);
  params.resolution = stored.resolution;
  params.prob_hit = stored.prob_hit;
  params.prob_miss = stored.prob_miss;
  params.clamping_min = stored.clamping_min;
  params.clamping_max = stored.clamping_max;
  params.occupancy_threshold = stored.occupancy_threshold;
}

void IntegrateStore::load(OccupancyMap& map) {
  if (!writer_) return;
  const HostTree tree = writer_->load();
  if (tree.root_exists) map.upload(tree);
}

bool IntegrateStore::begin(OccupancyMap& map) { return writer_ && writer_->begin(map); }

void IntegrateStore::abandon() noexcept {
  if (writer_) writer_->abandon();
}

void IntegrateStore::finish() {
  if (writer_) writer_->finish();
}

void IntegrateStore::commit(OccupancyMap& map, const std::string& source, std::size_t scan) {
  if (writer_) writer_->commitInBackground(map, source, scan);
}

void IntegrateStore::report(Report& report) const {
  if (!writer_) return;
  const store::CommitStats& t = writer_->totals();
  const std::size_t scans = t.seq;
  const double per_scan = scans == 0 ? 0.0 : 1.0 / static_cast<double>(scans);
  const std::size_t reloads = writer_->reloads();
  report
      .line("store",
            format(
                "%s, map '%s' (%s): %zu scans committed%s", store_->location().c_str(),
                map_name_.c_str(), existed_ ? "continued" : "created", scans,
                reloads == 0
                    ? ""
                    : format(", the map reloaded %zu times after other writers' "
                             "scans (%.1f ms each)",
                             reloads, writer_->reloadSeconds() * 1e3 / static_cast<double>(reloads))
                          .c_str()))
      .line("store writes",
            format("%zu tiles, %zu bytes of tiles (%.0f bytes and %.1f tiles per scan, at most "
                   "%zu bytes)",
                   t.tiles_written, t.body_bytes, static_cast<double>(t.body_bytes) * per_scan,
                   static_cast<double>(t.tiles_written) * per_scan, writer_->maxBodyBytes()))
      .line("store time",
            format("%.3f ms/scan finding the changed tiles (%.1f tiles a scan compared), %.3f "
                   "ms/scan committing them (each scan's while the next one runs on the device)",
                   t.find_s * 1e3 * per_scan, static_cast<double>(t.tiles_compared) * per_scan,
                   t.write_s * 1e3 * per_scan));
}

void IntegrateStore::printHelp(std::ostream& out) {
  out << "      --store FILE       keep the map in a store too, scan by scan (--map NAME: which)\n";
}

}  // namespace octovk::cli
