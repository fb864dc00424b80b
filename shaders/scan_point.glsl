// A scan's point and the start of its ray, as OccupancyOcTreeBase::computeUpdate begins them: the
// per-point checks (non-finite points, max range, keys outside the map, discretize's end cells),
// the end cell marked occupied, the origin's cell marked free and the walk's start. One copy for
// the walked scans (ray_keys.comp) and the traced ones (scan_rays_rt.comp), so that both mark
// the same cells. The includer declares the push constants `pc` (point_count, mode).
#ifndef OCTOVK_SCAN_POINT_GLSL
#define OCTOVK_SCAN_POINT_GLSL

#include "cell_set.glsl"
#include "ray_walk.glsl"

// The walk of this invocation's ray (ray_walk.glsl) and its end cell and length.
RayWalk w;
uvec3 key_end;
float len;

vec3 scanOrigin() { return vec3(params.origin_x, params.origin_y, params.origin_z); }

// Direction, length, steps and tDelta of the ray from the scan's origin to e (and tMax when
// starting), as computeRayKeys computes them.
void setUpWalk(vec3 e, bool start) {
  vec3 o = scanOrigin();
  walkSetUp(w, o, rayKeysDirection(o, e, len), start, kHalfStepFloat);
}

// OcTreeBaseImpl::computeRayKeys: Amanatides-Woo, origin cell included, end cell excluded.
// Its start: false when an end lies outside the map (no free cells); `walking` when cells are
// left to walk after the origin's (origin and end in one cell: none).
bool startRay(vec3 o, vec3 e, out bool walking) {
  walking = false;
  uvec3 ko;
  if (!coordToKeyChecked(o.x, ko.x) || !coordToKeyChecked(o.y, ko.y) ||
      !coordToKeyChecked(o.z, ko.z))
    return false;
  if (!coordToKeyChecked(e.x, key_end.x) || !coordToKeyChecked(e.y, key_end.y) ||
      !coordToKeyChecked(e.z, key_end.z))
    return false;
  if (ko == key_end) return true;
  markCell(ko, false);
  w.key = ko;
  walking = true;
  return true;
}

// A new ray: point i's (or end cell i's) occupied cell, and the start of its walk (w.key; the
// caller sets up the rest, setUpWalk). The end of the walk goes to `e`. True when cells are left to walk.
bool startPoint(uint i, out vec3 e) {
  e = vec3(0.0);
  vec3 p;
  if (pc.mode == kRayKeysPoints) {
    if (i >= pc.point_count) return false;
    p = vec3(POINTS[3u * i], POINTS[3u * i + 1u], POINTS[3u * i + 2u]);
    if (!finiteBits(p)) {
      atomicAdd(counters.skipped_nonfinite, 1u);
      return false;
    }
  } else {
    if (i >= counters.endpoint_entries) return false;
    uvec3 kk = unpackKey(ENDPOINT_KEYS[SLOTS[params.hash_capacity + i]]);
    p = vec3(toFloat(keyToCoord(kk.x)), toFloat(keyToCoord(kk.y)), toFloat(keyToCoord(kk.z)));
  }
  vec3 o = scanOrigin();
  bool inserted = false;
  precise float dx = p.x - o.x;
  precise float dy = p.y - o.y;
  precise float dz = p.z - o.z;
  double dist = normOf(dx, dy, dz);
  bool within = params.max_range < 0.0lf || dist <= params.max_range;
  e = p;
  if (within) {
    uvec3 k;
    if (coordToKeyChecked(p.x, k.x) && coordToKeyChecked(p.y, k.y) &&
        coordToKeyChecked(p.z, k.z)) {
      markCell(k, true);
      inserted = true;
    }
  } else {
    // Point3d::normalized() then origin + direction * (float) maxrange.
    if (dist > 0.0lf) {
      float l = toFloat(dist);
      dx = divFloat(dx, l);
      dy = divFloat(dy, l);
      dz = divFloat(dz, l);
    }
    float range = toFloat(params.max_range);
    precise float ex = o.x + dx * range;
    precise float ey = o.y + dy * range;
    precise float ez = o.z + dz * range;
    e = vec3(ex, ey, ez);
  }
  bool walking;
  inserted = startRay(o, e, walking) || inserted;
  if (!inserted) atomicAdd(counters.skipped_outside, 1u);
  return walking;
}

#endif  // OCTOVK_SCAN_POINT_GLSL
