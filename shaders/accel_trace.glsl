// Tracing a walk's ray through the boxes accel_boxes.comp writes (castRay's ray-tracing backend,
// cast_ray_rt.glsl, and scans through ray tracing, scan_rays_rt.comp): the boxes buffer's view,
// the slack on ray parameters, the exact slab test of one box, and (with OCTOVK_RAY_QUERY) the
// ray query for the nearest box.
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

// Parameter interval of the ray in box b (slab test in double); false when it misses.
bool boxInterval(AccelBox b, RayWalk w, out double t_in, out double t_out) {
  t_in = -1.0e300lf;
  t_out = 1.0e300lf;
  float lo[3] = float[3](b.min_x, b.min_y, b.min_z);
  float hi[3] = float[3](b.max_x, b.max_y, b.max_z);
  for (int a = 0; a < 3; ++a) {
    double o = double(w.org[a]);
    if (w.dir[a] == 0.0) {
      if (o < double(lo[a]) || o > double(hi[a])) return false;
      continue;
    }
    double inv = 1.0lf / double(w.dir[a]);
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
bool holdsFixedAxes(AccelBox b, RayWalk w) {
  vec3 lo = vec3(b.min_x, b.min_y, b.min_z);
  vec3 hi = vec3(b.max_x, b.max_y, b.max_z);
  vec3 c = 0.5 * (lo + hi);
  vec3 extent = hi - lo;
  double m = params.resolution * 0.25lf +
             double(max(abs(c.x), max(abs(c.y), abs(c.z))) +
                    max(extent.x, max(extent.y, extent.z))) *
                 kRangeMargin;
  for (int a = 0; a < 3; ++a) {
    if (w.step[a] != 0) continue;
    double centre = keyToCoord(w.key[a]);
    if (double(lo[a]) + m > centre || double(hi[a]) - m < centre) return false;
  }
  return true;
}

#ifdef OCTOVK_RAY_QUERY
// The nearest box whose interval reaches past t_from and starts before t_to: its
// entry (at least t_from) and exit. False when there is none. `fixed_axes`: only boxes that
// hold the walk's cell on the axes it never steps along (holdsFixedAxes).
bool nearestBox(AccelRef scene, RayWalk w, double t_from, float t_to, bool fixed_axes,
                out double t_enter, out double t_exit) {
  rayQueryEXT rq;
  float t_min = float(max(t_from, 0.0lf));
  rayQueryInitializeEXT(rq, accelerationStructureEXT(scene.header.tlas), gl_RayFlagsNoneEXT,
                        0xFFu, w.org, t_min, w.dir, t_to);
  bool found = false;
  t_enter = 1.0e300lf;
  t_exit = 1.0e300lf;
  while (rayQueryProceedEXT(rq)) {
    if (rayQueryGetIntersectionTypeEXT(rq, false) != gl_RayQueryCandidateIntersectionAABBEXT)
      continue;
    uint index = rayQueryGetIntersectionPrimitiveIndexEXT(rq, false);
    double t_in, t_out;
    AccelBox b = scene.boxes[index];
    if (!boxInterval(b, w, t_in, t_out) || t_out < t_from) continue;
    if (fixed_axes && !holdsFixedAxes(b, w)) continue;
    t_in = max(t_in, t_from);
    if (t_in > double(t_to) || (found && t_in >= t_enter)) continue;
    found = true;
    t_enter = t_in;
    t_exit = t_out;
    // Commit it so that the traversal skips farther boxes: monotone rounding keeps the hit
    // parameters non-increasing.
    rayQueryGenerateIntersectionEXT(rq, min(max(t_min, float(t_in)), t_to));
  }
  return found;
}
#endif

#endif  // OCTOVK_ACCEL_TRACE_GLSL
