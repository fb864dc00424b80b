// octovk_bench: OctoMap's insertPointCloud and octovk on the same scans, in one process.
// It measures and reports; it never asserts on time.
#include <octomap/OcTree.h>

#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <ctime>
#include <filesystem>
#include <fstream>
#include <iostream>
#include <sstream>
#include <string>
#include <thread>
#include <vector>

#include "building.hpp"
#include "json.hpp"
#include "octovk/octovk.hpp"
#include "workloads.hpp"

namespace {

namespace fs = std::filesystem;
using octovk::bench::BenchOptions;

const char* const kWorkloads[] = {"paper",   "scandat",  "fr079", "scaling",
                                  "queries", "distance", "edits", "payloads"};

struct Args {
  BenchOptions bench;
  std::vector<std::string> workloads;
  std::string json_path;
};

void printHelp(const char* data_dir) {
  std::printf(
      "octovk_bench [options]\n"
      "\n"
      "Runs OctoMap's OcTree::insertPointCloud and octovk's OccupancyMap::insertPointCloud on\n"
      "the same scans (identical float inputs) in this process, and reports per-scan times,\n"
      "their ratio, octovk's device time per stage (Vulkan timestamps), rays and cell updates\n"
      "per second, and the memory of both maps per node. It measures; it never fails on time.\n"
      "Tables go to stdout (Markdown), progress to stderr, everything to --json FILE.\n"
      "\n"
      "Workloads:\n"
      "  paper    a synthetic building (rooms, corridor, doors, furniture), six 320x240 = 76,800-\n"
      "           ray views from different poses, at 0.1, 0.05 and 0.02 m, depth 16\n"
      "  scandat  OctoMap's real 3D scan (scan.dat, 88,206 points), at 0.1 and 0.05 m\n"
      "  fr079    the 4,934-scan FR-079 sequence (.graph from clf2log.py + log2graph), placed as\n"
      "           graph2tree does, at 0.1 and 0.05 m; time per scan against map size\n"
      "  scaling  rays per scan 10K..1M and maximum range 2..30 m, one scan into fresh maps\n"
      "  queries  the paper map at 0.05 m in both systems, then point lookups (OcTree::search\n"
      "           against OccupancyMap::search, 1,000,000 random points in the building) and\n"
      "           castRay (against OccupancyMap::castRays, 100,000 random directions from the\n"
      "           six sensor poses, ignore_unknown off and on, max range 10 m and unlimited):\n"
      "           queries per second of both and every answer compared\n"
      "  distance DistanceField against dynamicEDT3D's DynamicEDTOctomap on the paper map at\n"
      "           0.05 m (the building's box): from scratch, the update after each view, and\n"
      "           --lookups points (default 100,000) of getDistanceAndClosestObstacle\n"
      "  edits    clearBox and keepBox on the paper map at 0.05 m against OctoMap's loops\n"
      "           (clear_bbx: leaf_bbx_iterator + updateInnerOccupancy; keep: a tree rebuilt\n"
      "           from leaf_bbx_iterator's leaves), four boxes, every result compared\n"
      "  payloads the first FR-079 scans (500; 100 with --quick; or --fr079-scans) at 0.1 and\n"
      "           0.05 m into OcTree, ColorOcTree (+ averageNodeColor per point) and\n"
      "           OcTreeStamped, and into OccupancyMap, ColorMap and StampedMap: time per scan\n"
      "\n"
      "Options:\n"
      "  --workload W        paper, scandat, fr079, scaling, queries, distance, edits, payloads\n"
      "                      or all;\n"
      "                      repeat or comma-separate to pick several (default: all)\n"
      "  --resolutions LIST  comma-separated resolutions in metres for paper, scandat and fr079\n"
      "                      (default: each workload's own, listed above)\n"
      "  --scaling-resolution M  resolution of the scaling runs (default: 0.05)\n"
      "  --repeat N          run each paper / scandat / scaling measurement N times into fresh\n"
      "                      maps, and each query batch N times, and report the median\n"
      "                      (default: 1)\n"
      "  --lookups N         points of the queries workload (default: 1,000,000; 100,000 with\n"
      "                      --quick)\n"
      "  --query-rays N      rays per castRay configuration of the queries workload (default:\n"
      "                      100,000; 2,000 with --quick)\n"
      "  --json FILE         write all results as JSON to FILE\n"
      "  --quick             a smoke run of about a minute: fewer resolutions, the first 600\n"
      "                      FR-079 scans, three scaling points each, a tenth of the queries\n"
      "  --scandat FILE      scan.dat, plain text (default: %s/scan.dat)\n"
      "  --fr079 FILE        FR-079 scan graph (default: %s/fr079.graph)\n"
      "  --fr079-scans N     use only the first N scans of FR-079 (default: all; 600 with "
      "--quick)\n"
      "  --no-compute-update do not time OcTree::computeUpdate on its own (saves about a third of\n"
      "                      OctoMap's time; the cell-set parity check is then skipped)\n"
      "  --lazy-leaf-boxes   octovk rebuilds the leaf boxes on demand, as the library does by\n"
      "                      default; without it the bench makes octovk rebuild them after every\n"
      "                      scan (OccupancyMap::setLeafBoxesEveryScan(true)), so that its times\n"
      "                      cover the whole pipeline, upload through leaf-box rebuild\n"
      "  -h, --help          this text\n"
      "\n"
      "bench/prepare_data.sh makes the data files; bench/run_all.sh builds, prepares the data,\n"
      "runs everything and draws the plot. OCTOVK_DEVICE picks the Vulkan device (index or name\n"
      "substring); OCTOVK_BENCH_DATA_DIR replaces the default data folder above.\n"
      "Exit status: 0 done, 1 failure (no device, missing data), 2 usage error.\n",
      data_dir, data_dir);
}

[[noreturn]] void usageError(const std::string& message) {
  std::fprintf(stderr, "octovk_bench: %s (see --help)\n", message.c_str());
  std::exit(2);
}

double parsePositive(const std::string& option, const std::string& text) {
  char* end = nullptr;
  const double v = std::strtod(text.c_str(), &end);
  if (text.empty() || *end != '\0' || !(v > 0) || v > 1e9)
    usageError(option + " wants a positive number, got '" + text + "'");
  return v;
}

std::vector<std::string> splitCommas(const std::string& text) {
  std::vector<std::string> out;
  std::stringstream s(text);
  std::string item;
  while (std::getline(s, item, ',')) out.push_back(item);
  return out;
}

// The data folder: $OCTOVK_BENCH_DATA_DIR when set (a bundle from scripts/bundle.sh, run from
// another folder, points at its own copy), else the one the build compiled in.
std::string dataDir() {
  const char* env = std::getenv("OCTOVK_BENCH_DATA_DIR");
  return env && *env ? std::string(env) : std::string(OCTOVK_BENCH_DATA_DIR);
}

Args parseArgs(int argc, char** argv) {
  Args a;
  const std::string data_dir = dataDir();
  a.bench.scandat_path = data_dir + "/scan.dat";
  a.bench.fr079_path = data_dir + "/fr079.graph";
  for (int i = 1; i < argc; ++i) {
    std::string name = argv[i], value;
    const bool has_inline = name.rfind("--", 0) == 0 && name.find('=') != std::string::npos;
    if (has_inline) {
      value = name.substr(name.find('=') + 1);
      name = name.substr(0, name.find('='));
    }
    const auto next = [&]() -> std::string {
      if (has_inline) return value;
      if (i + 1 >= argc) usageError(name + " needs a value");
      return argv[++i];
    };
    if (name == "-h" || name == "--help") {
      printHelp(data_dir.c_str());
      std::exit(0);
    } else if (name == "--workload") {
      for (const std::string& w : splitCommas(next())) {
        bool known = w == "all";
        for (const char* k : kWorkloads) known = known || w == k;
        if (!known)
          usageError(
              "unknown workload '" + w +
              "'; use paper, scandat, fr079, scaling, queries, distance, edits, payloads or all");
        if (w == "all")
          a.workloads.assign(std::begin(kWorkloads), std::end(kWorkloads));
        else
          a.workloads.push_back(w);
      }
    } else if (name == "--resolutions") {
      for (const std::string& r : splitCommas(next()))
        a.bench.resolutions.push_back(parsePositive(name, r));
    } else if (name == "--scaling-resolution") {
      a.bench.scaling_resolution = parsePositive(name, next());
    } else if (name == "--repeat") {
      a.bench.repeat = static_cast<int>(parsePositive(name, next()));
    } else if (name == "--lookups") {
      a.bench.lookups = static_cast<std::size_t>(parsePositive(name, next()));
    } else if (name == "--query-rays") {
      a.bench.query_rays = static_cast<std::size_t>(parsePositive(name, next()));
    } else if (name == "--json") {
      a.json_path = next();
    } else if (name == "--quick") {
      a.bench.quick = true;
    } else if (name == "--scandat") {
      a.bench.scandat_path = next();
    } else if (name == "--fr079") {
      a.bench.fr079_path = next();
    } else if (name == "--fr079-scans") {
      a.bench.fr079_scans = static_cast<std::size_t>(parsePositive(name, next()));
    } else if (name == "--no-compute-update") {
      a.bench.compute_update = false;
    } else if (name == "--lazy-leaf-boxes") {
      a.bench.leaf_boxes_every_scan = false;
    } else {
      usageError("unknown argument '" + name + "'");
    }
    if (has_inline &&
        (name == "--quick" || name == "--no-compute-update" || name == "--lazy-leaf-boxes"))
      usageError(name + " takes no value");
  }
  if (a.workloads.empty()) a.workloads.assign(std::begin(kWorkloads), std::end(kWorkloads));
  return a;
}

bool wants(const Args& a, const std::string& w) {
  for (const std::string& x : a.workloads)
    if (x == w) return true;
  return false;
}

std::string cpuModel() {
  std::ifstream in("/proc/cpuinfo");
  std::string line;
  while (std::getline(in, line))
    if (line.rfind("model name", 0) == 0) return line.substr(line.find(':') + 2);
  return "unknown";
}

std::string utcNow() {
  const std::time_t now = std::time(nullptr);
  char buf[32];
  std::strftime(buf, sizeof(buf), "%Y-%m-%d %H:%M UTC", std::gmtime(&now));
  return buf;
}

void checkFile(const std::string& path, const char* option) {
  if (!fs::is_regular_file(path)) {
    std::fprintf(stderr,
                 "octovk_bench: data file '%s' is missing: run bench/prepare_data.sh, or give "
                 "%s FILE, or leave that workload out with --workload\n",
                 path.c_str(), option);
    std::exit(1);
  }
}

// The first scan of a process builds the pipelines; keep that out of every measurement.
void warmUp(octovk::Context& context) {
  const octovk::bench::Building building;
  const auto view = octovk::bench::paperViews().front();
  const auto cloud = octovk::bench::rangeImage(building, view, 64, 48);
  octovk::MapParams params;
  octovk::OccupancyMap map(context, params);
  map.insertPointCloud(cloud, view.position.cast<float>());
  map.insertPointCloud(cloud, Eigen::Vector3f::Zero(), octovk::Pose{});
  map.nodeCount();
}

}  // namespace

