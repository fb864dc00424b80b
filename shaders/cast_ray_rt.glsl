// castRay through the acceleration structure over the map's boxes (the ray-tracing backend):
// OccupancyOcTreeBase::castRay for each query ray, with the same answer as cast_ray.comp. Two
// passes are built from this file: cast_ray_rt.comp (OCTOVK_CAST_RAY_TRACE: ray queries) answers
// the rays that ignore unknown space, cast_ray_jump.comp the others, without ray queries (on
// lavapipe a shader with ray queries costs more per invocation, and such rays mostly end within
// a few cells, at the edge of what a sensor saw, where the unknown boxes are many and small).
//
// A ray query finds the nearest box along the ray that could end the walk: an occupied leaf
// and, unless ignore_unknown, an unknown region (instance masks kAccelMask*). The boxes are
// enlarged (accel_boxes.comp), so every cell OctoMap's walk enters before the enlarged box's
// entry parameter is free (or unknown with ignore_unknown), inside the map and within the max
// range once those limits are also kept. The walk jumps there exactly (castRayJumpTo: the same
// tMax bits as stepping), then steps with tree lookups, exactly as OctoMap does, until it ends
// or has passed the box; then the next box is traced. Inside a node a lookup found free (or
// unknown, when ignored), the walk jumps to the node's exit the same way. Without ray queries
// (cast_ray_jump) the walk only steps and jumps through such nodes.
#define OCTOVK_NODES_READ_ONLY
#include "tree_search.glsl"
#include "cast_ray_walk.glsl"
#ifdef OCTOVK_CAST_RAY_TRACE
#define OCTOVK_RAY_QUERY
#endif
#include "accel_trace.glsl"

layout(push_constant) uniform PushBlock { CastRayRtConstants pc; };

layout(std430, binding = kBindQueryIn) buffer QueryInBuf { RayQuery rays[]; };
layout(std430, binding = kBindQueryOut) buffer QueryOutBuf { RayResult ray_results[]; };
void finish(uint i, uint hit, vec3 end) { ray_results[i] = RayResult(hit, end.x, end.y, end.z); }

// The ray parameter where the walk leaves the node the cache holds (a free node, or an unknown
// region when unknown space is ignored): every cell the walk enters before it lies in that node
// and gets the same answer, so the walk may jump there (less the slack). 0 for a finest cell.
double nodeExit(CastRayWalk w, CellCache c, dvec3 inv_dir) {
  if (c.shift < 2u || c.shift >= 32u) return 0.0lf;  // small nodes: stepping is as cheap
  double size = params.resolution * double(1u << c.shift);
  double t = 1.0e300lf;
  for (int a = 0; a < 3; ++a) {
    if (w.step[a] == 0) continue;
    double lo = double(int(c.prefix[a] << c.shift) - 32768) * params.resolution;
    double face = w.step[a] > 0 ? lo + size : lo;
    t = min(t, (face - double(w.org[a])) * inv_dir[a]);
  }
  return t;
}

// One step of OctoMap's walk and what the new cell says: true when the ray has its result
// (written). The range test runs only for cells entered from t_range on (see main).
bool stepOnce(uint i, inout CastRayWalk w, inout CellCache cache, bool ignore_unknown,
              double t_range) {
  int dim = castRayNextAxis(w);
  if (castRayAtBorder(w, dim)) {
    finish(i, 0u, castRayCellCentre(w.key));  // the map's border
    return true;
  }
  double entry = w.t_max[dim];
  castRayStep(w, dim);
  if (entry >= t_range) {
    vec3 e = castRayCellCentre(w.key);
    if (castRayBeyondRange(w, e)) {
      finish(i, 0u, e);
      return true;
    }
  }
  uint searched;
  uint state = castRayCellState(w.key, cache, searched);
  if (state == kCellOccupied || (state == kCellUnknown && !ignore_unknown)) {
    finish(i, state == kCellOccupied ? 1u : 0u, castRayCellCentre(w.key));
    return true;
  }
  return false;
}

// Jumps the walk to the exit of the node the cache holds (less the slack, and not past t_limit).
void jumpThroughNode(inout CastRayWalk w, CellCache cache, double t_limit, double dir_len,
                     dvec3 inv_dir) {
  double through = min(nodeExit(w, cache, inv_dir), t_limit);
  through -= slack(through, w.org, dir_len);
  if (through > castRayMinTMax(w)) castRayJumpTo(w, through);
}

