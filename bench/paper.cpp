// The paper workload: six 320x240 views of the synthetic building, by the walk and by ray
// tracing, OctoMap beside (Table I).
#include <octomap/OcTree.h>

#include <chrono>
#include <cstdio>
#include <string>
#include <vector>

#include "building.hpp"
#include "measure.hpp"
#include "octovk/octomap_io.hpp"
#include "workload_common.hpp"
#include "workloads.hpp"

namespace octovk::bench {

namespace {

// The paper's views again with ScanRays::kRayTracing (fresh maps; OctoMap in the same run), per
// view the structure's boxes and build, the rays traced through it, and the rest, beside the
// walk's `walk` (median per view). Every map checked against OctoMap's after the last view.
void runPaperRt(Context& context, const BenchOptions& o, double res,
                const std::vector<SensorPose>& views,
                const std::vector<std::vector<Eigen::Vector3f>>& clouds,
                const std::vector<std::string>& labels, const std::vector<ScanTiming>& walk,
                JsonWriter& json) {
  std::vector<std::vector<ScanStats>> runs;
  std::vector<std::vector<double>> om_ms;
  bool equal = true;
  for (int rep = 0; rep < o.repeat; ++rep) {
    octomap::OcTree tree(res);
    OccupancyMap map = makeMap(context, o, res, ScanRays::kRayTracing);
    std::vector<ScanStats> run;
    std::vector<double> om;
    for (std::size_t i = 0; i < views.size(); ++i) {
      progress("paper rt %g m, run %d/%d: view %zu/%zu\n", res, rep + 1, o.repeat, i + 1,
               views.size());
      const Eigen::Vector3f origin = views[i].position.cast<float>();
      const ScanTiming t = measureWorldScan(tree, map, clouds[i], origin, -1.0, false);
      run.push_back(t.vk);
      om.push_back(t.om_insert_ms);
      equal = equal && t.vk.nodes == t.om_nodes;
    }
    equal = equal && *toOcTree(map) == tree;
    runs.push_back(run);
    om_ms.push_back(om);
  }
  const auto med = [&](std::size_t view, const std::function<double(const ScanStats&)>& get) {
    std::vector<double> v;
    for (const auto& run : runs) v.push_back(get(run[view]));
    return median(v);
  };
  std::printf(
      "\n### paper, resolution %g m: scans through ray tracing (ScanRays::kRayTracing) beside the "
      "walk\n\nPer view, ms (median of %d run(s), fresh maps): OctoMap insertPointCloud in the "
      "same "
      "run; octovk wall time; device time of the walk's ray stage, and of the traced scan's "
      "boxes, structure build, ray shooting (trace + DDA through the boxes) and the rest of the "
      "scan. Maps %s OctoMap's.\n\n"
      "| view | OctoMap ms | walk wall ms | walk ray_keys ms | rt wall ms | rt boxes ms | "
      "rt build ms | rt trace ms | rt rest ms | free cells walk / rt |\n"
      "| --- | --: | --: | --: | --: | --: | --: | --: | --: | --: |\n",
      res, o.repeat, equal ? "equal to" : "DIFFER FROM");
  json.beginObject().field("equals_octomap", equal).key("views").beginArray();
  for (std::size_t i = 0; i < views.size(); ++i) {
    std::vector<double> om;
    for (const auto& run : om_ms) om.push_back(run[i]);
    const double wall = med(i, [](const ScanStats& s) { return s.wall_ms; });
    const double boxes = med(i, [](const ScanStats& s) { return s.device.scan_boxes_ms; });
    const double build = med(i, [](const ScanStats& s) { return s.device.scan_build_ms; });
    const double trace = med(i, [](const ScanStats& s) { return s.device.scan_trace_ms; });
    const double rest = med(i, [](const ScanStats& s) {
      return s.device.total_ms() - s.device.scan_boxes_ms - s.device.scan_build_ms -
             s.device.scan_trace_ms;
    });
    const ScanStats& first = runs.front()[i];
    std::printf("| %s | %.1f | %.1f | %.1f | %.1f | %.1f | %.1f | %.1f | %.1f | %zu / %zu |\n",
                labels[i].c_str(), median(om), walk[i].vk.wall_ms, walk[i].vk.device.ray_keys_ms,
                wall, boxes, build, trace, rest, walk[i].vk.free_cells, first.free_cells);
    json.beginObject()
        .field("view", labels[i])
        .field("octomap_insert_ms", median(om))
        .field("walk_wall_ms", walk[i].vk.wall_ms)
        .field("walk_ray_keys_ms", walk[i].vk.device.ray_keys_ms)
        .field("rt_wall_ms", wall)
        .field("rt_boxes_ms", boxes)
        .field("rt_build_ms", build)
        .field("rt_trace_ms", trace)
        .field("rt_rest_ms", rest)
        .field("walk_free_cells", walk[i].vk.free_cells)
        .field("rt_free_cells", first.free_cells)
        .endObject();
  }
  json.endArray();

  // Revisits: the six views inserted six times over into fresh maps (a sensor that stays in the
  // building), walk and ray tracing side by side with OctoMap; the last pass, per view, when the
  // free space seen is clamped and the traced rays jump over it.
  constexpr int kPasses = 6;
  octomap::OcTree tree(res);
  OccupancyMap walk_map = makeMap(context, o, res, ScanRays::kWalk);
  OccupancyMap rt_map = makeMap(context, o, res, ScanRays::kRayTracing);
  std::vector<ScanStats> walk_last, rt_last;
  std::vector<double> om_last;
  for (int pass = 0; pass < kPasses; ++pass) {
    for (std::size_t i = 0; i < views.size(); ++i) {
      progress("paper rt %g m, revisits: pass %d/%d, view %zu/%zu\n", res, pass + 1, kPasses, i + 1,
               views.size());
      const Eigen::Vector3f origin = views[i].position.cast<float>();
      const ScanTiming t = measureWorldScan(tree, rt_map, clouds[i], origin, -1.0, false);
      const ScanStats w = walk_map.insertPointCloud(clouds[i], origin);
      if (pass + 1 == kPasses) {
        rt_last.push_back(t.vk);
        walk_last.push_back(w);
        om_last.push_back(t.om_insert_ms);
      }
    }
  }
  const bool revisit_equal = *toOcTree(rt_map) == tree && *toOcTree(walk_map) == tree;
  std::printf(
      "\nRevisits (the six views %d times over, fresh maps, one run): pass %d per view, ms. Maps "
      "%s OctoMap's.\n\n"
      "| view | OctoMap ms | walk wall ms | walk ray_keys + classify ms | rt wall ms | rt boxes "
      "ms | rt build ms | rt trace ms | rt classify ms | free cells walk / rt |\n"
      "| --- | --: | --: | --: | --: | --: | --: | --: | --: | --: |\n",
      kPasses, kPasses, revisit_equal ? "equal to" : "DIFFER FROM");
  json.key("revisits").beginObject().field("passes", kPasses);
  json.field("equals_octomap", revisit_equal).key("last_pass").beginArray();
  for (std::size_t i = 0; i < views.size(); ++i) {
    const StageTimes& wd = walk_last[i].device;
    const StageTimes& rd = rt_last[i].device;
    std::printf("| %s | %.1f | %.1f | %.1f | %.1f | %.1f | %.1f | %.1f | %.1f | %zu / %zu |\n",
                labels[i].c_str(), om_last[i], walk_last[i].wall_ms,
                wd.ray_keys_ms + wd.classify_ms, rt_last[i].wall_ms, rd.scan_boxes_ms,
                rd.scan_build_ms, rd.scan_trace_ms, rd.classify_ms, walk_last[i].free_cells,
                rt_last[i].free_cells);
    json.beginObject()
        .field("view", labels[i])
        .field("octomap_insert_ms", om_last[i])
        .field("walk_wall_ms", walk_last[i].wall_ms)
        .field("walk_ray_keys_ms", wd.ray_keys_ms)
        .field("walk_classify_ms", wd.classify_ms)
        .field("rt_wall_ms", rt_last[i].wall_ms)
        .field("rt_boxes_ms", rd.scan_boxes_ms)
        .field("rt_build_ms", rd.scan_build_ms)
        .field("rt_trace_ms", rd.scan_trace_ms)
        .field("rt_classify_ms", rd.classify_ms)
        .field("walk_free_cells", walk_last[i].free_cells)
        .field("rt_free_cells", rt_last[i].free_cells)
        .endObject();
  }
  json.endArray().endObject();
  json.endObject();
}

}  // namespace

void runPaper(Context& context, const BenchOptions& o, JsonWriter& json) {
  const std::vector<double> resolutions = resolutionsFor(o, {0.1, 0.05, 0.02}, {0.1, 0.05});
  const Building building;
  const std::vector<SensorPose> views = paperViews();
  std::vector<std::vector<Eigen::Vector3f>> clouds;
  std::vector<std::string> labels;
  for (const SensorPose& v : views) {
    clouds.push_back(rangeImage(building, v, kPaperWidth, kPaperHeight));
    labels.push_back(v.name);
  }

  std::printf("\n## paper: synthetic building, %zu views of %zux%zu rays, depth 16\n", views.size(),
              kPaperWidth, kPaperHeight);
  std::printf(
      "\nBuilding: %zu boxes (40 x 16 x 3 m, corridor, 10 furnished rooms, doors). "
      "Max range: unlimited. Times: median of %d run(s), each into fresh maps.\n",
      building.boxCount(), o.repeat);
  json.key("paper").beginObject();
  json.field("width", kPaperWidth).field("height", kPaperHeight).field("repeat", o.repeat);
  json.key("views").beginArray();
  for (std::size_t i = 0; i < views.size(); ++i) {
    const SensorPose& v = views[i];
    json.beginObject()
        .field("name", v.name)
        .key("position")
        .beginArray()
        .value(v.position.x())
        .value(v.position.y())
        .value(v.position.z())
        .endArray()
        .field("yaw_deg", v.yaw_deg)
        .field("pitch_deg", v.pitch_deg)
        .field("rays", clouds[i].size())
        .endObject();
  }
  json.endArray();
  json.key("runs").beginArray();

  std::vector<ScanTiming> means;
  for (double res : resolutions) {
    MemoryReport memory;
    std::vector<double> sustained;
    const std::vector<ScanTiming> scans = repeatSequence(o.repeat, [&](int rep) {
      octomap::OcTree tree(res);
      OccupancyMap map = makeMap(context, o, res);
      std::vector<ScanTiming> run;
      double rays = 0, wall_ms = 0;
      for (std::size_t i = 0; i < views.size(); ++i) {
        progress("paper %g m, run %d/%d: view %zu/%zu\n", res, rep + 1, o.repeat, i + 1,
                 views.size());
        const Eigen::Vector3f origin = views[i].position.cast<float>();
        run.push_back(measureWorldScan(tree, map, clouds[i], origin, -1.0, o.compute_update));
        rays += static_cast<double>(run.back().rays);
        wall_ms += run.back().vk.wall_ms;
      }
      sustained.push_back(perSecond(rays, wall_ms));
      if (rep == 0) memory = memoryReport(tree, map);
      return run;
    });
    const ScanTiming mean = meanOf(scans);
    means.push_back(mean);

    std::printf("\n### paper, resolution %g m\n", res);
    printScanTable("view", labels, scans);
    printStageTable("view (octovk device ms)", labels, scans);
    printMemoryTable({fmt("paper, 6 views, %g m", res)}, {memory});
    std::printf(
        "\n%s. Cell sets equal to OctoMap's computeUpdate in %zu of %zu views. "
        "Six views back to back: %.3g Mrays/s (octovk wall).\n",
        parityLine(memory.om_nodes, memory.vk_nodes).c_str(), scans.size() - cellMismatches(scans),
        scans.size(), median(sustained) * 1e-6);

    json.beginObject().field("resolution", res).key("scans");
    writeScans(json, scans);
    json.key("mean_per_view");
    writeJson(json, mean);
    json.field("back_to_back_rays_per_s", median(sustained));
    // The six views submitted back to back (submitPointCloud, one flush), fresh maps.
    std::vector<double> streamed_s;
    bool streamed_equal = true;
    std::uint64_t streamed_waits = 0, streamed_submissions = 0;
    for (int rep = 0; rep < o.repeat; ++rep) {
      OccupancyMap map = makeMap(context, o, res);
      const OccupancyMap::SyncCounts before = map.syncCounts();
      const auto start = Clock::now();
      for (std::size_t i = 0; i < views.size(); ++i)
        map.submitPointCloud(clouds[i], views[i].position.cast<float>());
      map.flush();
      streamed_s.push_back(secondsSince(start));
      const OccupancyMap::SyncCounts after = map.syncCounts();
      streamed_waits = after.host_waits - before.host_waits;
      streamed_submissions = after.submissions - before.submissions;
      streamed_equal = streamed_equal && map.nodeCount() == memory.om_nodes;
    }
    double view_rays = 0;
    for (const auto& c : clouds) view_rays += static_cast<double>(c.size());
    const double streamed_median = median(streamed_s);
    json.key("streamed").beginObject();
    json.field("wall_s", streamed_median).field("rays_per_s", view_rays / streamed_median);
    const double view_count = static_cast<double>(views.size());
    json.field("views_per_s", view_count / streamed_median);
    json.field("submissions", streamed_submissions).field("host_waits", streamed_waits);
    json.field("node_count_equals_octomap", streamed_equal);
    json.endObject();
    std::printf(
        "Six views submitted back to back (fresh map, one flush): %.3f s, %.3g Mrays/s, %.1f "
        "views/s; %llu submissions, %llu host waits; node count %s OctoMap's.\n",
        streamed_median, view_rays / streamed_median * 1e-6, view_count / streamed_median,
        static_cast<unsigned long long>(streamed_submissions),
        static_cast<unsigned long long>(streamed_waits),
        streamed_equal ? "equals" : "DIFFERS FROM");
    json.field("cell_set_mismatches", cellMismatches(scans));
    json.key("memory");
    writeJson(json, memory);
    if (context.device().ray_query_enabled) {
      json.key("rt_scans");
      runPaperRt(context, o, res, views, clouds, labels, scans, json);
    }
    json.endObject();
  }
  json.endArray();

  std::printf("\n### paper: Table I (octovk per stage, mean per %zux%zu view)\n", kPaperWidth,
              kPaperHeight);
  printTableOne(resolutions, means);
  json.endObject();
}

}  // namespace octovk::bench
