// Tracing a walk's ray through the boxes accel_boxes.comp writes (castRay's ray-tracing backend,
// cast_ray_rt.glsl, and scans through ray tracing, scan_rays_rt.glsl): the boxes buffer's view,
// the slack on ray parameters, the exact slab test of one box, the test that keeps the nearest
// box (BoxSearch), and nearestBox, the trace itself, through a ray query (OCTOVK_RAY_QUERY, in a
// compute pass) or a ray-tracing pipeline (OCTOVK_RAY_PIPELINE, in a ray generation shader, with
// accel_box.rint and accel_box.rahit). Both paths run the same tests on the same boxes, so they
// find the same box.
#ifndef OCTOVK_ACCEL_TRACE_GLSL
#define OCTOVK_ACCEL_TRACE_GLSL

#include "ray_walk.glsl"

layout(buffer_reference, std430, buffer_reference_align = 8) buffer AccelRef {
  AccelHeader header;
  AccelBox boxes[];
};

// Slack on ray parameters: the hardware's float test and our own rounding, far below the boxes'
// enlargement (a quarter cell for castRay's, a 64th for a scan's: accel_boxes.comp's margin()).
double slack(double t, vec3 org, double dir_len) {
  float m = max(abs(org.x), max(abs(org.y), abs(org.z)));
  return (params.resolution * 0.125lf + (abs(t) * dir_len + double(m)) * kRangeMargin) / dir_len;
}

// Parameter interval of the ray (org, dir: the walk's, as traced) in box b (slab test in double);
// false when it misses.
bool boxInterval(AccelBox b, vec3 org, vec3 dir, out double t_in, out double t_out) {
  t_in = -1.0e300lf;
  t_out = 1.0e300lf;
  float lo[3] = float[3](b.min_x, b.min_y, b.min_z);
  float hi[3] = float[3](b.max_x, b.max_y, b.max_z);
  for (int a = 0; a < 3; ++a) {
    double o = double(org[a]);
    if (dir[a] == 0.0) {
      if (o < double(lo[a]) || o > double(hi[a])) return false;
      continue;
    }
    double inv = 1.0lf / double(dir[a]);
    double t0 = (double(lo[a]) - o) * inv;
    double t1 = (double(hi[a]) - o) * inv;
    t_in = max(t_in, min(t0, t1));
    t_out = min(t_out, max(t0, t1));
  }
  return t_in <= t_out;
}

// Whether box b, less its enlargement (accel_boxes.comp's margin(), estimated from the
// enlarged box: a hair larger), holds the centre of the walk's cell on every axis the walk never
// steps along. The walk stays in that cell's slab there, so a box that misses it never holds a
// cell of the walk, however near the line runs (a ray along a cell border grazes the enlarged
// boxes of the next layer: a planar scan at z = 0 runs along the border of two layers).
bool holdsFixedAxes(AccelBox b, uvec3 key, ivec3 step) {
  vec3 lo = vec3(b.min_x, b.min_y, b.min_z);
  vec3 hi = vec3(b.max_x, b.max_y, b.max_z);
  vec3 c = 0.5 * (lo + hi);
  vec3 extent = hi - lo;
  double m = params.resolution * 0.25lf +
             double(max(abs(c.x), max(abs(c.y), abs(c.z))) +
                    max(extent.x, max(extent.y, extent.z))) *
                 kRangeMargin;
  for (int a = 0; a < 3; ++a) {
    if (step[a] != 0) continue;
    double centre = keyToCoord(key[a]);
    if (double(lo[a]) + m > centre || double(hi[a]) - m < centre) return false;
  }
  return true;
}

// The search for the nearest box along a walk's ray: what it asks and the best box so far. The
// ray-tracing pipeline's payload (its any-hit shader keeps the best box here).
struct BoxSearch {
  double t_from;   // boxes whose interval reaches past it count, entered at t_from at the earliest
  double t_enter;  // the best box so far: its entry (at least t_from)
  double t_exit;   // and exit
  uvec3 key;       // the walk's cell and steps, for holdsFixedAxes
  ivec3 step;
  float t_to;      // boxes entered after it do not count
  bool fixed_axes;  // only boxes that hold the walk's cell on the axes it never steps along
  bool found;       // whether there is a best box
};

