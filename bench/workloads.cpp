#include "workloads.hpp"

#include <octomap/OcTree.h>

#include <algorithm>
#include <chrono>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <functional>
#include <memory>
#include <numeric>
#include <sstream>
#include <stdexcept>

#include "building.hpp"
#include "measure.hpp"
#include "octovk/octomap_io.hpp"

namespace octovk::bench {

namespace {

using Clock = std::chrono::steady_clock;

constexpr std::size_t kPaperWidth = 320;
constexpr std::size_t kPaperHeight = 240;

double secondsSince(Clock::time_point start) {
  return std::chrono::duration<double>(Clock::now() - start).count();
}

std::vector<double> resolutionsFor(const BenchOptions& o, std::vector<double> full,
                                   std::vector<double> quick) {
  if (!o.resolutions.empty()) return o.resolutions;
  return o.quick ? quick : full;
}

MapParams paramsFor(double resolution) {
  MapParams p;
  p.resolution = resolution;
  return p;
}

OccupancyMap makeMap(Context& context, const BenchOptions& o, double resolution,
                     ScanRays rays = ScanRays::kWalk) {
  MapParams params = paramsFor(resolution);
  params.scan_rays = rays;
  OccupancyMap map(context, params);
  map.setLeafBoxesEveryScan(o.leaf_boxes_every_scan);
  return map;
}

double median(std::vector<double> v) {
  std::sort(v.begin(), v.end());
  const std::size_t n = v.size();
  return n % 2 ? v[n / 2] : 0.5 * (v[n / 2 - 1] + v[n / 2]);
}

// Counts are the same in every repetition; each time is the median over the repetitions.
ScanTiming medianOf(const std::vector<ScanTiming>& reps) {
  ScanTiming m = reps.front();
  const auto med = [&](const std::function<double(const ScanTiming&)>& get) {
    std::vector<double> v;
    for (const ScanTiming& r : reps) v.push_back(get(r));
    return median(v);
  };
  m.om_compute_update_ms = med([](const ScanTiming& t) { return t.om_compute_update_ms; });
  m.om_insert_ms = med([](const ScanTiming& t) { return t.om_insert_ms; });
  m.vk.wall_ms = med([](const ScanTiming& t) { return t.vk.wall_ms; });
  m.vk.device.upload_ms = med([](const ScanTiming& t) { return t.vk.device.upload_ms; });
  m.vk.device.ray_keys_ms = med([](const ScanTiming& t) { return t.vk.device.ray_keys_ms; });
  m.vk.device.classify_ms = med([](const ScanTiming& t) { return t.vk.device.classify_ms; });
  m.vk.device.tree_update_ms = med([](const ScanTiming& t) { return t.vk.device.tree_update_ms; });
  m.vk.device.prune_ms = med([](const ScanTiming& t) { return t.vk.device.prune_ms; });
  m.vk.device.leaf_boxes_ms = med([](const ScanTiming& t) { return t.vk.device.leaf_boxes_ms; });
  return m;
}

// Field-wise mean of several scans (for "per view" rows and Table I).
ScanTiming meanOf(const std::vector<ScanTiming>& scans) {
  ScanTiming m;
  if (scans.empty()) return m;
  const double n = static_cast<double>(scans.size());
  double rays = 0, free_cells = 0, occupied = 0, om_free = 0, om_occ = 0;
  m.om_compute_update_ms = 0;
  for (const ScanTiming& t : scans) {
    rays += static_cast<double>(t.rays);
    free_cells += static_cast<double>(t.vk.free_cells);
    occupied += static_cast<double>(t.vk.occupied_cells);
    om_free += static_cast<double>(t.om_free_cells);
    om_occ += static_cast<double>(t.om_occupied_cells);
    m.om_compute_update_ms += t.om_compute_update_ms / n;
    m.om_insert_ms += t.om_insert_ms / n;
    m.vk.wall_ms += t.vk.wall_ms / n;
    m.vk.device.upload_ms += t.vk.device.upload_ms / n;
    m.vk.device.ray_keys_ms += t.vk.device.ray_keys_ms / n;
    m.vk.device.classify_ms += t.vk.device.classify_ms / n;
    m.vk.device.tree_update_ms += t.vk.device.tree_update_ms / n;
    m.vk.device.prune_ms += t.vk.device.prune_ms / n;
    m.vk.device.leaf_boxes_ms += t.vk.device.leaf_boxes_ms / n;
    m.vk.cell_set_attempts = std::max(m.vk.cell_set_attempts, t.vk.cell_set_attempts);
  }
  m.rays = static_cast<std::size_t>(std::lround(rays / n));
  m.vk.free_cells = static_cast<std::size_t>(std::lround(free_cells / n));
  m.vk.occupied_cells = static_cast<std::size_t>(std::lround(occupied / n));
  m.om_free_cells = static_cast<std::size_t>(std::lround(om_free / n));
  m.om_occupied_cells = static_cast<std::size_t>(std::lround(om_occ / n));
  m.om_nodes = scans.back().om_nodes;
  m.vk.nodes = scans.back().vk.nodes;
  return m;
}

std::size_t cells(const ScanTiming& t) { return t.vk.free_cells + t.vk.occupied_cells; }

double perSecond(double count, double ms) { return ms > 0 ? count / (ms * 1e-3) : 0.0; }

std::string fmt(const char* format, double v) {
  char buf[64];
  std::snprintf(buf, sizeof(buf), format, v);
  return buf;
}

// OctoMap's cell sets and octovk's (before early abort) must have the same sizes.
int cellMismatches(const std::vector<ScanTiming>& scans) {
  int bad = 0;
  for (const ScanTiming& t : scans)
    if (t.om_compute_update_ms >= 0 &&
        (t.om_free_cells != t.vk.free_cells || t.om_occupied_cells != t.vk.occupied_cells))
      ++bad;
  return bad;
}

void printScanTable(const std::string& first_column, const std::vector<std::string>& labels,
                    const std::vector<ScanTiming>& scans) {
  std::printf(
      "\n| %s | rays | cells (free + occupied) | OctoMap computeUpdate ms | OctoMap "
      "insertPointCloud ms | octovk wall ms | OctoMap insert / octovk | octovk Mrays/s | "
      "octovk M cell updates/s |\n"
      "| --- | --: | --: | --: | --: | --: | --: | --: | --: |\n",
      first_column.c_str());
  for (std::size_t i = 0; i < scans.size(); ++i) {
    const ScanTiming& t = scans[i];
    std::printf("| %s | %zu | %zu | %s | %.1f | %.1f | %.2fx | %.3g | %.3g |\n", labels[i].c_str(),
                t.rays, cells(t),
                t.om_compute_update_ms >= 0 ? fmt("%.1f", t.om_compute_update_ms).c_str() : "-",
                t.om_insert_ms, t.vk.wall_ms, t.om_insert_ms / t.vk.wall_ms,
                perSecond(static_cast<double>(t.rays), t.vk.wall_ms) * 1e-6,
                perSecond(static_cast<double>(cells(t)), t.vk.wall_ms) * 1e-6);
  }
  std::fflush(stdout);
}

void printStageTable(const std::string& first_column, const std::vector<std::string>& labels,
                     const std::vector<ScanTiming>& scans) {
  std::printf(
      "\n| %s | upload | ray walk + hash set | classify / early abort | tree update | prune | "
      "leaf-box rebuild | device total | octovk wall | wall - device | cell-set passes |\n"
      "| --- | --: | --: | --: | --: | --: | --: | --: | --: | --: | --: |\n",
      first_column.c_str());
  for (std::size_t i = 0; i < scans.size(); ++i) {
    const StageTimes& d = scans[i].vk.device;
    std::printf("| %s | %.2f | %.2f | %.2f | %.2f | %.2f | %.2f | %.2f | %.2f | %.2f | %zu |\n",
                labels[i].c_str(), d.upload_ms, d.ray_keys_ms, d.classify_ms, d.tree_update_ms,
                d.prune_ms, d.leaf_boxes_ms, d.total(), scans[i].vk.wall_ms,
                scans[i].vk.wall_ms - d.total(), scans[i].vk.cell_set_attempts);
  }
  std::fflush(stdout);
}

// The paper's Table I: one column per resolution, mean per view, milliseconds.
void printTableOne(const std::vector<double>& resolutions, const std::vector<ScanTiming>& means) {
  std::printf("\n| mean per view, ms |");
  for (double r : resolutions) std::printf(" %g m |", r);
  std::printf("\n| --- |");
  for (std::size_t i = 0; i < resolutions.size(); ++i) std::printf(" --: |");
  std::printf("\n");
  const auto row = [&](const char* name, const std::function<std::string(const ScanTiming&)>& f) {
    std::printf("| %s |", name);
    for (const ScanTiming& m : means) std::printf(" %s |", f(m).c_str());
    std::printf("\n");
  };
  const auto ms = [](double v) { return fmt("%.2f", v); };
  row("OctoMap computeUpdate", [&](const ScanTiming& m) { return ms(m.om_compute_update_ms); });
  row("OctoMap insertPointCloud", [&](const ScanTiming& m) { return ms(m.om_insert_ms); });
  row("octovk upload", [&](const ScanTiming& m) { return ms(m.vk.device.upload_ms); });
  row("octovk ray walk + hash set",
      [&](const ScanTiming& m) { return ms(m.vk.device.ray_keys_ms); });
  row("octovk classify / early abort",
      [&](const ScanTiming& m) { return ms(m.vk.device.classify_ms); });
  row("octovk tree update", [&](const ScanTiming& m) { return ms(m.vk.device.tree_update_ms); });
  row("octovk prune", [&](const ScanTiming& m) { return ms(m.vk.device.prune_ms); });
  row("octovk leaf-box rebuild",
      [&](const ScanTiming& m) { return ms(m.vk.device.leaf_boxes_ms); });
  row("octovk device total", [&](const ScanTiming& m) { return ms(m.vk.device.total()); });
  row("octovk wall", [&](const ScanTiming& m) { return ms(m.vk.wall_ms); });
  row("**OctoMap insert / octovk wall**",
      [&](const ScanTiming& m) { return fmt("**%.2fx**", m.om_insert_ms / m.vk.wall_ms); });
  row("cells per view (free + occupied)",
      [&](const ScanTiming& m) { return fmt("%.0f", static_cast<double>(cells(m))); });
  row("octovk Mrays/s", [&](const ScanTiming& m) {
    return fmt("%.3g", perSecond(static_cast<double>(m.rays), m.vk.wall_ms) * 1e-6);
  });
  row("OctoMap Mrays/s", [&](const ScanTiming& m) {
    return fmt("%.3g", perSecond(static_cast<double>(m.rays), m.om_insert_ms) * 1e-6);
  });
  row("octovk M cell updates/s", [&](const ScanTiming& m) {
    return fmt("%.3g", perSecond(static_cast<double>(cells(m)), m.vk.wall_ms) * 1e-6);
  });
  row("OctoMap M cell updates/s", [&](const ScanTiming& m) {
    return fmt("%.3g", perSecond(static_cast<double>(cells(m)), m.om_insert_ms) * 1e-6);
  });
  std::fflush(stdout);
}

void writeScans(JsonWriter& json, const std::vector<ScanTiming>& scans) {
  json.beginArray();
  for (const ScanTiming& t : scans) {
    json.newline();
    writeJson(json, t);
  }
  json.endArray();
}

// Runs `scans` in order into fresh maps, `repeat` times; per scan the median of the times.
std::vector<ScanTiming> repeatSequence(
    int repeat, const std::function<std::vector<ScanTiming>(int rep)>& run_once) {
  std::vector<std::vector<ScanTiming>> runs;
  for (int rep = 0; rep < repeat; ++rep) runs.push_back(run_once(rep));
  std::vector<ScanTiming> out;
  for (std::size_t i = 0; i < runs.front().size(); ++i) {
    std::vector<ScanTiming> reps;
    for (const auto& run : runs) reps.push_back(run[i]);
    out.push_back(medianOf(reps));
  }
  return out;
}

void progress(const char* format, auto... args) {
  std::fprintf(stderr, format, args...);
  std::fflush(stderr);
}

}  // namespace

// ---- paper: six 320x240 views of the synthetic building ------------------------------------

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
      "walk\n\nPer view, ms (median of %d run(s), fresh maps): OctoMap insertPointCloud in the same "
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
      return s.device.total() - s.device.scan_boxes_ms - s.device.scan_build_ms -
             s.device.scan_trace_ms;
    });
    const ScanStats& first = runs.front()[i];
    std::printf("| %s | %.1f | %.1f | %.1f | %.1f | %.1f | %.1f | %.1f | %.1f | %zu / %zu |\n",
                labels[i].c_str(), median(om), walk[i].vk.wall_ms,
                walk[i].vk.device.ray_keys_ms, wall, boxes, build, trace, rest,
                walk[i].vk.free_cells, first.free_cells);
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
      progress("paper rt %g m, revisits: pass %d/%d, view %zu/%zu\n", res, pass + 1, kPasses,
               i + 1, views.size());
      const Eigen::Vector3f origin = views[i].position.cast<float>();
      const ScanTiming t = measureWorldScan(tree, rt_map, clouds[i], origin, -1.0, false);
      const ScanStats w = walk_map.insertPointCloud(clouds[i], origin, -1.0);
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
        static_cast<unsigned long long>(streamed_waits), streamed_equal ? "equals" : "DIFFERS FROM");
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

