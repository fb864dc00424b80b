// octovk integrate: every scan of an OctoMap scan graph, or every image of a TUM RGB-D folder, into
// one map, written as .bt / .ot files byte-identical to those of OctoMap's graph2tree on the same
// input (for a folder: on `octovk convert`'s graph of it) and parameters.
#include <fcntl.h>
#include <octomap/OcTree.h>
#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <charconv>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <iomanip>
#include <iostream>
#include <optional>
#include <sstream>

#include "command.hpp"
#include "octovk/octomap_io.hpp"
#include "octovk/octovk.hpp"
#include "octovk/store.hpp"
#include "octovk/tum_sequence.hpp"
#include "ply.hpp"
#include "png.hpp"
#include "report.hpp"
#include "store.hpp"

namespace octovk::cli {

namespace {

namespace fs = std::filesystem;

void checkInput(const std::string& path) {
  if (path.empty())
    throw UsageError(
        "no scan graph or folder given; usage: octovk integrate SCANS.graph|DIR -o MAP.bt");
  checkRegularInput(path, "scan graph",
                    "give an OctoMap scan graph (.graph) or a TUM RGB-D folder");
  // A map given for a graph would otherwise fail deep in the graph reader, with counts read
  // from its header text; OctoMap's files start with a header line, whatever their name.
  char head[32] = {};
  std::ifstream in(path, std::ios_base::binary);
  in.read(head, sizeof(head) - 1);
  const std::string start(head, static_cast<std::size_t>(in.gcount()));
  if (start.rfind("# Octomap OcTree", 0) == 0) {
    const char* kind = start.rfind("# Octomap OcTree binary file", 0) == 0 ? ".bt" : ".ot";
    throw UsageError("'" + path + "' is an OctoMap map (" + kind +
                     "), not a scan graph: integrate takes a .graph or a TUM RGB-D folder; to "
                     "look at the map use 'octovk info " +
                     path + "'");
  }
}

// validate() names MapParams fields; the user knows them as options.
std::string paramFix(const std::string& why) {
  const auto starts = [&](const char* field) { return why.rfind(field, 0) == 0; };
  std::string option = "--resolution, --prob-hit, --prob-miss, --clamping-min or --clamping-max";
  if (starts("resolution"))
    option = "--resolution";
  else if (starts("prob_hit"))
    option = "--prob-hit";
  else if (starts("prob_miss"))
    option = "--prob-miss";
  else if (starts("clamping"))
    option = "--clamping-min / --clamping-max";
  return "fix " + option + " (see 'octovk integrate --help')";
}

// Where scan `i` of the run comes from, to begin its errors: the graph and the scan's number
// (from 1), or the folder and the image's timestamp and name, as depth.txt lists them.
std::string scanPlace(const std::string& input, const std::optional<TumSequence>& tum,
                      std::size_t i, std::size_t count) {
  if (!tum) return input + ": scan " + std::to_string(i + 1) + " of " + std::to_string(count);
  const TumFrame& frame = tum->frames[i];
  char stamp[64];
  std::snprintf(stamp, sizeof(stamp), "%.6f", frame.timestamp);
  const std::string name = fs::path(frame.image_path).lexically_relative(fs::path(input)).string();
  return input + ": depth image " + stamp + " (" + (name.empty() ? frame.image_path : name) +
         ", depth.txt line " + std::to_string(frame.line) + ")";
}

// --degrade-after's value: whole seconds, as OcTreeStamped's stamps.
std::uint32_t parseSeconds(const ParsedOption& opt) {
  std::uint32_t value = 0;
  const char* end = opt.value.data() + opt.value.size();
  const auto [at, ec] = std::from_chars(opt.value.data(), end, value);
  if (opt.value.empty() || ec != std::errc() || at != end)
    throw UsageError(opt.name + " " + opt.value +
                     ": give whole seconds from 0 to 4294967295 (OcTreeStamped's stamps are whole "
                     "seconds); e.g. " +
                     opt.name + " 30");
  return value;
}

// --stamps FILE: one stamp a line, in whole seconds, exactly one per scan ('#' comment lines and
// blank lines skipped). Errors name the file and the line.
std::vector<std::uint32_t> readStamps(const std::string& path, std::size_t scans) {
  std::ifstream in(path, std::ios_base::binary);
  if (!in.is_open())
    throw Error(ErrorCode::kIo, "cannot read stamps file '" + path + "': " + std::strerror(errno));
  std::vector<std::uint32_t> stamps;
  std::size_t number = 0;
  for (std::string line; std::getline(in, line);) {
    ++number;
    if (!line.empty() && line.back() == '\r') line.pop_back();
    const std::size_t first = line.find_first_not_of(" \t");
    if (first == std::string::npos || line[first] == '#') continue;
    const std::string text = line.substr(first, line.find_last_not_of(" \t") + 1 - first);
    const std::string where = "stamps file '" + path + "' line " + std::to_string(number) + ": ";
    if (stamps.size() == scans)
      throw Error(ErrorCode::kFormat, where + "a stamp for scan " + std::to_string(scans + 1) +
                                          ", but the graph holds " + std::to_string(scans) +
                                          " scans; give one stamp per scan");
    std::uint32_t stamp = 0;
    const auto [end, ec] = std::from_chars(text.data(), text.data() + text.size(), stamp);
    if (ec != std::errc() || end != text.data() + text.size()) {
      const std::string shown = text.size() > 40 ? text.substr(0, 37) + "..." : text;
      throw Error(ErrorCode::kFormat,
                  where + "'" + shown +
                      "' is not a time stamp; give whole seconds from 0 to 4294967295, one a "
                      "line (OcTreeStamped's stamps)");
    }
    stamps.push_back(stamp);
  }
  if (in.bad())
    throw Error(ErrorCode::kIo, "cannot read stamps file '" + path + "': " + std::strerror(errno));
  if (stamps.size() != scans)
    throw Error(ErrorCode::kFormat,
                "stamps file '" + path + "' holds " + std::to_string(stamps.size()) +
                    " stamps (in " + std::to_string(number) + " lines) but the graph holds " +
                    std::to_string(scans) + " scans; give one stamp per scan, one a line");
  return stamps;
}

// --stamped: image `i`'s time stamp in whole seconds (its timestamp's floor), as OcTreeStamped
// holds time(NULL).
std::uint32_t imageStamp(const std::optional<TumSequence>& tum, std::size_t i) {
  const double t = std::floor(tum->frames[i].timestamp);
  if (!(t >= 0.0 && t <= 4294967295.0))
    throw Error(ErrorCode::kFormat,
                scanPlace(tum->dir, tum, i, tum->frames.size()) +
                    ": its time stamp is outside 0 to 4294967295 s, and --stamped gives each "
                    "image its time stamp in whole seconds (OcTreeStamped's unsigned stamps)");
  return static_cast<std::uint32_t>(t);
}

// --color: image `i`'s colour image has the depth image's size (`depth`), pixel for pixel.
void checkColorSize(const std::optional<TumSequence>& tum, std::size_t i,
                    const DepthPngSize& depth) {
  const TumFrame& frame = tum->frames[i];
  const DepthPngSize size = checkColorPng(frame.color_path);
  if (size.width != depth.width || size.height != depth.height)
    throw Error(ErrorCode::kFormat,
                scanPlace(tum->dir, tum, i, tum->frames.size()) + ": its colour image '" +
                    frame.color_path + "' (rgb.txt line " + std::to_string(frame.color_line) +
                    ") is " + std::to_string(size.width) + " x " + std::to_string(size.height) +
                    " pixels, the depth image " + std::to_string(depth.width) + " x " +
                    std::to_string(depth.height) +
                    "; --color needs colour images registered to the depth images, pixel for "
                    "pixel");
}

// Progress lines on stderr: on a terminal from the start, elsewhere only once the run has taken
// a second, so that short runs and test logs stay clean. At most one line per second or per 10%.
class Progress {
 public:
  Progress(std::size_t total, bool enabled)
      : total_(total), enabled_(enabled && total > 0), tty_(::isatty(STDERR_FILENO) == 1) {}

