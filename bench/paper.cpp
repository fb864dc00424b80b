// The paper workload: six 320x240 views of the synthetic building, by the walk and by ray
// tracing, OctoMap beside (Table I).
#include <octomap/OcTree.h>

#include <chrono>
#include <cstdio>
#include <functional>
#include <string>
#include <vector>

#include "building.hpp"
#include "measure.hpp"
#include "octovk/octomap_io.hpp"
#include "workload_common.hpp"
#include "workloads.hpp"

namespace octovk::bench {

namespace {

// One ray-tracing path's runs of the paper's views (fresh maps; OctoMap in the same run): per
// run and view the scan's statistics and OctoMap's insert time; whether every map equals
// OctoMap's after the last view.
struct TracedRuns {
  std::vector<std::vector<ScanStats>> runs;
  std::vector<std::vector<double>> om_ms;
  bool equal = true;

  double median(std::size_t view, const std::function<double(const ScanStats&)>& get) const {
    std::vector<double> v;
    for (const auto& run : runs) v.push_back(get(run[view]));
    return bench::median(v);
  }
};

TracedRuns runTraced(Context& context, const BenchOptions& o, double res, const TracePath& path,
                     const std::vector<SensorPose>& views,
                     const std::vector<std::vector<Eigen::Vector3f>>& clouds) {
  TracedRuns out;
  for (int rep = 0; rep < o.repeat; ++rep) {
    octomap::OcTree tree(res);
    OccupancyMap map = makeMap(context, o, res, path.scan_rays);
    std::vector<ScanStats> run;
    std::vector<double> om;
    for (std::size_t i = 0; i < views.size(); ++i) {
      progress("paper %s %g m, run %d/%d: view %zu/%zu\n", path.label, res, rep + 1, o.repeat,
               i + 1, views.size());
      const Eigen::Vector3f origin = views[i].position.cast<float>();
      const ScanTiming t = measureWorldScan(tree, map, clouds[i], origin, -1.0, false);
      run.push_back(t.vk);
      om.push_back(t.om_insert_ms);
      out.equal = out.equal && t.vk.nodes == t.om_nodes;
    }
    out.equal = out.equal && *toOcTree(map) == tree;
    out.runs.push_back(run);
    out.om_ms.push_back(om);
  }
  return out;
}

double restMs(const StageTimes& d) {
  return d.total_ms() - d.scan_boxes_ms - d.scan_build_ms - d.scan_trace_ms;
}

// The paper's views again through ray tracing, on each path the device runs (ray queries, a
// ray-tracing pipeline: a column group each), per view the structure's boxes and build, the rays
// traced through it, and the rest, beside the walk's `walk` (median per view). Every map checked
// against OctoMap's after the last view.
void runPaperRt(Context& context, const BenchOptions& o, double res,
                const std::vector<SensorPose>& views,
                const std::vector<std::vector<Eigen::Vector3f>>& clouds,
                const std::vector<std::string>& labels, const std::vector<ScanTiming>& walk,
                const std::vector<TracePath>& paths, JsonWriter& json) {
  std::vector<TracedRuns> traced;
  bool equal = true;
  for (const TracePath& path : paths) {
    traced.push_back(runTraced(context, o, res, path, views, clouds));
    equal = equal && traced.back().equal;
  }
  // The table's header: the walk's columns, then per path wall, boxes, build, trace, rest.
  const auto header = [&](const char* walk_stage, const char* last_stage) {
    std::string head = std::string("| view | OctoMap ms | walk wall ms | ") + walk_stage + " ms |";
    std::string rule = "| --- | --: | --: | --: |";
    for (const TracePath& path : paths) {
      for (const char* col : {"wall", "boxes", "build", "trace", last_stage})
        head += std::string(" ") + path.label + " " + col + " ms |";
      rule += " --: | --: | --: | --: | --: |";
    }
    std::printf("%s free cells walk / rt |\n%s --: |\n", head.c_str(), rule.c_str());
  };
  std::printf(
      "\n### paper, resolution %g m: scans through ray tracing (ScanRays::kRayQuery, "
      "kRayTracingPipeline) beside the walk\n\nPer view, ms (median of %d run(s), fresh maps): "
      "OctoMap insertPointCloud in the same run; octovk wall time; device time of the walk's ray "
      "stage, and per ray-tracing path of the traced scan's boxes, structure build, ray shooting "
      "(trace + DDA through the boxes) and the rest of the scan. Maps %s OctoMap's.\n\n",
      res, o.repeat, equal ? "equal to" : "DIFFER FROM");
  header("walk ray_keys", "rest");
  json.beginObject().field("equals_octomap", equal).key("views").beginArray();
  for (std::size_t i = 0; i < views.size(); ++i) {
    std::vector<double> om;
    for (const auto& run : traced.front().om_ms) om.push_back(run[i]);
    std::printf("| %s | %.1f | %.1f | %.1f |", labels[i].c_str(), median(om), walk[i].vk.wall_ms,
                walk[i].vk.device.ray_keys_ms);
    json.beginObject()
        .field("view", labels[i])
        .field("octomap_insert_ms", median(om))
        .field("walk_wall_ms", walk[i].vk.wall_ms)
        .field("walk_ray_keys_ms", walk[i].vk.device.ray_keys_ms);
    for (std::size_t p = 0; p < paths.size(); ++p) {
      const TracedRuns& r = traced[p];
      const double wall = r.median(i, [](const ScanStats& s) { return s.wall_ms; });
      const double boxes = r.median(i, [](const ScanStats& s) { return s.device.scan_boxes_ms; });
      const double build = r.median(i, [](const ScanStats& s) { return s.device.scan_build_ms; });
      const double trace = r.median(i, [](const ScanStats& s) { return s.device.scan_trace_ms; });
      const double rest = r.median(i, [](const ScanStats& s) { return restMs(s.device); });
      std::printf(" %.1f | %.1f | %.1f | %.1f | %.1f |", wall, boxes, build, trace, rest);
      const std::string k = paths[p].key;
      json.field(k + "_wall_ms", wall)
          .field(k + "_boxes_ms", boxes)
          .field(k + "_build_ms", build)
          .field(k + "_trace_ms", trace)
          .field(k + "_rest_ms", rest)
          .field(k + "_free_cells", r.runs.front()[i].free_cells);
    }
    // Both paths mark the same cells: the first one's count stands for them.
    std::printf(" %zu / %zu |\n", walk[i].vk.free_cells, traced.front().runs.front()[i].free_cells);
    json.field("walk_free_cells", walk[i].vk.free_cells).endObject();
  }
  json.endArray();

  // Revisits: the six views inserted six times over into fresh maps (a sensor that stays in the
  // building), walk and each ray-tracing path side by side with OctoMap; the last pass, per
  // view, when the free space seen is clamped and the traced rays jump over it.
  constexpr int kPasses = 6;
  octomap::OcTree tree(res);
  OccupancyMap walk_map = makeMap(context, o, res, ScanRays::kWalk);
  std::vector<OccupancyMap> rt_maps;
  for (const TracePath& path : paths) rt_maps.push_back(makeMap(context, o, res, path.scan_rays));
  std::vector<ScanStats> walk_last;
  std::vector<std::vector<ScanStats>> rt_last(paths.size());
  std::vector<double> om_last;
  for (int pass = 0; pass < kPasses; ++pass) {
    for (std::size_t i = 0; i < views.size(); ++i) {
      progress("paper rt %g m, revisits: pass %d/%d, view %zu/%zu\n", res, pass + 1, kPasses, i + 1,
               views.size());
      const Eigen::Vector3f origin = views[i].position.cast<float>();
      const ScanTiming t = measureWorldScan(tree, rt_maps.front(), clouds[i], origin, -1.0, false);
      std::vector<ScanStats> rt{t.vk};
      for (std::size_t p = 1; p < paths.size(); ++p)
        rt.push_back(rt_maps[p].insertPointCloud(clouds[i], origin));
      const ScanStats w = walk_map.insertPointCloud(clouds[i], origin);
      if (pass + 1 == kPasses) {
        for (std::size_t p = 0; p < paths.size(); ++p) rt_last[p].push_back(rt[p]);
        walk_last.push_back(w);
        om_last.push_back(t.om_insert_ms);
      }
    }
  }
  bool revisit_equal = *toOcTree(walk_map) == tree;
  for (OccupancyMap& m : rt_maps) revisit_equal = revisit_equal && *toOcTree(m) == tree;
  std::printf(
      "\nRevisits (the six views %d times over, fresh maps, one run): pass %d per view, ms. Maps "
      "%s OctoMap's.\n\n",
      kPasses, kPasses, revisit_equal ? "equal to" : "DIFFER FROM");
  header("walk ray_keys + classify", "classify");
  json.key("revisits").beginObject().field("passes", kPasses);
  json.field("equals_octomap", revisit_equal).key("last_pass").beginArray();
  for (std::size_t i = 0; i < views.size(); ++i) {
    const StageTimes& wd = walk_last[i].device;
    std::printf("| %s | %.1f | %.1f | %.1f |", labels[i].c_str(), om_last[i], walk_last[i].wall_ms,
                wd.ray_keys_ms + wd.classify_ms);
    json.beginObject()
        .field("view", labels[i])
        .field("octomap_insert_ms", om_last[i])
        .field("walk_wall_ms", walk_last[i].wall_ms)
        .field("walk_ray_keys_ms", wd.ray_keys_ms)
        .field("walk_classify_ms", wd.classify_ms);
    for (std::size_t p = 0; p < paths.size(); ++p) {
      const ScanStats& r = rt_last[p][i];
      const StageTimes& rd = r.device;
      std::printf(" %.1f | %.1f | %.1f | %.1f | %.1f |", r.wall_ms, rd.scan_boxes_ms,
                  rd.scan_build_ms, rd.scan_trace_ms, rd.classify_ms);
      const std::string k = paths[p].key;
      json.field(k + "_wall_ms", r.wall_ms)
          .field(k + "_boxes_ms", rd.scan_boxes_ms)
          .field(k + "_build_ms", rd.scan_build_ms)
          .field(k + "_trace_ms", rd.scan_trace_ms)
          .field(k + "_classify_ms", rd.classify_ms)
          .field(k + "_free_cells", r.free_cells);
    }
    std::printf(" %zu / %zu |\n", walk_last[i].free_cells, rt_last.front()[i].free_cells);
    json.field("walk_free_cells", walk_last[i].free_cells).endObject();
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
    if (const std::vector<TracePath> paths = tracePaths(context); !paths.empty()) {
      json.key("rt_scans");
      runPaperRt(context, o, res, views, clouds, labels, scans, paths, json);
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
