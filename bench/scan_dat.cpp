// The scandat workload: OctoMap's real 3D laser scan (scan.dat), one scan into fresh maps.
#include <octomap/OcTree.h>

#include <cstdio>
#include <fstream>
#include <stdexcept>
#include <string>
#include <vector>

#include "measure.hpp"
#include "workload_common.hpp"
#include "workloads.hpp"

namespace octovk::bench {

namespace {

std::vector<Eigen::Vector3f> readXyz(const std::string& path) {
  std::ifstream in(path);
  if (!in)
    throw std::runtime_error("cannot read '" + path +
                             "'; make it with bench/prepare_data.sh or give --scandat FILE");
  std::vector<Eigen::Vector3f> points;
  float x, y, z;
  while (in >> x >> y >> z) points.emplace_back(x, y, z);
  if (!in.eof() || points.empty())
    throw std::runtime_error("'" + path + "' is not a list of 'x y z' lines");
  return points;
}

}  // namespace

void runScanDat(Context& context, const BenchOptions& o, JsonWriter& json) {
  const std::vector<double> resolutions = resolutionsFor(o, {0.1, 0.05}, {0.1});
  const std::vector<Eigen::Vector3f> points = readXyz(o.scandat_path);
  std::printf("\n## scandat: OctoMap's scan.dat, %zu points, sensor at the origin\n",
              points.size());
  std::printf("\nOne scan into fresh maps; times: median of %d run(s). Max range: unlimited.\n",
              o.repeat);
  json.key("scandat").beginObject().field("file", o.scandat_path).field("points", points.size());
  json.key("runs").beginArray();
  std::vector<ScanTiming> scans;
  std::vector<MemoryReport> memories;
  std::vector<std::string> labels;
  for (double res : resolutions) {
    MemoryReport memory;
    scans.push_back(repeatSequence(o.repeat, [&](int rep) {
                      progress("scandat %g m, run %d/%d\n", res, rep + 1, o.repeat);
                      octomap::OcTree tree(res);
                      OccupancyMap map = makeMap(context, o, res);
                      std::vector<ScanTiming> run{measureWorldScan(
                          tree, map, points, Eigen::Vector3f::Zero(), -1.0, o.compute_update)};
                      if (rep == 0) memory = memoryReport(tree, map);
                      return run;
                    }).front());
    memories.push_back(memory);
    labels.push_back(fmt("%g m", res));
    json.beginObject().field("resolution", res).key("scan");
    writeJson(json, scans.back());
    json.key("memory");
    writeJson(json, memory);
    json.endObject();
  }
  json.endArray().endObject();
  printScanTable("resolution", labels, scans);
  printStageTable("resolution (octovk device ms)", labels, scans);
  for (std::string& l : labels) l = "scan.dat, " + l;
  printMemoryTable(labels, memories);
  for (std::size_t i = 0; i < scans.size(); ++i)
    std::printf("\n%s: %s; cell sets %s.\n", labels[i].c_str(),
                parityLine(memories[i].om_nodes, memories[i].vk_nodes).c_str(),
                cellMismatches({scans[i]}) ? "DIFFER from OctoMap's" : "equal to OctoMap's");
}

}  // namespace octovk::bench
