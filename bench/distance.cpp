// The distance workload: octovk's DistanceField against dynamicEDT3D's DynamicEDTOctomap on the
// paper map at 0.05 m (the building's box): from scratch, the update after each further view,
// and 100,000 point queries, every answer compared (squared distances in cells, capped as
// dynamicEDT3D caps them).
#include "octovk/distance.hpp"

#include <dynamicEDT3D/dynamicEDTOctomap.h>
#include <octomap/OcTree.h>

#include <algorithm>
#include <chrono>
#include <cstdio>
#include <memory>
#include <vector>

#include "building.hpp"
#include "measure.hpp"
#include "workload_common.hpp"
#include "workloads.hpp"

namespace octovk::bench {

namespace {

constexpr double kResolution = 0.05;
constexpr float kMaxDistance = 2.0f;

double msSince(Clock::time_point start) {
  return std::chrono::duration<double, std::milli>(Clock::now() - start).count();
}

}  // namespace

void runDistance(Context& context, const BenchOptions& o, JsonWriter& json) {
  const std::size_t query_count = o.lookups ? o.lookups : 100'000;
  const Building building;
  const std::vector<SensorPose> views = paperViews();
  const Box bounds = building.bounds();
  const Eigen::Vector3f lo = bounds.lo.cast<float>(), hi = bounds.hi.cast<float>();

  octomap::OcTree tree(kResolution);
  MapParams params;
  params.resolution = kResolution;
  OccupancyMap map(context, params);
  std::unique_ptr<DynamicEDTOctomap> edt;
  std::unique_ptr<DistanceField> field;
  std::printf("\n## distance: DistanceField against DynamicEDTOctomap on the paper map at %g m\n",
              kResolution);
  std::printf(
      "\nBox: the building's bounds (%.2f..%.2f, %.2f..%.2f, %.2f..%.2f m), max distance %g m. "
      "After view 1 both are built from scratch (dynamicEDT3D: constructor + update(); octovk: "
      "the DistanceField constructor); after each further view dynamicEDT3D's incremental "
      "update() and octovk's update() (incremental: the obstacles re-read from the tree or from "
      "the change set, which the first update() turns on, and only the lines whose input "
      "changed redone). Wall times of the calls; octovk's device time in brackets.\n\n",
      lo.x(), hi.x(), lo.y(), hi.y(), lo.z(), hi.z(), kMaxDistance);
  std::printf(
      "| view | dynamicEDT3D ms | octovk ms (device) | octovk update | speed-up |\n"
      "|---|---|---|---|---|\n");
  json.key("distance").beginObject();
  json.key("views").beginArray();
  for (std::size_t i = 0; i < views.size(); ++i) {
    std::fprintf(stderr, "distance: view %zu/%zu\n", i + 1, views.size());
    const std::vector<Eigen::Vector3f> cloud = rangeImage(building, views[i], 320, 240);
    measureWorldScan(tree, map, cloud, views[i].position.cast<float>(), -1.0, false);
    auto t0 = Clock::now();
    if (!edt) {
      edt = std::make_unique<DynamicEDTOctomap>(kMaxDistance, &tree,
                                                octomap::point3d(lo.x(), lo.y(), lo.z()),
                                                octomap::point3d(hi.x(), hi.y(), hi.z()), false);
    }
    edt->update();
    const double edt_ms = msSince(t0);
    t0 = Clock::now();
    if (!field)
      field = std::make_unique<DistanceField>(
          map, lo, hi,
          DistanceFieldOptions{.max_distance_m = kMaxDistance, .treat_unknown_as_occupied = false});
    else
      field->update();
    const double vk_ms = msSince(t0);
    const char* kind = "build";
    if (field->lastUpdateKind() == DistanceField::UpdateKind::kFromTree) kind = "from the tree";
    if (field->lastUpdateKind() == DistanceField::UpdateKind::kFromChanges)
      kind = "from the change set";
    std::printf("| %zu%s | %.1f | %.1f (%.1f) | %s | %.1fx |\n", i + 1, i == 0 ? " (scratch)" : "",
                edt_ms, vk_ms, field->lastUpdateMs(), kind, edt_ms / vk_ms);
    json.beginObject();
    json.field("view", static_cast<double>(i + 1));
    json.field("dynamicedt_ms", edt_ms);
    json.field("octovk_ms", vk_ms);
    json.field("octovk_device_ms", field->lastUpdateMs());
    json.endObject();
  }
  json.endArray();
  const auto size = field->size();
  std::printf("\nField: %u x %u x %u cells, %.1f MiB on the device.\n", size[0], size[1], size[2],
              static_cast<double>(field->deviceBytes()) / (1 << 20));

  Rng rng(20261125);
  std::vector<Eigen::Vector3f> points(query_count);
  for (Eigen::Vector3f& p : points)
    p = Eigen::Vector3f(static_cast<float>(rng.uniform(lo.x(), hi.x())),
                        static_cast<float>(rng.uniform(lo.y(), hi.y())),
                        static_cast<float>(rng.uniform(lo.z(), hi.z())));
  (void)field->distances(points);  // sizes the query buffers
  // Five rounds, each side once per round (interleaved, so load drifts hit both alike).
  constexpr int kRounds = 5;
  std::vector<float> theirs(points.size());
  std::vector<octomap::point3d> obstacles(points.size());
  std::vector<DistanceSample> ours;
  std::vector<double> edt_times, vk_times;
  for (int round = 0; round < kRounds; ++round) {
    auto t0 = Clock::now();
    for (std::size_t i = 0; i < points.size(); ++i)
      edt->getDistanceAndClosestObstacle(
          octomap::point3d(points[i].x(), points[i].y(), points[i].z()), theirs[i], obstacles[i]);
    edt_times.push_back(msSince(t0));
    t0 = Clock::now();
    ours = field->distances(points);
    vk_times.push_back(msSince(t0));
  }
  const double edt_ms = median(edt_times), vk_ms = median(vk_times);
  const double edt_min = *std::min_element(edt_times.begin(), edt_times.end());
  const double vk_min = *std::min_element(vk_times.begin(), vk_times.end());
  const auto cap = static_cast<std::uint32_t>(edt->getSquaredMaxDistCells());
  std::size_t agree = 0;
  for (std::size_t i = 0; i < points.size(); ++i) {
    const octomap::point3d p(points[i].x(), points[i].y(), points[i].z());
    agree += static_cast<std::uint32_t>(edt->getSquaredDistanceInCells(p)) ==
             std::min(ours[i].squared_cells, cap);
  }
  std::printf(
      "\nQueries: %zu points uniform in the box, %d rounds. dynamicEDT3D: a loop of "
      "getDistanceAndClosestObstacle, median %.1f ms (min %.1f); octovk: one distances() call "
      "(staging, upload, dispatch, download), median %.1f ms (min %.1f): %.1fx on the medians. "
      "Squared distances in cells agree on %zu of %zu.\n",
      points.size(), kRounds, edt_ms, edt_min, vk_ms, vk_min, edt_ms / vk_ms, agree, points.size());
  json.field("query_points", points.size()).field("query_dynamicedt_ms", edt_ms);
  json.field("query_octovk_ms", vk_ms).field("query_agree", agree);
  json.endObject();
}

}  // namespace octovk::bench
