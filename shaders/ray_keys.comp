#version 450
#extension GL_GOOGLE_include_directive : require
// Ray keys and hash set: for every point (mode 0) or every distinct end cell (mode 1, discretize),
// the cells of OctoMap's computeRayKeys go into the scan's cell set as free and the end cell as
// occupied (occupied wins: it is a flag on the same entry). Mirrors OccupancyOcTreeBase::computeUpdate.
#include "common.glsl"

// OcTreeBaseImpl::computeRayKeys: Amanatides-Woo, origin cell included, end cell excluded.
bool insertRay(vec3 o, vec3 e) {
  uvec3 ko, ke;
  if (!coordToKeyChecked(o.x, ko.x) || !coordToKeyChecked(o.y, ko.y) ||
      !coordToKeyChecked(o.z, ko.z))
    return false;
  if (!coordToKeyChecked(e.x, ke.x) || !coordToKeyChecked(e.y, ke.y) ||
      !coordToKeyChecked(e.z, ke.z))
    return false;
  if (ko == ke) return true;
  insertCell(packKey(ko));

  precise float dir[3];
  dir[0] = e.x - o.x;
  dir[1] = e.y - o.y;
  dir[2] = e.z - o.z;
  float len = float(normOf(dir[0], dir[1], dir[2]));
  dir[0] = divFloat(dir[0], len);
  dir[1] = divFloat(dir[1], len);
  dir[2] = divFloat(dir[2], len);
  float org[3] = float[3](o.x, o.y, o.z);

  int step[3];
  precise double t_max[3];
  double t_delta[3];
  uint cur[3] = uint[3](ko.x, ko.y, ko.z);
  const double kDoubleMax = 1.7976931348623157e308lf;
  for (int i = 0; i < 3; ++i) {
    step[i] = dir[i] > 0.0 ? 1 : (dir[i] < 0.0 ? -1 : 0);
    if (step[i] != 0) {
      precise double border = keyToCoord(cur[i]);
      precise double half_step = double(step[i]) * params.resolution * 0.5lf;
      border += double(float(half_step));
      t_max[i] = (border - double(org[i])) / double(dir[i]);
      t_delta[i] = params.resolution / double(abs(dir[i]));
    } else {
      t_max[i] = kDoubleMax;
      t_delta[i] = kDoubleMax;
    }
  }
  for (uint guard = 0u; guard < 3u * 65536u; ++guard) {
    int dim;
    if (t_max[0] < t_max[1]) dim = t_max[0] < t_max[2] ? 0 : 2;
    else dim = t_max[1] < t_max[2] ? 1 : 2;
    cur[dim] = uint(int(cur[dim]) + step[dim]) & 0xFFFFu;
    t_max[dim] += t_delta[dim];
    if (cur[0] == ke.x && cur[1] == ke.y && cur[2] == ke.z) break;
    double m01 = t_max[1] < t_max[0] ? t_max[1] : t_max[0];
    double dist = t_max[2] < m01 ? t_max[2] : m01;
    if (dist > double(len)) break;
    if (insertCell(packKey(uvec3(cur[0], cur[1], cur[2]))) == 0xFFFFFFFFu) break;  // redone
  }
  return true;
}

void main() {
  uint i = invocationIndex();
  vec3 p;
  if (pc.mode == 0u) {
    if (i >= pc.count) return;
    p = vec3(points[3u * i], points[3u * i + 1u], points[3u * i + 2u]);
    if (any(isnan(p)) || any(isinf(p))) {
      atomicAdd(counters.skipped_nonfinite, 1u);
      return;
    }
  } else {
    if (i >= params.endpoint_capacity) return;
    uint64_t k = endpoint_keys[i];
    if (k == kEmptyKey) return;
    uvec3 kk = unpackKey(k);
    p = vec3(float(keyToCoord(kk.x)), float(keyToCoord(kk.y)), float(keyToCoord(kk.z)));
  }
  vec3 o = vec3(params.origin_x, params.origin_y, params.origin_z);
  bool inserted = false;
  precise float dx = p.x - o.x;
  precise float dy = p.y - o.y;
  precise float dz = p.z - o.z;
  double dist = normOf(dx, dy, dz);
  if (params.max_range < 0.0lf || dist <= params.max_range) {
    inserted = insertRay(o, p);
    uvec3 k;
    if (coordToKeyChecked(p.x, k.x) && coordToKeyChecked(p.y, k.y) &&
        coordToKeyChecked(p.z, k.z)) {
      uint s = insertCell(packKey(k));
      if (s != 0xFFFFFFFFu) atomicOr(hash_flags[s], kHashFlagOccupied);
      inserted = true;
    }
  } else {
    // Point3d::normalized() then origin + direction * (float) maxrange.
    if (dist > 0.0lf) {
      float l = float(dist);
      dx = divFloat(dx, l);
      dy = divFloat(dy, l);
      dz = divFloat(dz, l);
    }
    float range = float(params.max_range);
    precise float ex = o.x + dx * range;
    precise float ey = o.y + dy * range;
    precise float ez = o.z + dz * range;
    inserted = insertRay(o, vec3(ex, ey, ez));
  }
  if (!inserted) atomicAdd(counters.skipped_outside, 1u);
}