// ---- scan.dat: OctoMap's real 3D laser scan --------------------------------------------------

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

// ---- FR-079: 4,934 real 2D scans with odometry poses ------------------------------------------

namespace {

struct Window {
  double om_ms_per_scan = 0, vk_ms_per_scan = 0;
  double om_us_per_point = 0, vk_us_per_point = 0;
  double vk_device_ms_per_scan = 0, vk_leaf_boxes_ms_per_scan = 0;
  std::size_t nodes_at_end = 0;
};

Window window(const std::vector<ScanTiming>& scans, std::size_t begin, std::size_t end) {
  Window w;
  double points = 0;
  for (std::size_t i = begin; i < end; ++i) {
    const ScanTiming& t = scans[i];
    points += static_cast<double>(t.rays);
    w.om_ms_per_scan += t.om_insert_ms;
    w.vk_ms_per_scan += t.vk.wall_ms;
    w.vk_device_ms_per_scan += t.vk.device.total();
    w.vk_leaf_boxes_ms_per_scan += t.vk.device.leaf_boxes_ms;
  }
  w.om_us_per_point = w.om_ms_per_scan * 1e3 / points;
  w.vk_us_per_point = w.vk_ms_per_scan * 1e3 / points;
  const double n = static_cast<double>(end - begin);
  w.om_ms_per_scan /= n;
  w.vk_ms_per_scan /= n;
  w.vk_device_ms_per_scan /= n;
  w.vk_leaf_boxes_ms_per_scan /= n;
  w.nodes_at_end = scans[end - 1].vk.nodes;
  return w;
}

void writeJson(JsonWriter& json, const Window& w) {
  json.beginObject()
      .field("octomap_insert_ms_per_scan", w.om_ms_per_scan)
      .field("octovk_wall_ms_per_scan", w.vk_ms_per_scan)
      .field("octomap_insert_us_per_point", w.om_us_per_point)
      .field("octovk_wall_us_per_point", w.vk_us_per_point)
      .field("octovk_device_ms_per_scan", w.vk_device_ms_per_scan)
      .field("octovk_leaf_boxes_ms_per_scan", w.vk_leaf_boxes_ms_per_scan)
      .field("octovk_nodes_at_end", w.nodes_at_end)
      .endObject();
}

}  // namespace