int main(int argc, char** argv) {
  // A line at a time: a run stopped by a time limit (a lent GPU's 10 minutes) keeps every table
  // it finished, which a full buffer would lose.
  std::setvbuf(stdout, nullptr, _IOLBF, 0);
  const Args args = parseArgs(argc, argv);
  if (wants(args, "scandat")) checkFile(args.bench.scandat_path, "--scandat");
  if (wants(args, "fr079") || wants(args, "payloads")) checkFile(args.bench.fr079_path, "--fr079");

  auto context_result = octovk::Context::create();
  if (!context_result) {
    std::fprintf(stderr, "octovk_bench: %s\n", context_result.error().what());
    return 1;
  }
  octovk::Context& context = *context_result.value();
  const octovk::DeviceInfo& device = context.device();

  std::ostringstream command;
  command << "octovk_bench";
  for (int i = 1; i < argc; ++i) command << ' ' << argv[i];
  std::printf("# octovk_bench\n\n");
  std::printf("- command: `%s`\n", command.str().c_str());
  std::printf("- date: %s\n", utcNow().c_str());
  std::printf("- device: %s (%s, %.1f GiB)\n", device.name.c_str(), device.type.c_str(),
              static_cast<double>(device.memory_bytes) / (1u << 30));
  std::printf("- host CPU: %s, %u hardware threads\n", cpuModel().c_str(),
              std::thread::hardware_concurrency());
  std::printf("- OctoMap: liboctomap %s (single-threaded), lazy_eval off, discretize off\n",
              OCTOVK_BENCH_OCTOMAP_VERSION);
  std::printf("- octovk leaf boxes: %s\n",
              args.bench.leaf_boxes_every_scan
                  ? "rebuilt after every scan (setLeafBoxesEveryScan(true); "
                    "the library default is on demand)"
                  : "rebuilt on demand (--lazy-leaf-boxes, the library default)");
  std::fflush(stdout);

  std::ostringstream json_text;
  octovk::bench::JsonWriter json(json_text);
  json.beginObject();
  json.field("command", command.str()).field("date", utcNow());
  json.key("device")
      .beginObject()
      .field("name", device.name)
      .field("type", device.type)
      .field("memory_bytes", device.memory_bytes)
      .endObject();
  json.key("host")
      .beginObject()
      .field("cpu", cpuModel())
      .field("hardware_threads", std::thread::hardware_concurrency())
      .endObject();
  json.field("octomap_version", OCTOVK_BENCH_OCTOMAP_VERSION);
  json.field("repeat", args.bench.repeat).field("quick", args.bench.quick);
  json.field("leaf_boxes_every_scan", args.bench.leaf_boxes_every_scan);

  try {
    warmUp(context);
    if (wants(args, "paper")) octovk::bench::runPaper(context, args.bench, json);
    if (wants(args, "scandat")) octovk::bench::runScanDat(context, args.bench, json);
    if (wants(args, "fr079")) octovk::bench::runFr079(context, args.bench, json);
    if (wants(args, "scaling")) octovk::bench::runScaling(context, args.bench, json);
    if (wants(args, "queries")) octovk::bench::runQueries(context, args.bench, json);
    if (wants(args, "distance")) octovk::bench::runDistance(context, args.bench, json);
    if (wants(args, "edits")) octovk::bench::runEdits(context, args.bench, json);
    if (wants(args, "payloads")) octovk::bench::runPayloads(context, args.bench, json);
  } catch (const std::exception& e) {
    std::fprintf(stderr, "octovk_bench: %s\n", e.what());
    return 1;
  }
  json.endObject();

  if (!args.json_path.empty()) {
    std::ofstream out(args.json_path);
    out << json_text.str() << "\n";
    if (!out) {
      std::fprintf(stderr, "octovk_bench: cannot write '%s'\n", args.json_path.c_str());
      return 1;
    }
    std::fprintf(stderr, "wrote %s\n", args.json_path.c_str());
  }
  return 0;
}
