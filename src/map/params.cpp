#include <cmath>
#include <sstream>

#include "map/map_buffers.hpp"
#include "octovk/octovk.hpp"

namespace octovk {

namespace {
bool inOpenUnit(double p) { return std::isfinite(p) && p > 0.0 && p < 1.0; }
}  // namespace

std::size_t MapParams::minDeviceBytes() const {
  return MapBuffers::initialBytes(poolBlockLimit(max_nodes), payload);
}

std::string MapParams::validate() const {
  std::ostringstream why;
  if (!std::isfinite(resolution) || resolution <= 0.0) {
    why << "resolution must be a positive number of metres (got " << resolution << ")";
  } else if (resolution < 1e-4 || resolution > 1e3) {
    why << "resolution " << resolution << " m is outside the supported 0.0001 .. 1000 m";
  } else if (!inOpenUnit(prob_hit) || prob_hit < 0.5) {
    why << "prob_hit must lie in [0.5, 1) (got " << prob_hit << ")";
  } else if (!inOpenUnit(prob_miss) || prob_miss > 0.5) {
    why << "prob_miss must lie in (0, 0.5] (got " << prob_miss << ")";
  } else if (!inOpenUnit(clamping_min) || !inOpenUnit(clamping_max) ||
             clamping_min >= clamping_max) {
    why << "clamping bounds must satisfy 0 < clamping_min < clamping_max < 1 (got " << clamping_min
        << ", " << clamping_max << ")";
  } else if (!inOpenUnit(occupancy_threshold)) {
    why << "occupancy_threshold must lie in (0, 1) (got " << occupancy_threshold << ")";
  } else if (static_cast<std::uint32_t>(cast_ray_backend) >
             static_cast<std::uint32_t>(CastRayBackend::kRayTracingPipeline)) {
    why << "cast_ray_backend " << static_cast<std::uint32_t>(cast_ray_backend)
        << " is not a CastRayBackend (kAuto, kWalk, kRayTracing, kRayQuery, "
           "kRayTracingPipeline)";
  } else if (static_cast<std::uint32_t>(scan_rays) < static_cast<std::uint32_t>(ScanRays::kWalk) ||
             static_cast<std::uint32_t>(scan_rays) >
                 static_cast<std::uint32_t>(ScanRays::kRayTracingPipeline)) {
    why << "scan_rays " << static_cast<std::uint32_t>(scan_rays)
        << " is not a ScanRays (kWalk = 1, kRayTracing = 2, kRayQuery = 3, "
           "kRayTracingPipeline = 4)";
  } else if (max_device_bytes != 0 && max_device_bytes < minDeviceBytes()) {
    why << "max_device_bytes " << max_device_bytes << " is less than an empty map holds on the "
        << "device: at least " << minDeviceBytes() << " bytes (MapParams::minDeviceBytes()); "
        << "raise it, or use 0 for no cap";
  }
  return why.str();
}

}  // namespace octovk

namespace octovk {

const char* treeTypeName(Payload payload) {
  switch (payload) {
    case Payload::kColor:
      return "ColorOcTree";
    case Payload::kStamp:
      return "OcTreeStamped";
    case Payload::kNone:
      break;
  }
  return "OcTree";
}

}  // namespace octovk