namespace {

struct Stream {
  std::unique_ptr<OccupancyMap> map;
  double wall_s = 0, submit_ms = 0;
  double boxes_ms = 0, build_ms = 0, trace_ms = 0, device_ms = 0;  // sums over the scans
  std::uint64_t submissions = 0, waits = 0;
  std::size_t reruns = 0;
};

// Every scan of `graph` submitted back to back into a fresh map, then one flush: the wall time
// of the whole, the host's time in submit, and the map's submissions and host waits.
Stream streamGraph(Context& context, const BenchOptions& o, double res,
                   const std::vector<GraphScan>& graph, ScanRays rays = ScanRays::kWalk) {
  Stream s;
  s.map = std::make_unique<OccupancyMap>(makeMap(context, o, res, rays));
  const OccupancyMap::SyncCounts before = s.map->syncCounts();
  const auto start = Clock::now();
  auto take = [&] {
    for (const ScanStats& st : s.map->takeScanStats()) {
      s.submit_ms += st.wall_ms;
      s.reruns += st.cell_set_attempts > 1;
      s.boxes_ms += st.device.scan_boxes_ms;
      s.build_ms += st.device.scan_build_ms;
      s.trace_ms += st.device.scan_trace_ms;
      s.device_ms += st.device.total();
    }
  };
  for (std::size_t i = 0; i < graph.size(); ++i) {
    const GraphScan& scan = graph[i];
    s.map->submitPointCloud(scan.points_sensor, graph2treeSensorOrigin(scan.T_world_sensor),
                            scan.T_world_sensor, -1.0);
    if (i % 1024 == 1023) take();  // the map keeps the newest 4096
  }
  s.map->flush();
  s.wall_s = secondsSince(start);
  take();
  const OccupancyMap::SyncCounts after = s.map->syncCounts();
  s.submissions = after.submissions - before.submissions;
  s.waits = after.host_waits - before.host_waits;
  return s;
}

}  // namespace

