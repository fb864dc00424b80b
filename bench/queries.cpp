// The queries workload: point lookups and castRay on the same map, OctoMap's OcTree against
// octovk's OccupancyMap, with every answer compared.
#include <fcntl.h>
#include <octomap/OcTree.h>
#include <unistd.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <functional>
#include <memory>
#include <numbers>
#include <span>
#include <string>
#include <vector>

#include "building.hpp"
#include "measure.hpp"
#include "workloads.hpp"

namespace octovk::bench {

namespace {

using Clock = std::chrono::steady_clock;

constexpr double kResolution = 0.05;
constexpr std::size_t kViewWidth = 320;
constexpr std::size_t kViewHeight = 240;
constexpr std::size_t kShownMismatches = 5;

double msSince(Clock::time_point start) {
  return std::chrono::duration<double, std::milli>(Clock::now() - start).count();
}

double median(std::vector<double> v) {
  std::sort(v.begin(), v.end());
  const std::size_t n = v.size();
  return n % 2 ? v[n / 2] : 0.5 * (v[n / 2 - 1] + v[n / 2]);
}

// OctoMap reports every ray that reaches the map's border on stderr (a formatted write and a
// flush); during its timed loop those lines go to /dev/null so they do not flood the terminal.
class StderrToDevNull {
 public:
  StderrToDevNull() {
    std::fflush(stderr);
    saved_ = ::dup(STDERR_FILENO);
    const int null_fd = ::open("/dev/null", O_WRONLY);
    if (saved_ >= 0 && null_fd >= 0) ::dup2(null_fd, STDERR_FILENO);
    if (null_fd >= 0) ::close(null_fd);
  }
  ~StderrToDevNull() {
    std::fflush(stderr);
    if (saved_ >= 0) {
      ::dup2(saved_, STDERR_FILENO);
      ::close(saved_);
    }
  }
  StderrToDevNull(const StderrToDevNull&) = delete;
  StderrToDevNull& operator=(const StderrToDevNull&) = delete;

 private:
  int saved_ = -1;
};

// What a user of OctoMap writes to get octovk's answer: search(), then isNodeOccupied().
std::vector<Lookup> octomapSearch(const octomap::OcTree& tree,
                                  std::span<const Eigen::Vector3f> points) {
  std::vector<Lookup> out(points.size());
  for (std::size_t i = 0; i < points.size(); ++i) {
    const Eigen::Vector3f& p = points[i];
    const octomap::OcTreeNode* node = tree.search(p.x(), p.y(), p.z());
    if (node)
      out[i] = {tree.isNodeOccupied(node) ? CellState::kOccupied : CellState::kFree,
                node->getLogOdds(), 0};
  }
  return out;
}

std::vector<RayHit> octomapCastRays(const octomap::OcTree& tree, std::span<const Ray> rays) {
  std::vector<RayHit> out(rays.size());
  StderrToDevNull quiet;
  for (std::size_t i = 0; i < rays.size(); ++i) {
    const Ray& r = rays[i];
    const octomap::point3d origin(r.origin.x(), r.origin.y(), r.origin.z());
    octomap::point3d end = origin;  // OctoMap leaves `end` untouched on some early returns
    const bool hit =
        tree.castRay(origin, octomap::point3d(r.direction.x(), r.direction.y(), r.direction.z()),
                     end, r.ignore_unknown, r.max_range_m);
    out[i] = {hit, Eigen::Vector3f(end.x(), end.y(), end.z())};
  }
  return out;
}

// Equal as the oracle tests compare: ==, with NaN equal to NaN.
bool same(float a, float b) { return a == b || (std::isnan(a) && std::isnan(b)); }

const char* stateName(CellState s) {
  switch (s) {
    case CellState::kFree:
      return "free";
    case CellState::kOccupied:
      return "occupied";
    default:
      return "unknown";
  }
}

// One batch of queries timed on both systems: the median of `repeat` calls each.
struct QueryTiming {
  std::string label;
  std::size_t count = 0;
  double om_ms = 0.0;
  double vk_ms = 0.0;  ///< octovk as a map gets it by default (CastRayBackend::kAuto)
  // castRay: each backend: the walk (0 when not run), then each ray-tracing path the device runs
  // (tracePaths' order).
  double walk_ms = 0.0;
  std::size_t walk_mismatches = 0;
  std::vector<double> trace_ms;
  std::vector<std::size_t> trace_mismatches;
  std::size_t mismatches = 0;
  std::vector<std::string> first_mismatches;  ///< the first few, spelled out
  std::string answers;                        ///< what the answers were, in words

