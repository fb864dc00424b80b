// castRay through the acceleration structure over the map's boxes (the ray-tracing backend):
// OccupancyOcTreeBase::castRay for each query ray, with the same answer as cast_ray.comp. Three
// shaders are built from this file: cast_ray_rt.comp (OCTOVK_CAST_RAY_TRACE: ray queries) and
// cast_ray_rt.rgen (OCTOVK_CAST_RAY_TRACE and OCTOVK_RAY_PIPELINE: the ray generation shader of
// a ray-tracing pipeline) answer the rays that ignore unknown space, tracing through
// accel_trace.glsl's nearestBox; cast_ray_jump.comp the others, without ray queries (on
// lavapipe a shader with ray queries costs more per invocation, and such rays mostly end within
// a few cells, at the edge of what a sensor saw, where unknown regions are many and small): the
// structure holds only the occupied leaves.
//
// A ray query finds the nearest box along the ray that could end the walk: an occupied leaf
// (unknown space does not end it). The boxes are enlarged (accel_boxes.comp), so every cell
// OctoMap's walk enters before the enlarged box's entry parameter is free or unknown, inside the
// map and within the max range once those limits are also kept. The walk jumps there exactly
// (walkJumpTo: the same tMax bits as stepping), then steps with tree lookups, exactly as OctoMap
// does, until it ends or has passed the box; then the next box is traced. Inside a node a lookup
// found free (or unknown, when ignored), the walk jumps across the node exactly, as cast_ray does
// (walkJumpAcrossRegion). Without ray queries (cast_ray_jump) the walk only steps and jumps
// across such nodes. The walk, its lookups and jumps are ray_walk.glsl's and walk_cells.glsl's.
#define OCTOVK_NODES_READ_ONLY
#include "walk_cells.glsl"
#if defined(OCTOVK_CAST_RAY_TRACE) && !defined(OCTOVK_RAY_PIPELINE)
#define OCTOVK_RAY_QUERY
#endif
#include "accel_trace.glsl"

#ifndef OCTOVK_RAY_PIPELINE
layout(push_constant) uniform PushBlock { CastRayRtConstants pc; };
#else
OCTOVK_RAY_CONSTANTS(CastRayRtConstants);
#endif

layout(std430, binding = kBindQueryIn) buffer QueryInBuf { RayQuery rays[]; };
layout(std430, binding = kBindQueryOut) buffer QueryOutBuf { RayResult ray_results[]; };
void finish(uint i, uint hit, vec3 end) { ray_results[i] = RayResult(hit, end.x, end.y, end.z); }

// The ray's walk and its lookups (ray_walk.glsl, walk_cells.glsl).
RayWalk w;
CastRayRange range;
CellCache cache;
bool ignore_unknown;
bool jump_tried = true;  // whether the walk already tried to jump across the cached node

// One step of OctoMap's walk and what the new cell says (castRayStep): true when the ray has its
// result (written). After a new lookup, a jump across that node if it is large enough
// (walkJumpAcrossRegion: exact, and it stops before the max range's last cells).
bool stepOnce(uint i) {
  uint hit, cost;
  vec3 end;
  if (castRayStep(w, range, cache, ignore_unknown, hit, end, cost)) {
    finish(i, hit, end);
    return true;
  }
  if (cost != 0u) jump_tried = false;
  if (!jump_tried) {
    jump_tried = true;
    int no_budget = 0;
    walkJumpAcrossRegion(w, cache, range, kJumpMinShiftFree, no_budget, 0);
  }
  return false;
}

void main() {
  uint i = invocationIndex();
  if (i >= pc.ray_count) return;
  i += pc.first_ray;
  RayQuery q = rays[i];
  ignore_unknown = q.ignore_unknown != 0u;
#ifdef OCTOVK_CAST_RAY_TRACE
  if (!ignore_unknown) return;  // cast_ray_jump's
  AccelRef scene = AccelRef(pc.boxes);
#else
  if (ignore_unknown) return;  // cast_ray_rt's
#endif

  // Start, as cast_ray.comp.
  cache = walkEmptyCache();
  uint hit;
  vec3 end;
  if (castRayStart(q, w, cache, range, hit, end)) {
    finish(i, hit, end);
    return;
  }
  jump_tried = false;  // the origin's lookup

#ifdef OCTOVK_CAST_RAY_TRACE
  // Ray parameters are in units of the walk's line (w.dir: normalised, unless OctoMap could not
  // normalise the direction; 0 on the axes the walk never steps along).
  double dir_len = walkDirLength(w);
  // Where the walk must be stepped cell by cell whatever the boxes say: near the map's border
  // (the walk stops there) and near the max range (range.test_after: the first cell beyond it
  // ends the walk).
  double t_limit = range.set ? range.test_after : 1.0e300lf;
  const double kHalfExtent = double(kTreeMaxVal) * params.resolution;
  for (int a = 0; a < 3; ++a) {
    if (w.step[a] == 0) continue;
    double bound = w.step[a] > 0 ? kHalfExtent : -kHalfExtent;
    t_limit = min(t_limit, (bound - double(w.org[a])) / double(w.dir[a]) - params.resolution);
  }
  double t_from = walkMinTMax(w) - slack(walkMinTMax(w), w.org, dir_len);
  for (;;) {
    double t_enter, t_exit;
    bool found = nearestBox(scene, w, t_from, 3.0e38, false, t_enter, t_exit);
    double target = min(found ? t_enter : 1.0e300lf, t_limit);
    target -= slack(target, w.org, dir_len);
    int no_budget = 0;
    if (target > walkMinTMax(w)) walkJumpTo(w, target, no_budget, 0);
    // Beyond the box's exit (and its slack) the next box is traced; without one the walk runs
    // to its end (border or max range, both near).
    double t_leave = found ? t_exit + 2.0lf * slack(t_exit, w.org, dir_len) : 1.0e300lf;
    do {
      if (stepOnce(i)) return;
    } while (walkMinTMax(w) <= t_leave);
    t_from = walkMinTMax(w) - slack(walkMinTMax(w), w.org, dir_len);
  }
#else
  for (;;)
    if (stepOnce(i)) return;
#endif
}