void main() {
  uint i = invocationIndex();
  if (i >= pc.ray_count) return;
  i += pc.first_ray;
  RayQuery q = rays[i];
  bool ignore_unknown = q.ignore_unknown != 0u;
#ifdef OCTOVK_CAST_RAY_TRACE
  if (!ignore_unknown) return;  // cast_ray_jump's
  AccelRef scene = AccelRef(pc.boxes);
#else
  if (ignore_unknown) return;  // cast_ray_rt's
#endif
  vec3 origin = vec3(q.origin_x, q.origin_y, q.origin_z);

  // Start, as cast_ray.comp: where OctoMap leaves `end` untouched, it is the origin.
  CastRayWalk w;
  if (!coordToKeyChecked(q.origin_x, w.key.x) || !coordToKeyChecked(q.origin_y, w.key.y) ||
      !coordToKeyChecked(q.origin_z, w.key.z)) {
    finish(i, 0u, origin);
    return;
  }
  CellCache cache = castRayEmptyCache();
  uint searched;
  uint start = castRayCellState(w.key, cache, searched);
  if (start == kCellOccupied) {
    finish(i, 1u, castRayCellCentre(w.key));
    return;
  }
  if (start == kCellUnknown && !ignore_unknown) {
    finish(i, 0u, castRayCellCentre(w.key));
    return;
  }
  if (!castRaySetUp(q, true, w)) {  // direction (0, 0, 0): OctoMap refuses
    finish(i, 0u, origin);
    return;
  }

  // The traced ray is the walk's line: an axis the walk never steps (a zero or NaN component
  // of a direction OctoMap could not normalise) is not followed. Ray parameters are in units of
  // this direction (normalised, unless OctoMap could not normalise it).
  for (int a = 0; a < 3; ++a)
    if (w.step[a] == 0) w.dir[a] = 0.0;
  double dir_len = length(dvec3(w.dir));
  // 1 / direction, for the approximate parameters of node exits (inf where not followed).
  dvec3 inv_dir = dvec3(1.0e300lf);
  for (int a = 0; a < 3; ++a)
    if (w.step[a] != 0) inv_dir[a] = 1.0lf / double(w.dir[a]);

  // Where the walk must be stepped cell by cell whatever the boxes say: near the map's border
  // (the walk stops there) and near the max range (the first cell beyond it ends the walk). A
  // cell entered before t_range has its centre within the max range (its centre is within
  // sqrt(3)/2 cells of the ray), so OctoMap's range test is only run beyond.
  double t_limit = 1.0e300lf;
  const double kHalfExtent = double(kTreeMaxVal) * params.resolution;
  for (int a = 0; a < 3; ++a) {
    if (w.step[a] == 0) continue;
    double bound = w.step[a] > 0 ? kHalfExtent : -kHalfExtent;
    t_limit = min(t_limit, (bound - double(w.org[a])) / double(w.dir[a]) - params.resolution);
  }
  double t_range = 1.0e300lf;
  if (w.max_range_set) {
    double range = sqrt(w.max_range_sq);
    t_range = (range - 2.0lf * params.resolution - range * (1.0lf / 65536.0lf)) /
              (dir_len * (1.0lf + 1.0lf / 65536.0lf));
    t_limit = min(t_limit, t_range);
  }
#ifdef OCTOVK_CAST_RAY_TRACE
  uint mask = kAccelMaskOccupied | (ignore_unknown ? 0u : kAccelMaskUnknown);
#endif

#ifdef OCTOVK_CAST_RAY_TRACE
  double t_from = castRayMinTMax(w) - slack(castRayMinTMax(w), w.org, dir_len);
  for (;;) {
    double t_enter, t_exit;
    bool found = nearestBox(scene, w, mask, t_from, 3.0e38, false, t_enter, t_exit);
    double target = min(found ? t_enter : 1.0e300lf, t_limit);
    target -= slack(target, w.org, dir_len);
    if (target > castRayMinTMax(w)) castRayJumpTo(w, target);
    // Beyond the box's exit (and its slack) the next box is traced; without one the walk runs
    // to its end (border or max range, both near).
    double t_leave = found ? t_exit + 2.0lf * slack(t_exit, w.org, dir_len) : 1.0e300lf;
    do {
      if (stepOnce(i, w, cache, ignore_unknown, t_range)) return;
      jumpThroughNode(w, cache, t_limit, dir_len, inv_dir);
    } while (castRayMinTMax(w) <= t_leave);
    t_from = castRayMinTMax(w) - slack(castRayMinTMax(w), w.org, dir_len);
  }
#else
  for (;;) {
    if (stepOnce(i, w, cache, ignore_unknown, t_range)) return;
    jumpThroughNode(w, cache, t_limit, dir_len, inv_dir);
  }
#endif
}
