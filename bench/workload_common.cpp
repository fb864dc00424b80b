#include "workload_common.hpp"

#include <algorithm>
#include <cmath>
#include <cstdio>

namespace octovk::bench {

double median(std::vector<double> v) {
  std::sort(v.begin(), v.end());
  const std::size_t n = v.size();
  return n % 2 ? v[n / 2] : 0.5 * (v[n / 2 - 1] + v[n / 2]);
}

namespace {

MapParams paramsFor(double resolution) {
  MapParams p;
  p.resolution = resolution;
  return p;
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

std::size_t cells(const ScanTiming& t) { return t.vk.free_cells + t.vk.occupied_cells; }

}  // namespace

double secondsSince(Clock::time_point start) {
  return std::chrono::duration<double>(Clock::now() - start).count();
}

std::vector<double> resolutionsFor(const BenchOptions& o, std::vector<double> full,
                                   std::vector<double> quick) {
  if (!o.resolutions.empty()) return o.resolutions;
  return o.quick ? quick : full;
}

OccupancyMap makeMap(Context& context, const BenchOptions& o, double resolution, ScanRays rays) {
  MapParams params = paramsFor(resolution);
  params.scan_rays = rays;
  OccupancyMap map(context, params);
  map.setLeafBoxesEveryScan(o.leaf_boxes_every_scan);
  return map;
}

std::vector<TracePath> tracePaths(Context& context) {
  std::vector<TracePath> paths;
  if (context.device().ray_query_enabled)
    paths.push_back({ScanRays::kRayQuery, CastRayBackend::kRayQuery, "ray queries", "rt"});
  // Offered is enabled: the bench's Context keeps ContextOptions::enable_ray_query on.
  if (context.device().ray_tracing_pipeline)
    paths.push_back({ScanRays::kRayTracingPipeline, CastRayBackend::kRayTracingPipeline,
                     "rt pipeline", "rt_pipeline"});
  return paths;
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
                d.prune_ms, d.leaf_boxes_ms, d.total_ms(), scans[i].vk.wall_ms,
                scans[i].vk.wall_ms - d.total_ms(), scans[i].vk.cell_set_attempts);
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
  row("octovk device total", [&](const ScanTiming& m) { return ms(m.vk.device.total_ms()); });
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

}  // namespace octovk::bench
