// The scaling workload: octovk and OctoMap as the rays per scan and the maximum range grow.
#include <octomap/OcTree.h>

#include <cstdio>
#include <string>
#include <vector>

#include "building.hpp"
#include "measure.hpp"
#include "workload_common.hpp"
#include "workloads.hpp"

namespace octovk::bench {

void runScaling(Context& context, const BenchOptions& o, JsonWriter& json) {
  const double res = o.scaling_resolution;
  const Building building;
  const std::vector<SensorPose> views = paperViews();
  const SensorPose& room_view = views[1];      // rays mostly 2-8 m long
  const SensorPose& corridor_view = views[0];  // rays up to 39 m down the corridor
  const std::vector<std::size_t> ray_counts =
      o.quick ? std::vector<std::size_t>{10'000, 30'000, 100'000}
              : std::vector<std::size_t>{10'000, 30'000, 76'800, 100'000, 300'000, 1'000'000};
  const std::vector<double> ranges =
      o.quick ? std::vector<double>{2, 5, 10} : std::vector<double>{2, 5, 10, 15, 20, 30};

  const auto measureOne = [&](const std::vector<Eigen::Vector3f>& cloud, const SensorPose& pose,
                              double max_range) {
    return repeatSequence(
               o.repeat,
               [&](int) {
                 octomap::OcTree tree(res);
                 OccupancyMap map = makeMap(context, o, res);
                 return std::vector<ScanTiming>{measureWorldScan(
                     tree, map, cloud, pose.position.cast<float>(), max_range, o.compute_update)};
               })
        .front();
  };

  std::printf("\n## scaling, resolution %g m: one scan into fresh maps, median of %d run(s)\n", res,
              o.repeat);
  json.key("scaling").beginObject().field("resolution", res).field("repeat", o.repeat);

  std::vector<ScanTiming> by_rays;
  std::vector<std::string> labels;
  json.key("rays").beginObject().field("view", room_view.name).key("points").beginArray();
  for (std::size_t rays : ray_counts) {
    std::size_t w, h;
    imageSizeFor(rays, &w, &h);
    if (rays == kPaperWidth * kPaperHeight) w = kPaperWidth, h = kPaperHeight;
    progress("scaling %g m: %zux%zu rays\n", res, w, h);
    const std::vector<Eigen::Vector3f> cloud = rangeImage(building, room_view, w, h);
    by_rays.push_back(measureOne(cloud, room_view, -1.0));
    labels.push_back(std::to_string(w) + "x" + std::to_string(h));
    json.newline().beginObject().field("width", w).field("height", h).key("scan");
    writeJson(json, by_rays.back());
    json.endObject();
  }
  json.endArray().endObject();
  std::printf("\n### scaling with rays per scan (view '%s', unlimited range)\n",
              room_view.name.c_str());
  printScanTable("image", labels, by_rays);
  printStageTable("image (octovk device ms)", labels, by_rays);

  std::vector<ScanTiming> by_range;
  labels.clear();
  const std::vector<Eigen::Vector3f> corridor =
      rangeImage(building, corridor_view, kPaperWidth, kPaperHeight);
  json.key("max_range").beginObject().field("view", corridor_view.name).key("points").beginArray();
  for (double range : ranges) {
    progress("scaling %g m: max range %g m\n", res, range);
    by_range.push_back(measureOne(corridor, corridor_view, range));
    labels.push_back(fmt("%g m", range));
    json.newline().beginObject().field("max_range_m", range).key("scan");
    writeJson(json, by_range.back());
    json.endObject();
  }
  json.endArray().endObject().endObject();
  std::printf("\n### scaling with maximum range (view '%s', %zux%zu rays)\n",
              corridor_view.name.c_str(), kPaperWidth, kPaperHeight);
  printScanTable("max range", labels, by_range);
  printStageTable("max range (octovk device ms)", labels, by_range);
}

}  // namespace octovk::bench
