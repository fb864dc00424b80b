// The two ways the ray-tracing tests trace rays, CastRayBackend / ScanRays kRayQuery (ray queries
// in compute passes) and kRayTracingPipeline (a ray-tracing pipeline): each test of the traced
// passes runs on both, each where the device has it (skipped with the reason elsewhere, failed
// where the run expects ray tracing: OCTOVK_EXPECT_RAY_QUERY, Mesa 25's lavapipe has both).
#pragma once

#include <string>

#include "test_support.hpp"

namespace octovk::test {

/// The ray-tracing paths, as test-name suffixes.
inline const char* tracePathName(CastRayBackend path) {
  switch (path) {
    case CastRayBackend::kWalk:
      return "Walk";
    case CastRayBackend::kRayQuery:
      return "RayQuery";
    case CastRayBackend::kRayTracingPipeline:
      return "RtPipeline";
    case CastRayBackend::kRayTracing:
      return "RayTracing";
    default:
      return "Auto";
  }
}
inline const char* tracePathName(ScanRays path) {
  return tracePathName(static_cast<CastRayBackend>(path));  // numbered alike
}

/// Whether the device of `ctx` traces rays through `path` (kRayQuery or kRayTracingPipeline).
inline bool hasTracePath(Context& ctx, CastRayBackend path) {
  return path == CastRayBackend::kRayTracingPipeline ? ctx.device().ray_tracing_pipeline
                                                     : ctx.device().ray_query_enabled;
}

}  // namespace octovk::test

/// Skips a test of the ray-tracing path `path` (a CastRayBackend or ScanRays) with the reason on
/// a device without it; fails it there when the run expects ray tracing.
#define OCTOVK_REQUIRE_TRACE_PATH(ctx, path)                                                     \
  if (!::octovk::test::hasTracePath((ctx), static_cast<::octovk::CastRayBackend>(path))) {       \
    if (::octovk::test::rayQueryExpected())                                                      \
      FAIL() << "OCTOVK_EXPECT_RAY_QUERY is set but device '" << (ctx).device().name << "' ("    \
             << (ctx).device().driver << ") cannot trace rays through "                          \
             << ::octovk::test::tracePathName(path);                                             \
    GTEST_SKIP() << "device '" << (ctx).device().name << "' (" << (ctx).device().driver          \
                 << ") has no " << ::octovk::test::tracePathName(path)                           \
                 << " path (VK_KHR_acceleration_structure with VK_KHR_ray_query / "              \
                 << "VK_KHR_ray_tracing_pipeline): not tested here (Mesa 25 lavapipe has both)"; \
  }