  void update(std::size_t done) {
    if (!enabled_) return;
    const double elapsed_s = secondsSince(start_);
    if (!tty_ && elapsed_s < 1.0) return;
    const std::size_t decile = done * 10 / total_;
    const double since_last_s = elapsed_s - last_s_;
    const bool closing = done == total_ && printed_;  // a started report ends at 100%
    if (!closing && since_last_s < 1.0 && (decile == last_decile_ || since_last_s < 0.2)) return;
    printed_ = true;
    last_s_ = elapsed_s;
    last_decile_ = decile;
    const double ms_per_scan = elapsed_s * 1e3 / static_cast<double>(done);
    const double eta_s = ms_per_scan * static_cast<double>(total_ - done) / 1e3;
    std::fprintf(stderr, "scan %zu/%zu (%zu%%), %.2f ms/scan, %.1f s left\n", done, total_,
                 done * 100 / total_, ms_per_scan, eta_s);
    std::fflush(stderr);
  }

 private:
  std::size_t total_;
  bool enabled_;
  bool tty_;
  Clock::time_point start_ = Clock::now();
  double last_s_ = 0.0;
  std::size_t last_decile_ = 0;
  bool printed_ = false;
};

const Rgb kCreatedBlue{60, 120, 220};
const Rgb kFlippedOrange{240, 140, 30};

// --changes: one vertex per changed key, sorted by key: its cell centre and OctoMap's flag.
void writeChanges(const std::string& path, std::vector<ChangedKey> changes, double resolution,
                  const std::string& input) {
  std::sort(changes.begin(), changes.end(),
            [](const ChangedKey& a, const ChangedKey& b) { return a.key < b.key; });
  std::ostringstream comment;
  comment << "octovk integrate of " << input << " (resolution " << resolution
          << " m): the keys changed over the whole run (OctoMap's change detection, on from the "
             "first scan, never reset), cell centre x y z in metres; created 1 = the leaf was "
             "created, 0 = an existing leaf's occupancy flipped; colour blue created, orange "
             "flipped";
  writeAsciiPly(
      path, comment.str(), changes.size(),
      {"float x", "float y", "float z", "uchar created", "uchar red", "uchar green", "uchar blue"},
      [&](std::string& text, std::size_t i) {
        const ChangedKey& c = changes[i];
        const Eigen::Vector3f centre = keyToCoord(resolution, c.key);
        for (int a = 0; a < 3; ++a) appendNumber(text, centre[a], ' ');
        const Rgb& colour = c.created ? kCreatedBlue : kFlippedOrange;
        appendByte(text, c.created ? 1 : 0, ' ');
        appendByte(text, colour[0], ' ');
        appendByte(text, colour[1], ' ');
        appendByte(text, colour[2], '\n');
      });
}

// Every output is written before any is renamed into place, so that a failed write (a full
// disk) leaves every existing file as it was. The maps are the -o outputs, in order; a stamped
// map's stamps files (`stamps_outputs`, one per map, MAP.ot.stamps) and the change set
// (`changes_output`, when there is one) follow them. Returns the nodes each map file holds.
std::vector<std::size_t> writeOutputs(OccupancyMap& map, Invocation& in,
                                      const std::vector<std::size_t>& stamps_outputs,
                                      const std::optional<std::size_t>& changes_output,
                                      const std::vector<ChangedKey>& changes) {
  OutputFiles& outputs = in.files();
  std::vector<std::size_t> nodes(in.outputs().size());
  {
    StderrSilencer silenced;  // OctoMap's .bt writer reports on stderr
    for (std::size_t i = 0; i < in.outputs().size(); ++i)
      nodes[i] = writeMapOutput(
          map, outputs, i,
          i < stamps_outputs.size() ? std::optional<std::size_t>(stamps_outputs[i]) : std::nullopt);
  }
  if (changes_output)
    outputs.write(*changes_output, [&](const std::string& temporary) {
      writeChanges(temporary, changes, map.params().resolution, in.input());
    });
  outputs.commit();
  return nodes;
}

// The nodes each map file holds, as 'octovk info' counts them: a .bt is written max-likelihood
// and pruned, so it may hold fewer than the map in memory.
std::string fileNodesText(const std::vector<std::string>& paths,
                          const std::vector<std::size_t>& nodes) {
  std::string text;
  for (std::size_t i = 0; i < paths.size(); ++i)
    text += (i == 0 ? "" : ", ") + paths[i] + " " + std::to_string(nodes[i]) +
            (fs::path(paths[i]).extension() == ".bt" ? " (max-likelihood, pruned)" : "");
  return text + ": as 'octovk info' counts them";
}

}  // namespace

void printIntegrateHelp(std::ostream& out) {
  const MapParams defaults;
  out << "octovk integrate SCANS.graph|DIR -o MAP.bt [-o MAP.ot] [options]\n"
         "\n"
         "Inserts every scan of an OctoMap scan graph (.graph), or depth image of a TUM RGB-D\n"
         "folder DIR, into one occupancy map on the Vulkan device and writes it byte-identical to\n"
         "graph2tree (-o X.bt its X.bt, -o X.ot its X.bt.ot; DIR: on 'octovk convert DIR').\n";
  printTumFolderHelp(out);
  out << "\n"
         "Options:\n"
         "  -o, --output FILE      file to write, repeatable, all or none: .bt max-likelihood, "
         ".ot full\n"
         "  -r, --resolution M     edge of the smallest voxel in metres (default: "
      << defaults.resolution
      << ")\n"
         "  -m, --max-range M      beams clear space only up to M metres; < 0 = unlimited "
         "(default: -1)\n"
         "      --prob-hit P       occupancy probability of a hit, in [0.5, 1) (default: "
      << defaults.prob_hit
      << ")\n"
         "      --prob-miss P      occupancy probability of a miss, in (0, 0.5] (default: "
      << defaults.prob_miss
      << ")\n"
         "      --clamping-min P   lower clamping bound of a voxel's probability (default: "
      << defaults.clamping_min
      << ")\n"
         "      --clamping-max P   upper clamping bound, above --clamping-min (default: "
      << defaults.clamping_max
      << ")\n"
         "      --discretize       one point per voxel before ray casting (default: off)\n"
         "      --rays walk|rt|rt-query|rt-pipeline  cell walk or ray tracing (default: walk)\n"
         "      --changes FILE.ply the run's changed keys as PLY: x y z, uchar created, "
         "red green blue\n"
         "  -q, --quiet            no progress on stderr (default: on a terminal, or after a "
         "second)\n"
         "      --color            DIR: a ColorOcTree (.ot only), each pixel coloured by rgb.txt\n"
         "      --stamps FILE      .graph: an OcTreeStamped (.ot only), scan i stamped "
         "with line i\n"
         "      --stamped          DIR: an OcTreeStamped (.ot only) with the images' seconds\n"
         "      --degrade-after S  before each stamped scan, occupied cells older than S s fade\n";
  out << "      --max-device-memory BYTES\n"
         "                         the map's device memory cap, K/M/G/T suffixes (512M, 2G), 0 = "
         "no cap\n"
         "                         (default). Scans run in parts; a map larger than the cap keeps "
         "cold\n"
         "                         tiles in a temp file (with --degrade-after it fails, naming the "
         "cap).\n"
         "                         Not with --rays rt (nor rt-query, rt-pipeline).\n";
  IntegrateStore::printHelp(out);
  printCameraOptionsHelp(out);
  out << "  -h, --help             show this help\n"
         "Values: '--name VALUE' or '--name=VALUE' ('--intrinsics=FX,FY,CX,CY').\n";
}

namespace {

class Integrate final : public Command {
 public:
  bool option(const ParsedOption& opt) override {
    if (store_->option(opt)) return true;  // --store, --map
    if (opt.name == "-r" || opt.name == "--resolution")
      params_.resolution = parseNumber(opt, "0.05");
    else if (opt.name == "-m" || opt.name == "--max-range")
      scan_.max_range_m = parseNumber(opt, "10 (metres; negative: unlimited)");
    else if (opt.name == "--prob-hit")
      params_.prob_hit = parseNumber(opt, "0.7");
    else if (opt.name == "--prob-miss")
      params_.prob_miss = parseNumber(opt, "0.4");
    else if (opt.name == "--clamping-min")
      params_.clamping_min = parseNumber(opt, "0.1192");
    else if (opt.name == "--clamping-max")
      params_.clamping_max = parseNumber(opt, "0.971");
    else if (opt.name == "--discretize")
      scan_.discretize = true;
    else if (opt.name == "--rays") {
      if (opt.value == "walk")
        params_.scan_rays = ScanRays::kWalk;
      else if (opt.value == "rt")
        params_.scan_rays = ScanRays::kRayTracing;
      else if (opt.value == "rt-query")
        params_.scan_rays = ScanRays::kRayQuery;
      else if (opt.value == "rt-pipeline")
        params_.scan_rays = ScanRays::kRayTracingPipeline;
      else
        throw UsageError("--rays " + opt.value +
                         ": use --rays walk (the compute walk), --rays rt (ray tracing), or "
                         "--rays rt-query / rt-pipeline (ray tracing through ray queries / a "
                         "ray-tracing pipeline)");
    } else if (opt.name == "-q" || opt.name == "--quiet")
      quiet_ = true;
    else if (opt.name == "--changes")
      changes_path_ = opt.value;
    else if (opt.name == "--color")
      color_ = true;
    else if (opt.name == "--stamps")
      stamps_path_ = opt.value;
    else if (opt.name == "--stamped")
      stamped_ = true;
    else if (opt.name == "--degrade-after")
      degrade_after_ = parseSeconds(opt);
    else if (parseCameraOption(opt, camera_)) {
      if (camera_option_.empty()) camera_option_ = opt.name;
    } else
      return false;
    return true;
  }