BoxSearch boxSearch(RayWalk w, double t_from, float t_to, bool fixed_axes) {
  return BoxSearch(t_from, 1.0e300lf, 1.0e300lf, w.key, w.step, t_to, fixed_axes, false);
}

// The float parameter the trace starts from.
float traceTMin(double t_from) { return float(max(t_from, 0.0lf)); }

// Whether box b, whose interval on the ray is [t_in, t_out] (boxInterval), is nearer than the
// best so far; then it becomes the best, and `t_hit` is the parameter to commit it at, so that
// the traversal skips farther boxes (monotone rounding keeps the committed parameters
// non-increasing, and a nearer box's never above them). `t_min`: traceTMin(s.t_from).
bool nearerBox(inout BoxSearch s, AccelBox b, double t_in, double t_out, float t_min,
               out float t_hit) {
  t_hit = t_min;
  if (t_out < s.t_from) return false;
  if (s.fixed_axes && !holdsFixedAxes(b, s.key, s.step)) return false;
  t_in = max(t_in, s.t_from);
  if (t_in > double(s.t_to) || (s.found && t_in >= s.t_enter)) return false;
  s.found = true;
  s.t_enter = t_in;
  s.t_exit = t_out;
  t_hit = min(max(t_min, float(t_in)), s.t_to);
  return true;
}

// The nearest box whose interval reaches past t_from and starts before t_to: its entry (at least
// t_from) and exit. False when there is none. `fixed_axes`: only boxes that hold the walk's cell
// on the axes it never steps along (holdsFixedAxes).
#if defined(OCTOVK_RAY_QUERY)
bool nearestBox(AccelRef scene, RayWalk w, double t_from, float t_to, bool fixed_axes,
                out double t_enter, out double t_exit) {
  BoxSearch s = boxSearch(w, t_from, t_to, fixed_axes);
  float t_min = traceTMin(t_from);
  rayQueryEXT rq;
  rayQueryInitializeEXT(rq, accelerationStructureEXT(scene.header.tlas), gl_RayFlagsNoneEXT,
                        0xFFu, w.org, t_min, w.dir, t_to);
  while (rayQueryProceedEXT(rq)) {
    if (rayQueryGetIntersectionTypeEXT(rq, false) != gl_RayQueryCandidateIntersectionAABBEXT)
      continue;
    AccelBox b = scene.boxes[rayQueryGetIntersectionPrimitiveIndexEXT(rq, false)];
    double t_in, t_out;
    float t_hit;
    if (boxInterval(b, w.org, w.dir, t_in, t_out) && nearerBox(s, b, t_in, t_out, t_min, t_hit))
      rayQueryGenerateIntersectionEXT(rq, t_hit);
  }
  t_enter = s.t_enter;
  t_exit = s.t_exit;
  return s.found;
}
#elif defined(OCTOVK_RAY_PIPELINE)
// The trace's payload: accel_box.rahit keeps the nearest box in it (nearerBox), in the order the
// traversal reports the boxes accel_box.rint found on the ray (boxInterval); no miss or closest
// hit shader has work to do.
layout(location = 0) rayPayloadEXT BoxSearch search;

bool nearestBox(AccelRef scene, RayWalk w, double t_from, float t_to, bool fixed_axes,
                out double t_enter, out double t_exit) {
  search = boxSearch(w, t_from, t_to, fixed_axes);
  // Every box is a candidate for the any-hit shader (none is opaque), which commits the nearer
  // ones; a committed box ends no trace.
  traceRayEXT(accelerationStructureEXT(scene.header.tlas),
              gl_RayFlagsNoOpaqueEXT | gl_RayFlagsSkipClosestHitShaderEXT, 0xFFu, 0u, 0u, 0u, w.org,
              traceTMin(t_from), w.dir, t_to, 0);
  t_enter = search.t_enter;
  t_exit = search.t_exit;
  return search.found;
}
#endif

#endif  // OCTOVK_ACCEL_TRACE_GLSL