void runFr079(Context& context, const BenchOptions& o, JsonWriter& json) {
  const std::vector<double> resolutions = resolutionsFor(o, {0.1, 0.05}, {0.1});
  const auto read_start = Clock::now();
  std::vector<GraphScan> graph = readScanGraph(o.fr079_path);
  const std::size_t limit = o.fr079_scans ? o.fr079_scans : (o.quick ? 600 : 0);
  if (limit && graph.size() > limit) graph.resize(limit);
  std::size_t total_points = 0;
  for (const GraphScan& s : graph) total_points += s.points_sensor.size();
  progress("fr079: read %zu scans in %.1f s\n", graph.size(), secondsSince(read_start));

  // First and last windows of 500 scans (a tenth of the run each when it is shorter).
  const std::size_t win = std::min<std::size_t>(500, std::max<std::size_t>(graph.size() / 10, 1));
  std::printf(
      "\n## fr079: FR-079 corridor, %zu real 2D scans, %zu points, graph2tree's placement\n",
      graph.size(), total_points);
  std::printf(
      "\nOne pass over the sequence per resolution, fresh maps. Max range: unlimited. "
      "Leaf boxes rebuilt every scan: %s. Flatness: the last %zu scans against the "
      "first %zu, per scan and per point.\n",
      o.leaf_boxes_every_scan ? "yes" : "no (on demand, the library default)", win, win);
  json.key("fr079").beginObject();
  json.field("file", o.fr079_path).field("scans", graph.size()).field("points", total_points);
  json.field("window", win).field("leaf_boxes_every_scan", o.leaf_boxes_every_scan);
  json.key("runs").beginArray();

  std::vector<std::string> labels;
  std::vector<ScanTiming> means;
  std::vector<MemoryReport> memories;
  std::vector<std::pair<Window, Window>> windows;
  for (double res : resolutions) {
    octomap::OcTree tree(res);
    OccupancyMap map = makeMap(context, o, res);
    std::vector<ScanTiming> scans;
    scans.reserve(graph.size());
    const auto start = Clock::now();
    double last_report = 0;
    for (std::size_t i = 0; i < graph.size(); ++i) {
      scans.push_back(measureGraphScan(tree, map, graph[i].points_sensor, graph[i].T_world_sensor,
                                       -1.0, o.compute_update));
      const double elapsed = secondsSince(start);
      if (elapsed - last_report > 10.0 || i + 1 == graph.size()) {
        last_report = elapsed;
        progress("fr079 %g m: scan %zu/%zu, %.0f s\n", res, i + 1, graph.size(), elapsed);
      }
    }
    const MemoryReport memory = memoryReport(tree, map);
    const ScanTiming mean = meanOf(scans);
    const Window first = window(scans, 0, win);
    const Window last = window(scans, graph.size() - win, graph.size());
    labels.push_back(fmt("%g m", res));
    means.push_back(mean);
    memories.push_back(memory);
    windows.emplace_back(first, last);

    double om_total = 0, om_cu_total = 0, vk_total = 0;
    for (const ScanTiming& t : scans) {
      om_total += t.om_insert_ms;
      om_cu_total += std::max(0.0, t.om_compute_update_ms);
      vk_total += t.vk.wall_ms;
    }
    int node_mismatches = 0;
    for (const ScanTiming& t : scans) node_mismatches += t.om_nodes != t.vk.nodes;

    json.beginObject().field("resolution", res);
    json.field("octomap_insert_total_s", om_total * 1e-3);
    json.field("octomap_compute_update_total_s", om_cu_total * 1e-3);
    json.field("octovk_wall_total_s", vk_total * 1e-3);
    json.field("scans_with_node_count_mismatch", node_mismatches);
    json.field("cell_set_mismatches", cellMismatches(scans));
    json.key("mean_per_scan");
    writeJson(json, mean);
    json.key("first_window");
    writeJson(json, first);
    json.key("last_window");
    writeJson(json, last);
    json.key("memory");
    writeJson(json, memory);
    // Per scan, as columns, to keep the file small.
    json.key("columns").beginArray();
    for (const char* c :
         {"points", "octomap_compute_update_ms", "octomap_insert_ms", "octovk_wall_ms", "upload_ms",
          "ray_keys_ms", "classify_ms", "tree_update_ms", "prune_ms", "leaf_boxes_ms",
          "octomap_nodes", "octovk_nodes"})
      json.value(c);
    json.endArray();
    json.key("per_scan").beginArray();
    for (const ScanTiming& t : scans) {
      const StageTimes& d = t.vk.device;
      json.newline().beginArray();
      json.value(t.rays).value(t.om_compute_update_ms).value(t.om_insert_ms).value(t.vk.wall_ms);
      json.value(d.upload_ms).value(d.ray_keys_ms).value(d.classify_ms).value(d.tree_update_ms);
      json.value(d.prune_ms).value(d.leaf_boxes_ms).value(t.om_nodes).value(t.vk.nodes);
      json.endArray();
    }
    json.endArray();

    std::printf(
        "\n### fr079, resolution %g m: %zu scans, OctoMap insertPointCloud %.2f s "
        "(computeUpdate alone %.2f s), octovk %.2f s: %.2fx\n",
        res, scans.size(), om_total * 1e-3, om_cu_total * 1e-3, vk_total * 1e-3,
        om_total / vk_total);
    std::printf(
        "\n%s at the end; per scan: node counts differ in %d of %zu scans, cell sets in "
        "%d.\n",
        parityLine(memory.om_nodes, memory.vk_nodes).c_str(), node_mismatches, scans.size(),
        cellMismatches(scans));

    // The same scans submitted back to back into a fresh map (OccupancyMap::submitPointCloud),
    // as `octovk integrate` does: no host wait per scan but for a free frame.
    const Stream stream = streamGraph(context, o, res, graph);
    const bool same = stream.map && *toOcTree(*stream.map) == tree;
    const double scan_count = static_cast<double>(graph.size());
    json.key("streamed").beginObject();
    json.field("wall_total_s", stream.wall_s).field("scans_per_s", scan_count / stream.wall_s);
    json.field("rays_per_s", static_cast<double>(total_points) / stream.wall_s);
    json.field("host_submit_ms_per_scan", stream.submit_ms / scan_count);
    json.field("submissions_per_scan", static_cast<double>(stream.submissions) / scan_count);
    json.field("host_waits_per_scan", static_cast<double>(stream.waits) / scan_count);
    json.field("scans_run_again", stream.reruns);
    json.field("equals_octomap", same);
    json.endObject();
    std::printf(
        "\nStreamed (submitted back to back, fresh map): %.2f s, %.0f scans/s, %.2f M rays/s; "
        "host %.3f ms per submit; %.2f submissions and %.2f host waits per scan; %zu scans run "
        "again; map %s OctoMap's. OctoMap insertPointCloud %.2f s: %.2fx.\n",
        stream.wall_s, scan_count / stream.wall_s,
        static_cast<double>(total_points) / stream.wall_s * 1e-6,
        stream.submit_ms / scan_count, static_cast<double>(stream.submissions) / scan_count,
        static_cast<double>(stream.waits) / scan_count, stream.reruns,
        same ? "equals" : "DIFFERS FROM", om_total * 1e-3, om_total * 1e-3 / stream.wall_s);
    if (context.device().ray_query_enabled) {
      // The same stream with ScanRays::kRayTracing: per scan, the structure (boxes and build)
      // and the rays traced through it, in the scan's own submission.
      const Stream rt = streamGraph(context, o, res, graph, ScanRays::kRayTracing);
      const bool rt_same = rt.map && *toOcTree(*rt.map) == tree;
      const double n = static_cast<double>(graph.size());
      json.key("streamed_rt").beginObject();
      json.field("wall_total_s", rt.wall_s).field("scans_per_s", n / rt.wall_s);
      json.field("boxes_ms_per_scan", rt.boxes_ms / n).field("build_ms_per_scan", rt.build_ms / n);
      json.field("trace_ms_per_scan", rt.trace_ms / n);
      json.field("rest_ms_per_scan", (rt.device_ms - rt.boxes_ms - rt.build_ms - rt.trace_ms) / n);
      json.field("equals_octomap", rt_same);
      json.endObject();
      std::printf(
          "\nStreamed with ScanRays::kRayTracing (fresh map): %.2f s, %.0f scans/s; per scan "
          "%.2f ms boxes, %.2f ms structure build, %.2f ms ray shooting, %.2f ms the rest "
          "(device); map %s OctoMap's. Walk streamed: %.2f s; OctoMap insertPointCloud %.2f s.\n",
          rt.wall_s, n / rt.wall_s, rt.boxes_ms / n, rt.build_ms / n, rt.trace_ms / n,
          (rt.device_ms - rt.boxes_ms - rt.build_ms - rt.trace_ms) / n,
          rt_same ? "equals" : "DIFFERS FROM", stream.wall_s, om_total * 1e-3);
    }
    json.endObject();
  }
  json.endArray().endObject();

  std::printf("\n### fr079: mean per scan\n");
  printScanTable("resolution", labels, means);
  printStageTable("resolution (octovk device ms)", labels, means);
  std::vector<std::string> memory_labels;
  for (const std::string& l : labels) memory_labels.push_back("FR-079, " + l);
  printMemoryTable(memory_labels, memories);

  std::printf("\n### fr079: time per scan against map size (first %zu scans vs last %zu)\n", win,
              win);
  std::printf(
      "\n| resolution | system | first: ms/scan | last: ms/scan | last / first | "
      "first: us/point | last: us/point | last / first (per point) | nodes after first "
      "/ at end |\n| --- | --- | --: | --: | --: | --: | --: | --: | --: |\n");
  for (std::size_t i = 0; i < labels.size(); ++i) {
    const auto& [first, last] = windows[i];
    std::printf(
        "| %s | OctoMap insertPointCloud | %.3f | %.3f | %.2f | %.3f | %.3f | %.2f | "
        "%zu / %zu |\n",
        labels[i].c_str(), first.om_ms_per_scan, last.om_ms_per_scan,
        last.om_ms_per_scan / first.om_ms_per_scan, first.om_us_per_point, last.om_us_per_point,
        last.om_us_per_point / first.om_us_per_point, first.nodes_at_end, last.nodes_at_end);
    std::printf("| %s | octovk wall | %.3f | %.3f | %.2f | %.3f | %.3f | %.2f | %zu / %zu |\n",
                labels[i].c_str(), first.vk_ms_per_scan, last.vk_ms_per_scan,
                last.vk_ms_per_scan / first.vk_ms_per_scan, first.vk_us_per_point,
                last.vk_us_per_point, last.vk_us_per_point / first.vk_us_per_point,
                first.nodes_at_end, last.nodes_at_end);
    std::printf(
        "| %s | octovk device (of which leaf boxes) | %.3f (%.3f) | %.3f (%.3f) | %.2f | "
        "| | | |\n",
        labels[i].c_str(), first.vk_device_ms_per_scan, first.vk_leaf_boxes_ms_per_scan,
        last.vk_device_ms_per_scan, last.vk_leaf_boxes_ms_per_scan,
        last.vk_device_ms_per_scan / first.vk_device_ms_per_scan);
  }
  std::fflush(stdout);
}

// ---- scaling: rays per scan and maximum range ----------------------------------------------

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