  void check(Invocation& in) override;
  int run(Invocation& in) override;

 private:
  // --color, --stamps, --stamped, --degrade-after: which input each takes, and the payload.
  void checkPayload(const Invocation& in);
  struct Sources;
  struct Totals;
  // The scans or images of the input, checked before any is inserted.
  Sources readSources(Invocation& in) const;
  // Inserts every scan into `map` (`stamped`: the same map, when it holds stamps); errors name
  // the scan that failed.
  Totals insert(OccupancyMap& map, StampedMap* stamped, const Sources& sources,
                const std::string& input) const;

  bool tum_ = false;           ///< the input is a TUM RGB-D folder, not a scan graph
  CameraIntrinsics camera_;    ///< --intrinsics, --depth-scale (TUM folders only)
  std::string camera_option_;  ///< the first of those given, for the error on a scan graph
  MapParams params_;
  ScanOptions scan_;  ///< --max-range, --discretize
  bool quiet_ = false;
  std::string changes_path_;                    ///< --changes
  std::optional<std::size_t> changes_output_;   ///< its index in the run's output files
  std::vector<std::size_t> stamps_outputs_;     ///< each -o map's stamps file, by index
  bool color_ = false;                          ///< --color: a ColorOcTree from rgb.txt
  std::string stamps_path_;                     ///< --stamps: a graph's scans' stamps
  bool stamped_ = false;                        ///< --stamped: a folder's images' own stamps
  std::optional<std::uint32_t> degrade_after_;  ///< --degrade-after
  std::unique_ptr<IntegrateStore> store_ = std::make_unique<IntegrateStore>();  ///< --store
};

void Integrate::check(Invocation& in) {
  const std::string& graph_path = in.input();
  params_.max_device_bytes = in.maxDeviceBytes();
  std::error_code ec;
  tum_ = !graph_path.empty() && fs::is_directory(graph_path, ec);
  if (tum_) {
    checkTumFolder(graph_path, "octovk integrate DIR -o MAP.bt");
  } else {
    checkInput(graph_path);
    if (!camera_option_.empty())
      throw UsageError(camera_option_ + " applies to a TUM RGB-D folder; scan graph '" +
                       graph_path + "' holds 3D points already: leave " + camera_option_ + " out");
  }
  checkPayload(in);
  if (!store_->enabled() || !in.outputs().empty()) in.checkOutputs();  // -o optional with --store
  // A stamped map's .ot holds no stamps (OctoMap writes none): they go beside it, written and
  // renamed with it, so that readMapFile finds the map's own.
  if (params_.payload == Payload::kStamp)
    for (const std::string& output : in.outputs())
      stamps_outputs_.push_back(in.addOptionOutput(output + ".stamps"));
  if (!changes_path_.empty()) {
    checkOutputFile(changes_path_, {".ply"}, ".ply (ASCII PLY point cloud) for --changes");
    changes_output_ = in.addOptionOutput(changes_path_);
  }
  checkDeviceMemoryCap(params_);
  if (params_.scan_rays != ScanRays::kWalk && params_.max_device_bytes != 0)
    throw UsageError(std::string("--rays rt cannot be capped by ") + kMaxDeviceMemoryOption +
                     ": its acceleration structures are not held under the cap; use --rays walk "
                     "or leave " +
                     kMaxDeviceMemoryOption + " out");
  const std::string why = params_.validate();
  if (!why.empty()) throw UsageError(why + "; " + paramFix(why));
}

void Integrate::checkPayload(const Invocation& in) {
  const std::string& input = in.input();
  if (color_ && (stamped_ || !stamps_path_.empty()))
    throw UsageError(std::string("a map holds colours or time stamps, not both (OctoMap's "
                                 "ColorOcTree or OcTreeStamped): give --color or ") +
                     (stamped_ ? "--stamped" : "--stamps") + ", not both");
  if (stamped_ && !stamps_path_.empty())
    throw UsageError("--stamped takes a folder's stamps and --stamps a scan graph's: give one");
  if (color_ && !tum_)
    throw UsageError(
        "--color takes the colours of a TUM RGB-D folder's rgb.txt images; scan "
        "graph '" +
        input + "' holds no colours: leave --color out");
  if (color_) {
    std::error_code ec;
    if (!fs::exists(fs::path(input) / "rgb.txt", ec))
      throw UsageError("folder '" + input +
                       "' has no rgb.txt, which --color reads ('timestamp filename' lines naming "
                       "8-bit colour PNGs registered to the depth images)");
  }
  if (stamped_ && !tum_)
    throw UsageError(
        "--stamped takes the time stamps of a TUM RGB-D folder's images; for scan "
        "graph '" +
        input + "' give --stamps FILE (one stamp per scan)");
  if (!stamps_path_.empty()) {
    if (tum_)
      throw UsageError("--stamps gives a scan graph's scans their stamps; TUM RGB-D folder '" +
                       input + "' has its own: use --stamped");
    checkRegularInput(stamps_path_, "stamps file",
                      "give a text file with one whole-second stamp per scan, one a line");
  }
  const bool stamps = stamped_ || !stamps_path_.empty();
  if (degrade_after_ && !stamps)
    throw UsageError(
        "--degrade-after needs the scans' time stamps: add --stamps FILE (a scan "
        "graph) or --stamped (a TUM RGB-D folder)");
  params_.payload = color_ ? Payload::kColor : stamps ? Payload::kStamp : Payload::kNone;
  if (params_.payload == Payload::kNone) return;
  // A .bt holds one occupancy bit pair per leaf: no colour or stamp, nor their tree type.
  for (const std::string& output : in.outputs())
    if (fs::path(output).extension() == ".bt")
      throw UsageError("'" + output + "': a .bt file holds occupancy only; " +
                       (color_     ? "--color"
                        : stamped_ ? "--stamped"
                                   : "--stamps") +
                       " makes a " + treeTypeName(params_.payload) + ": write it as -o MAP.ot");
}

// What a run reads: a scan graph's scans, or a TUM RGB-D folder's images (read one by one), and
// the scans' stamps (--stamps, --stamped).
struct Integrate::Sources {
  std::vector<GraphScan> scans;
  std::optional<TumSequence> tum;
  std::uint64_t max_pixels = 0;       // the device's largest depth image (TUM folders)
  std::vector<std::uint32_t> stamps;  // one per scan, or none
  std::size_t count() const { return tum ? tum->frames.size() : scans.size(); }
};

// The points the scans held, as ScanStats count them over the run.
struct Integrate::Totals {
  std::size_t points = 0, skipped_nonfinite = 0, skipped_outside = 0, pixels = 0, no_depth = 0;
  std::size_t split_scans = 0, most_groups = 1;  // scans applied in groups of tiles
  void add(const std::vector<ScanStats>& finished, bool tum) {
    for (ScanStats stats : finished) {
      if (stats.tile_groups > 1) {
        ++split_scans;
        most_groups = std::max(most_groups, stats.tile_groups);
      }
      if (tum) {
        pixels += stats.points;
        no_depth += stats.skipped_no_depth;
        stats.points -= stats.skipped_no_depth;
      }
      points += stats.points;
      skipped_nonfinite += stats.skipped_nonfinite;
      skipped_outside += stats.skipped_outside;
    }
  }
};

Integrate::Sources Integrate::readSources(Invocation& in) const {
  const std::string& graph_path = in.input();
  Sources sources;
  if (tum_) {
    sources.tum = readTumSequence(graph_path, kTumMaxTimeDifference,
                                  color_ ? TumColor::kRgbTxt : TumColor::kNone);
    // Every image's format before any work, rather than after minutes of it; then, with the
    // device, the largest image's size from its header, before any image is decoded.
    std::uint64_t largest = 0;
    const TumFrame* largest_frame = nullptr;
    for (std::size_t i = 0; i < sources.tum->frames.size(); ++i) {
      const TumFrame& frame = sources.tum->frames[i];
      const DepthPngSize size = checkDepthPng(frame.image_path);
      if (std::uint64_t{size.width} * size.height > largest) {
        largest = std::uint64_t{size.width} * size.height;
        largest_frame = &frame;
      }
      if (color_) checkColorSize(sources.tum, i, size);
      if (stamped_) sources.stamps.push_back(imageStamp(sources.tum, i));
    }
    sources.max_pixels = maxDepthImagePixels(in.context());
    if (largest_frame) checkDepthPng(largest_frame->image_path, sources.max_pixels);
    return sources;
  }
  sources.scans = readScanGraph(graph_path);
  // An empty map written with exit 0 looks like success; it is almost always a wrong file.
  if (sources.scans.empty())
    throw Error(ErrorCode::kInvalidArgument,
                "scan graph '" + graph_path +
                    "' holds no scans: there is nothing to integrate and no map was written; "
                    "give a graph with scans (OctoMap's log2graph writes one)");
  if (std::none_of(sources.scans.begin(), sources.scans.end(),
                   [](const GraphScan& scan) { return !scan.points_sensor.empty(); }))
    throw Error(ErrorCode::kInvalidArgument,
                "scan graph '" + graph_path + "' holds " + std::to_string(sources.scans.size()) +
                    " scan(s) but no points: there is nothing to integrate and no map was "
                    "written; give a graph whose scans hold points");
  if (!stamps_path_.empty()) sources.stamps = readStamps(stamps_path_, sources.scans.size());
  return sources;
}

Integrate::Totals Integrate::insert(OccupancyMap& map, StampedMap* stamped, const Sources& sources,
                                    const std::string& input) const {
  const std::size_t scan_count = sources.count();
  const bool tum = sources.tum.has_value();
  Progress progress(scan_count, !quiet_);
  // Scans are submitted back to back (the next one is read and staged while the device runs
  // the last ones); their statistics are gathered as they come in.
  Totals totals;
  // Errors say which scan failed: the one being submitted, or (Error::scan()) one submitted
  // earlier whose failure a synchronisation found. Tickets count the submissions from the first.
  std::size_t at = 0;
  ScanTicket first_ticket = 0;
  try {
    for (; at < scan_count; ++at) {
      const auto submitScan = [&]() -> ScanTicket {
        ScanOptions options = scan_;
        if (!sources.stamps.empty()) {
          options.stamp = sources.stamps[at];
          // What has not been seen for longer than the threshold fades before the scan, at its
          // time.
          if (stamped && degrade_after_) stamped->degradeOutdated(options.stamp, *degrade_after_);
        }
        if (tum) {
          // As graph2tree on convert's graph: the camera-frame points, cast from the pose's
          // position.
          const TumFrame& frame = sources.tum->frames[at];
          const DepthPng png = readDepthPng(frame.image_path, sources.max_pixels);
          ColorPng colour;
          if (color_) {
            colour = readColorPng(frame.color_path, sources.max_pixels);
            if (colour.width != png.width || colour.height != png.height)
              throw Error(ErrorCode::kFormat, "its colour image '" + frame.color_path +
                                                  "' is no longer the depth image's size");
            options.colors = colour.colors;  // one a pixel; copied by the submission
          }
          return map.submitDepthImage(png.image(camera_), frame.T_world_camera, options,
                                      graph2treeSensorOrigin(frame.T_world_camera));
        }
        const GraphScan& scan = sources.scans[at];
        return map.submitPointCloud(scan.points_sensor, graph2treeSensorOrigin(scan.T_world_sensor),
                                    scan.T_world_sensor, options);
      };
      const ScanTicket ticket = submitScan();
      if (at == 0) first_ticket = ticket;
      try {
        store_->finish();  // --store: the last scan's commit, which ran while this one was read
      } catch (const Error& e) {
        throw Error(e.code(), e.what(), ticket - 1);  // placed at that scan
      }
      // --store: the map's write lock, taken while the scan runs (the last commit ends first);
      // when other writers committed meanwhile the map is theirs, reloaded, and the scan goes in
      // again (its first statistics dropped, its ticket not counted).
      if (store_->begin(map)) {
        std::vector<ScanStats> stats = map.takeScanStats();
        if (!stats.empty()) stats.pop_back();
        totals.add(std::move(stats), tum);
        submitScan();
        ++first_ticket;
      }
      store_->commit(map, input, at);  // --store: waits for the scan, commits it
      if (at % 256 == 255) totals.add(map.takeScanStats(), tum);
      progress.update(at + 1);
    }
    map.flush();
    store_->finish();  // --store: the last scan's commit
    totals.add(map.takeScanStats(), tum);
  } catch (const Error& e) {
    store_->abandon();  // --store: a commit still running ends here, before the map does
    const std::size_t failed = e.scan() >= first_ticket && e.scan() != 0
                                   ? static_cast<std::size_t>(e.scan() - first_ticket)
                                   : at;
    std::string message = withOptionNames(e).what();
    // The library's note on which scans the map still holds, in its tickets: the place says
    // which scan, and a failed run writes no map.
    if (const std::size_t note = message.rfind(" [scan " + std::to_string(e.scan()) + " ");
        e.scan() != 0 && note != std::string::npos)
      message.erase(note);
    if (failed >= scan_count) throw Error(e.code(), input + ": " + message, e.scan());
    throw Error(e.code(), scanPlace(input, sources.tum, failed, scan_count) + ": " + message,
                e.scan());
  }
  return totals;
}

int Integrate::run(Invocation& in) {
  const auto run_start = Clock::now();
  const Sources sources = readSources(in);
  // Once, before the work: the progress lines that follow on stderr are the device's.
  Context& context = in.context();
  std::cout << "device: " << context.device().name << " (" << context.device().type << ")"
            << std::endl;

  store_->open(params_);  // --store: an existing map's parameters
  // params_.payload says what the nodes hold; a stamped map is taken over for degradeOutdated.
  OccupancyMap plain(context, params_);
  std::optional<StampedMap> stamped;
  if (params_.payload == Payload::kStamp) stamped.emplace(std::move(plain));
  OccupancyMap& map = stamped ? *stamped : plain;
  store_->load(map);
  // Under a cap, a map larger than the device keeps its coldest tiles in a temporary SQLite file
  // (a degrade reads the whole tree on the device). A store's commit takes an evicted tile as
  // committed, or brings the subtree of one that left mid-scan (TileWorkingSet::takeDirty).
  if (params_.max_device_bytes != 0 && !degrade_after_) map.spillTilesTo(sqliteTileSpill());
  if (changes_output_) map.enableChangeDetection(true);  // from the first scan, never reset
  const auto insert_start = Clock::now();
  const Totals totals = insert(map, stamped ? &*stamped : nullptr, sources, in.input());
  const double insert_s = secondsSince(insert_start);
  const std::size_t nodes = map.nodeCount();
  const std::size_t spilled = map.spilledTiles();
  const OccupancyMap::SpillCounts spill = map.spillCounts();
  const std::size_t device_bytes = map.deviceBytes();
  const std::size_t pool_bytes = map.poolBytes();
  std::vector<ChangedKey> changes;
  if (changes_output_) changes = map.changedKeys();
  const bool writes = !in.outputs().empty() || changes_output_;  // none with --store alone
  const std::vector<std::size_t> file_nodes =
      writes ? writeOutputs(map, in, stamps_outputs_, changes_output_, changes)
             : std::vector<std::size_t>{};
  const double total_s = secondsSince(run_start);

  const std::size_t scans = sources.count();
  const auto mib = [](std::size_t n) { return static_cast<double>(n) / (1024.0 * 1024.0); };
  Report report(15);
  if (sources.tum)
    report.line("images", tumImagesText(*sources.tum))
        .line("pixels", format("%zu (%zu without depth, skipped)", totals.pixels, totals.no_depth));
  report.line("scans", std::to_string(scans))
      .line("points", format("%zu (%zu skipped: %zu non-finite, %zu outside the map)",
                             totals.points, totals.skipped_nonfinite + totals.skipped_outside,
                             totals.skipped_nonfinite, totals.skipped_outside))
      .line("insert time",
            format("%.3f s, %.3f ms/scan (run total %.3f s, with reading and writing)", insert_s,
                   scans == 0 ? 0.0 : insert_s * 1e3 / static_cast<double>(scans), total_s))
      .line("nodes", std::to_string(nodes) + " in memory (graph2tree's 'Tree size')")
      .line("file nodes", writes ? fileNodesText(in.outputs(), file_nodes) : "no file (-o)")
      .line("device memory",
            format("%.1f MiB (node pool %.1f MiB; the rest is scan scratch and leaf boxes)",
                   mib(device_bytes), mib(pool_bytes)));
  if (spill.round_trips > 0)
    report.line("spilled",
                format("%zu tiles (16^3 cells) in a temporary file on the host at the end: the map "
                       "outgrew the device memory cap (%zu round trips of the node pool loaded %zu "
                       "tiles and evicted %zu)",
                       spilled, spill.round_trips, spill.loaded, spill.evicted));
  if (totals.split_scans > 0)
    report.line("in parts",
                format("%zu of the scans applied in groups of tiles (up to %zu parts), each part "
                       "walking every ray: their cells did not fit the device memory at once",
                       totals.split_scans, totals.most_groups));
  if (color_)
    report.line("colour",
                format("ColorOcTree: each depth pixel coloured by rgb.txt's image nearest in time "
                       "(%zu listed, less than %g s away)",
                       sources.tum->color_images, kTumMaxTimeDifference));
  if (!sources.stamps.empty()) {
    const auto [low, high] = std::minmax_element(sources.stamps.begin(), sources.stamps.end());
    report.line("stamps", format("OcTreeStamped: %u to %u s, ", *low, *high) +
                              (stamped_ ? "the images' time stamps in whole seconds"
                                        : "from " + stamps_path_ + ", one per scan") +
                              "; kept in MAP.ot.stamps (a .ot holds none)");
    if (degrade_after_)
      report.line("degraded", format("before each scan, occupied cells older than %u s at its "
                                     "stamp took a miss (degradeOutdatedNodes)",
                                     *degrade_after_));
  }
  if (changes_output_) {
    const auto created = static_cast<std::size_t>(std::count_if(
        changes.begin(), changes.end(), [](const ChangedKey& c) { return c.created; }));
    report.line("changes", format("%zu keys (%zu created, %zu flipped)", changes.size(), created,
                                  changes.size() - created));
  }
  store_->report(report);
  report.wrote(in.outputs());
  for (const std::string& output : in.outputs())
    if (!stamps_outputs_.empty()) report.wrote(output + ".stamps");
  if (changes_output_) report.wrote(changes_path_);
  return report.print();
}

}  // namespace

std::unique_ptr<Command> makeIntegrate() { return std::make_unique<Integrate>(); }

std::vector<std::string> integrateValueOptions() {
  std::vector<std::string> names = {"-r",
                                    "--resolution",
                                    "-m",
                                    "--max-range",
                                    "--prob-hit",
                                    "--prob-miss",
                                    "--clamping-min",
                                    "--clamping-max",
                                    "--rays",
                                    "--changes",
                                    "--stamps",
                                    "--degrade-after",
                                    "--store",
                                    "--map"};
  for (const std::string& name : cameraValueOptions()) names.push_back(name);
  return names;
}

std::size_t writeMapOutput(OccupancyMap& map, OutputFiles& outputs, std::size_t index,
                           std::optional<std::size_t> stamps_index) {
  std::size_t nodes = 0;
  std::string written;
  try {
    outputs.write(index, [&](const std::string& temporary) {
      written = temporary;
      nodes = writeMap(map, temporary);
    });
    // writeMapFile puts a stamped map's stamps beside the file it writes (its PATH.stamps):
    // beside the map's temporary, whence they move into their own output's.
    if (stamps_index)
      outputs.write(*stamps_index, [&](const std::string& temporary) {
        std::error_code ec;
        fs::rename(written + ".stamps", temporary, ec);
        if (ec) throw Error(ErrorCode::kIo, "cannot write '" + temporary + "': " + ec.message());
      });
  } catch (...) {
    std::error_code ec;
    if (!written.empty()) fs::remove(written + ".stamps", ec);
    throw;
  }
  return nodes;
}

// The map as OctoMap writes it, straight into `path` (the output's temporary): writeMapFile
// would add a temporary of its own, which a killed run would leave behind.
std::size_t writeMap(OccupancyMap& map, const std::string& path) {
  // A ColorOcTree or OcTreeStamped map: OctoMap's tree of the map's payload, through the library
  // (it writes a temporary of its own beside `path` and renames it).
  if (map.params().payload != Payload::kNone) {
    writeMapFile(map, path);
    return map.nodeCount();
  }
  std::unique_ptr<octomap::OcTree> tree = toOcTree(map);  // a fresh one: writeBinary prunes it
  std::ofstream out(path, std::ios_base::binary | std::ios_base::trunc);
  if (!out.is_open())
    throw Error(ErrorCode::kIo, "cannot write '" + path + "': " + std::strerror(errno));
  bool ok = fs::path(path).extension() == ".bt" ? tree->writeBinary(out) : tree->write(out);
  out.close();
  ok = ok && out.good();
  if (!ok) throw Error(ErrorCode::kIo, "failed writing '" + path + "' (disk full or I/O error)");
  return tree->size();
}

}  // namespace octovk::cli