  double omPerSecond() const { return om_ms > 0 ? static_cast<double>(count) / (om_ms * 1e-3) : 0; }
  double vkPerSecond() const { return vk_ms > 0 ? static_cast<double>(count) / (vk_ms * 1e-3) : 0; }
};

template <class Result>
void timeBoth(int repeat, QueryTiming& t, const std::function<std::vector<Result>()>& octomap_run,
              const std::function<std::vector<Result>()>& octovk_run, std::vector<Result>& om_out,
              std::vector<Result>& vk_out) {
  std::vector<double> om_ms, vk_ms;
  for (int rep = 0; rep < repeat; ++rep) {
    auto start = Clock::now();
    om_out = octomap_run();
    om_ms.push_back(msSince(start));
    start = Clock::now();
    vk_out = octovk_run();
    vk_ms.push_back(msSince(start));
  }
  t.om_ms = median(om_ms);
  t.vk_ms = median(vk_ms);
}

// 1234567.8 -> "1,234,568".
std::string grouped(double v) {
  const std::string digits = std::to_string(std::llround(std::abs(v)));
  std::string out = v < 0 ? "-" : "";
  for (std::size_t i = 0; i < digits.size(); ++i) {
    if (i > 0 && (digits.size() - i) % 3 == 0) out += ',';
    out += digits[i];
  }
  return out;
}

std::string fmt(const char* format, auto... args) {
  char buf[512];
  std::snprintf(buf, sizeof(buf), format, args...);
  return buf;
}

void compareLookups(std::span<const Eigen::Vector3f> points, const std::vector<Lookup>& om,
                    const std::vector<Lookup>& vk, QueryTiming& t) {
  double by_state[3] = {0, 0, 0};
  for (std::size_t i = 0; i < points.size(); ++i) {
    ++by_state[static_cast<std::uint32_t>(om[i].state)];
    if (i < vk.size() && om[i].state == vk[i].state && same(om[i].log_odds, vk[i].log_odds))
      continue;
    ++t.mismatches;
    if (t.first_mismatches.size() < kShownMismatches) {
      const Eigen::Vector3f& p = points[i];
      t.first_mismatches.push_back(
          i < vk.size()
              ? fmt("lookup %zu at (%.9g, %.9g, %.9g): OctoMap %s %.9g, octovk %s %.9g (depth %u)",
                    i, p.x(), p.y(), p.z(), stateName(om[i].state), om[i].log_odds,
                    stateName(vk[i].state), vk[i].log_odds, vk[i].depth)
              : fmt("lookup %zu: octovk returned only %zu answers", i, vk.size()));
    }
  }
  const double n = static_cast<double>(points.size());
  t.answers = fmt("unknown %.1f%%, free %.1f%%, occupied %.1f%%", 100.0 * by_state[0] / n,
                  100.0 * by_state[1] / n, 100.0 * by_state[2] / n);
}

void compareRays(std::span<const Ray> rays, const std::vector<RayHit>& om,
                 const std::vector<RayHit>& vk, QueryTiming& t) {
  std::size_t hits = 0;
  double length = 0;
  for (std::size_t i = 0; i < rays.size(); ++i) {
    hits += om[i].hit;
    length += static_cast<double>((om[i].end - rays[i].origin).norm());
    if (i < vk.size() && om[i].hit == vk[i].hit && same(om[i].end.x(), vk[i].end.x()) &&
        same(om[i].end.y(), vk[i].end.y()) && same(om[i].end.z(), vk[i].end.z()))
      continue;
    ++t.mismatches;
    if (t.first_mismatches.size() < kShownMismatches) {
      const Ray& r = rays[i];
      t.first_mismatches.push_back(
          i < vk.size()
              ? fmt("ray %zu from (%.9g, %.9g, %.9g) along (%.9g, %.9g, %.9g): OctoMap %s "
                    "(%.9g, %.9g, %.9g), octovk %s (%.9g, %.9g, %.9g)",
                    i, r.origin.x(), r.origin.y(), r.origin.z(), r.direction.x(), r.direction.y(),
                    r.direction.z(), om[i].hit ? "hit" : "no hit", om[i].end.x(), om[i].end.y(),
                    om[i].end.z(), vk[i].hit ? "hit" : "no hit", vk[i].end.x(), vk[i].end.y(),
                    vk[i].end.z())
              : fmt("ray %zu: octovk returned only %zu answers", i, vk.size()));
    }
  }
  const double n = static_cast<double>(rays.size());
  t.answers = fmt("hit %.1f%%, mean length to `end` %.3g m", 100.0 * static_cast<double>(hits) / n,
                  length / n);
}

void writeJson(JsonWriter& json, const QueryTiming& t, const std::vector<TracePath>& paths = {}) {
  json.field("count", t.count)
      .field("octomap_ms", t.om_ms)
      .field("octovk_wall_ms", t.vk_ms)
      .field("octomap_per_s", t.omPerSecond())
      .field("octovk_per_s", t.vkPerSecond())
      .field("octomap_over_octovk", t.vk_ms > 0 ? t.om_ms / t.vk_ms : 0.0)
      .field("mismatches", t.mismatches)
      .field("answers", t.answers);
  if (t.walk_ms > 0)
    json.field("walk_wall_ms", t.walk_ms)
        .field("octomap_over_walk", t.om_ms / t.walk_ms)
        .field("walk_mismatches", t.walk_mismatches);
  // Ray queries keep the names they had before the pipeline ("ray_tracing_*").
  for (std::size_t p = 0; p < t.trace_ms.size(); ++p) {
    const std::string name =
        paths[p].cast_ray_backend == CastRayBackend::kRayQuery ? "ray_tracing" : paths[p].key;
    json.field(name + "_wall_ms", t.trace_ms[p])
        .field("octomap_over_" + name, t.om_ms / t.trace_ms[p])
        .field(name + "_mismatches", t.trace_mismatches[p]);
  }
  json.key("first_mismatches").beginArray();
  for (const std::string& m : t.first_mismatches) json.value(m);
  json.endArray();
}

}  // namespace

void runQueries(Context& context, const BenchOptions& o, JsonWriter& json) {
  const std::size_t lookup_count = o.lookups ? o.lookups : (o.quick ? 100'000 : 1'000'000);
  const std::size_t ray_count = o.query_rays ? o.query_rays : (o.quick ? 2'000 : 100'000);
  const Building building;
  const std::vector<SensorPose> views = paperViews();

  // The paper workload's map at 0.05 m: its six views, in order, into both systems.
  octomap::OcTree tree(kResolution);
  MapParams params;
  params.resolution = kResolution;
  params.cast_ray_backend = CastRayBackend::kWalk;
  OccupancyMap map(context, params);
  map.setLeafBoxesEveryScan(o.leaf_boxes_every_scan);
  for (std::size_t i = 0; i < views.size(); ++i) {
    std::fprintf(stderr, "queries: building the map, view %zu/%zu\n", i + 1, views.size());
    const std::vector<Eigen::Vector3f> cloud =
        rangeImage(building, views[i], kViewWidth, kViewHeight);
    measureWorldScan(tree, map, cloud, views[i].position.cast<float>(), -1.0, false);
  }
  const std::size_t om_nodes = tree.size(), vk_nodes = map.nodeCount();

  // Lookups: uniform in the building's bounding box. Rays: uniform directions on the sphere,
  // from the six sensor poses in turn; the same rays in every configuration.
  Rng rng(20261123);
  const Box box = building.bounds();
  std::vector<Eigen::Vector3f> points(lookup_count);
  for (Eigen::Vector3f& p : points)
    p = Eigen::Vector3f(static_cast<float>(rng.uniform(box.lo.x(), box.hi.x())),
                        static_cast<float>(rng.uniform(box.lo.y(), box.hi.y())),
                        static_cast<float>(rng.uniform(box.lo.z(), box.hi.z())));
  std::vector<Ray> rays(ray_count);
  for (std::size_t i = 0; i < ray_count; ++i) {
    const double z = rng.uniform(-1.0, 1.0);
    const double phi = rng.uniform(0.0, 2.0 * std::numbers::pi);
    const double r = std::sqrt(1.0 - z * z);
    rays[i].origin = views[i % views.size()].position.cast<float>();
    rays[i].direction =
        Eigen::Vector3f(static_cast<float>(r * std::cos(phi)),
                        static_cast<float>(r * std::sin(phi)), static_cast<float>(z));
  }

  std::printf("\n## queries: point lookups and castRay on the paper map at %g m\n", kResolution);
  std::printf(
      "\nThe map: the paper workload's %zu views of %zux%zu rays inserted in order into both "
      "systems; %s. Lookups: %s points uniform in the building's bounding box (%.2f..%.2f, "
      "%.2f..%.2f, %.2f..%.2f m). Rays: %s uniform random directions from the %zu sensor poses "
      "in turn, the same rays in every configuration.\n",
      views.size(), kViewWidth, kViewHeight, parityLine(om_nodes, vk_nodes).c_str(),
      grouped(static_cast<double>(lookup_count)).c_str(), box.lo.x(), box.hi.x(), box.lo.y(),
      box.hi.y(), box.lo.z(), box.hi.z(), grouped(static_cast<double>(ray_count)).c_str(),
      views.size());
  std::printf(
      "\nTimes: the median of %d call(s) per batch. OctoMap: a loop of `search` + "
      "`isNodeOccupied` (or `castRay`) over the batch, single-threaded, results into a vector. "
      "octovk: the wall time of one `search(points)` (or `castRays(rays)`) call, which includes "
      "staging the queries, uploading them, the dispatches, downloading and unpacking the "
      "results: what a user pays. One untimed call of the same size comes first (it sizes the "
      "query buffers and builds the pipelines). Mismatches: answers that differ in state or "
      "log-odds (lookups), or in the hit flag or any coordinate of `end` (castRay), compared with "
      "==.\n",
      o.repeat);
  std::fflush(stdout);

  json.key("queries").beginObject();
  json.field("resolution", kResolution).field("views", views.size()).field("repeat", o.repeat);
  json.field("octomap_nodes", om_nodes).field("octovk_nodes", vk_nodes);
  json.field("octovk_timing",
             "wall time of one search/castRays call: staging, upload, dispatch, download, unpack");

  std::vector<QueryTiming> rows;
  {
    std::fprintf(stderr, "queries: %zu lookups\n", lookup_count);
    map.search(points);
    QueryTiming t;
    t.label = "lookup (`search` + `isNodeOccupied`)";
    t.count = lookup_count;
    std::vector<Lookup> om, vk;
    timeBoth<Lookup>(
        o.repeat, t, [&] { return octomapSearch(tree, points); },
        [&] { return map.search(points); }, om, vk);
    compareLookups(points, om, vk, t);
    rows.push_back(t);
    json.key("lookups").beginObject();
    writeJson(json, t);
    json.endObject();
  }

  // castRay on each backend: the walk on `map`, and each ray-tracing path the device runs (ray
  // queries, a ray-tracing pipeline) on a copy of it (uploaded from its download: the same
  // tree). The default (kAuto) is one of them.
  const std::vector<TracePath> paths = tracePaths(context);
  MapParams auto_params = params;
  auto_params.cast_ray_backend = CastRayBackend::kAuto;
  const CastRayBackend auto_backend = OccupancyMap(context, auto_params).castRayInfo().backend;
  std::vector<std::unique_ptr<OccupancyMap>> traced;
  for (const TracePath& path : paths) {
    MapParams rt_params = params;
    rt_params.cast_ray_backend = path.cast_ray_backend;
    traced.push_back(std::make_unique<OccupancyMap>(context, rt_params));
    traced.back()->upload(map.download());
  }
  const auto backendLabel = [&](CastRayBackend b) {
    for (const TracePath& path : paths)
      if (path.cast_ray_backend == b) return path.label;
    return "walk";
  };
  {
    // Sizes the query buffers for the ray batch at next to no cost: every ray ends at once. On
    // the ray-tracing maps this first call also builds the acceleration structure (and the
    // pipeline): timed.
    std::vector<Ray> short_rays = rays;
    for (Ray& r : short_rays) r.max_range_m = 1e-3;
    map.castRays(short_rays);
    for (std::size_t p = 0; p < paths.size(); ++p) {
      const auto start = Clock::now();
      traced[p]->castRays(short_rays);
      const double wall_ms = msSince(start);
      const OccupancyMap::CastRayInfo info = traced[p]->castRayInfo();
      std::printf(
          "\nRay-tracing backend (%s): acceleration structure over %s occupied-leaf boxes, built "
          "on the device in %.1f ms (boxes %.1f ms, BLAS + TLAS %.1f ms; device timestamps), "
          "%.1f MiB; first castRays call %.1f ms wall.\n",
          paths[p].label, grouped(static_cast<double>(info.occupied_boxes)).c_str(),
          info.last_build_ms, info.last_boxes_ms, info.last_build_ms - info.last_boxes_ms,
          static_cast<double>(info.device_bytes) / (1 << 20), wall_ms);
      // Ray queries keep the key they had before the pipeline.
      json.key(paths[p].cast_ray_backend == CastRayBackend::kRayQuery
                   ? std::string("accel_build")
                   : std::string(paths[p].key) + "_accel_build")
          .beginObject();
      json.field("device_ms", info.last_build_ms)
          .field("boxes_ms", info.last_boxes_ms)
          .field("structures_ms", info.last_build_ms - info.last_boxes_ms)
          .field("occupied_boxes", info.occupied_boxes)
          .field("device_bytes", info.device_bytes)
          .field("first_call_wall_ms", wall_ms);
      json.endObject();
    }
    if (paths.empty())
      std::printf(
          "\nRay-tracing backend: not run (the device has neither ray queries nor ray-tracing "
          "pipelines).\n");
  }
  json.field("default_cast_ray_backend", auto_backend == CastRayBackend::kWalk ? "walk"
                                         : auto_backend == CastRayBackend::kRayQuery
                                             ? "ray_tracing"
                                             : "rt_pipeline");
  json.key("cast_ray").beginArray();
  for (const double max_range : {10.0, -1.0}) {
    for (const bool ignore_unknown : {false, true}) {
      std::fprintf(stderr, "queries: %zu rays, max range %s, ignore_unknown %s\n", ray_count,
                   max_range > 0 ? fmt("%g m", max_range).c_str() : "unlimited",
                   ignore_unknown ? "true" : "false");
      for (Ray& r : rays) {
        r.max_range_m = max_range;
        r.ignore_unknown = ignore_unknown;
      }
      QueryTiming t;
      t.label = fmt("castRay, max range %s, ignore_unknown %s",
                    max_range > 0 ? fmt("%g m", max_range).c_str() : "unlimited",
                    ignore_unknown ? "true" : "false");
      t.count = ray_count;
      std::vector<RayHit> om, vk;
      timeBoth<RayHit>(
          o.repeat, t, [&] { return octomapCastRays(tree, rays); },
          [&] { return map.castRays(rays); }, om, vk);
      compareRays(rays, om, vk, t);
      t.walk_ms = t.vk_ms;
      t.walk_mismatches = t.mismatches;
      for (std::size_t p = 0; p < paths.size(); ++p) {
        std::vector<double> rt_ms;
        std::vector<RayHit> rt;
        for (int rep = 0; rep < o.repeat; ++rep) {
          const auto start = Clock::now();
          rt = traced[p]->castRays(rays);
          rt_ms.push_back(msSince(start));
        }
        t.trace_ms.push_back(median(rt_ms));
        QueryTiming check;
        compareRays(rays, om, rt, check);
        t.trace_mismatches.push_back(check.mismatches);
        for (const std::string& m : check.first_mismatches)
          if (t.first_mismatches.size() < 2 * kShownMismatches)
            t.first_mismatches.push_back(std::string(paths[p].label) + ": " + m);
        t.mismatches += check.mismatches;
        if (auto_backend == paths[p].cast_ray_backend) t.vk_ms = t.trace_ms.back();
      }
      rows.push_back(t);
      json.newline().beginObject();
      json.field("max_range_m", max_range).field("ignore_unknown", ignore_unknown);
      writeJson(json, t, paths);
      json.endObject();
    }
  }
  json.endArray().endObject();

  std::printf(
      "\n| query | count | OctoMap s | octovk wall s | OctoMap queries/s | octovk queries/s | "
      "OctoMap / octovk (time) | mismatches | answers |\n"
      "| --- | --: | --: | --: | --: | --: | --: | --: | --- |\n");
  for (const QueryTiming& t : rows)
    std::printf("| %s | %s | %.3f | %.3f | %s | %s | %.2fx | %zu | %s |\n", t.label.c_str(),
                grouped(static_cast<double>(t.count)).c_str(), t.om_ms * 1e-3, t.vk_ms * 1e-3,
                grouped(t.omPerSecond()).c_str(), grouped(t.vkPerSecond()).c_str(),
                t.om_ms / t.vk_ms, t.mismatches, t.answers.c_str());
  std::printf(
      "\ncastRay by backend (octovk's default here: %s):\n\n| query | OctoMap s | walk s | "
      "OctoMap / walk | walk mismatches |",
      backendLabel(auto_backend));
  for (const TracePath& path : paths)
    std::printf(" %s s | OctoMap / %s | %s mismatches |", path.label, path.label, path.label);
  std::printf("\n| --- | --: | --: | --: | --: |");
  for (std::size_t p = 0; p < paths.size(); ++p) std::printf(" --: | --: | --: |");
  std::printf("\n");
  for (const QueryTiming& t : rows) {
    if (t.walk_ms <= 0) continue;
    std::printf("| %s | %.3f | %.3f | %.2fx | %zu |", t.label.c_str(), t.om_ms * 1e-3,
                t.walk_ms * 1e-3, t.om_ms / t.walk_ms, t.walk_mismatches);
    for (std::size_t p = 0; p < t.trace_ms.size(); ++p)
      std::printf(" %.3f | %.2fx | %zu |", t.trace_ms[p] * 1e-3, t.om_ms / t.trace_ms[p],
                  t.trace_mismatches[p]);
    std::printf("\n");
  }
  if (paths.empty()) std::printf("\n(No ray-tracing column: the device traces no rays.)\n");
  std::size_t total_mismatches = 0;
  for (const QueryTiming& t : rows) total_mismatches += t.mismatches;
  std::printf("\nAnswers that differ from OctoMap's: %zu of %zu%s\n", total_mismatches,
              lookup_count + 4 * (1 + paths.size()) * ray_count,
              total_mismatches ? " (MISMATCH: first ones below)" : ".");
  for (const QueryTiming& t : rows)
    for (const std::string& m : t.first_mismatches)
      std::printf("- %s: %s\n", t.label.c_str(), m.c_str());
  std::fflush(stdout);
}

}  // namespace octovk::bench
