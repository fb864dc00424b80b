// The benchmark's workloads: each runs OctoMap and octovk on the same scans in this process,
// prints Markdown tables on stdout and writes its results into the JSON document.
#pragma once

#include <cstddef>
#include <string>
#include <vector>

#include "json.hpp"
#include "octovk/octovk.hpp"

namespace octovk::bench {

struct BenchOptions {
  std::vector<double> resolutions;  ///< empty: each workload's own list
  int repeat = 1;                   ///< fresh maps per measurement; the median is reported
  bool quick = false;
  bool compute_update = true;  ///< also time OcTree::computeUpdate on its own
  bool leaf_boxes_every_scan = true;
  std::string scandat_path;
  std::string fr079_path;
  std::size_t fr079_scans = 0;  ///< 0: all
  double scaling_resolution = 0.05;
  std::size_t lookups = 0;     ///< points for the queries workload; 0: its default
  std::size_t query_rays = 0;  ///< rays per castRay configuration; 0: its default
};

/// A way of tracing rays the device of a Context runs (ScanRays / CastRayBackend kRayQuery or
/// kRayTracingPipeline, numbered alike), with its names in tables and in the JSON.
struct TracePath {
  ScanRays scan_rays;
  CastRayBackend cast_ray_backend;
  const char* label;  ///< in tables: "ray queries", "rt pipeline"
  const char* key;    ///< JSON prefix: "rt" (ray queries, as before the pipeline), "rt_pipeline"
};
/// The ray-tracing paths the device of `context` runs, ray queries first: none, one or both.
std::vector<TracePath> tracePaths(Context& context);

void runPaper(Context& context, const BenchOptions& options, JsonWriter& json);
void runScanDat(Context& context, const BenchOptions& options, JsonWriter& json);
void runFr079(Context& context, const BenchOptions& options, JsonWriter& json);
void runScaling(Context& context, const BenchOptions& options, JsonWriter& json);
/// Point lookups and castRay on the paper map at 0.05 m (in queries.cpp).
void runQueries(Context& context, const BenchOptions& options, JsonWriter& json);
/// DistanceField against dynamicEDT3D's DynamicEDTOctomap on the paper map at 0.05 m
/// (distance.cpp).
void runDistance(Context& context, const BenchOptions& options, JsonWriter& json);
/// clearBox and keepBox against OctoMap's loops on the paper map at 0.05 m (edits.cpp).
void runEdits(Context& context, const BenchOptions& options, JsonWriter& json);
/// Colour and time stamps: OcTree, ColorOcTree and OcTreeStamped against OccupancyMap, ColorMap
/// and StampedMap on the first FR-079 scans (payloads.cpp).
void runPayloads(Context& context, const BenchOptions& options, JsonWriter& json);

}  // namespace octovk::bench
