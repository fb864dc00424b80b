#version 450
#extension GL_GOOGLE_include_directive : require
// Distance queries on the field (its sites after field_edt along z): for each sphere (centre,
// radius) of the query input, the cell holding the centre (OctoMap's coordToKey), its distance to
// the nearest occupied cell's centre capped at the field's max distance, minus the radius; that
// cell's centre; the unit vector from it to the cell (the gradient of the distance); the exact
// squared distance in cells. Outside the box: DynamicEDTOctomap's distanceValue_Error (-1).
#include "keys.glsl"
#include "field.glsl"

layout(push_constant) uniform PushBlock { FieldQueryConstants pc; };

layout(std430, binding = kBindQueryIn) buffer QueryInBuf { vec4 spheres[]; };
layout(std430, binding = kBindQueryOut) buffer QueryOutBuf { DistanceResult results[]; };

void main() {
  uint i = invocationIndex();
  if (i >= pc.query_count) return;
  FieldHeaderRef f = FieldHeaderRef(pc.header);
  vec4 s = spheres[i];
  float nan = uintBitsToFloat(0x7FC00000u);
  DistanceResult r = DistanceResult(-1.0, nan, nan, nan, 0.0, 0.0, 0.0, kDistanceOutside);
  uvec3 k;
  uvec3 size = fieldSize(f), lo = fieldMinKey(f);
  if (coordToKeyChecked(s.x, k.x) && coordToKeyChecked(s.y, k.y) && coordToKeyChecked(s.z, k.z) &&
      all(greaterThanEqual(k, lo)) && all(lessThan(k - lo, size))) {
    uvec3 c = k - lo;
    uint site = FieldWordsRef(f.h.sites).v[c.x + size.x * (c.y + size.y * c.z)];
    float max_m = f.h.max_distance_m;
    if (site == kFieldNoSite) {
      r.distance = max_m - s.w;
      r.squared_cells = kDistanceNoObstacle;
    } else {
      uvec3 o = fieldCell(site, size);
      ivec3 away_cells = ivec3(c) - ivec3(o);
      uint squared = uint(away_cells.x * away_cells.x + away_cells.y * away_cells.y +
                          away_cells.z * away_cells.z);  // < 2^31: kFieldMaxAxisCells
      precise double root = sqrt(double(squared));
      precise double metres = root * params.resolution;
      float d = min(toFloat(metres), max_m);
      precise float clearance = d - s.w;
      r.distance = clearance;
      r.obstacle_x = toFloat(keyToCoord(lo.x + o.x));
      r.obstacle_y = toFloat(keyToCoord(lo.y + o.y));
      r.obstacle_z = toFloat(keyToCoord(lo.z + o.z));
      if (squared != 0u && toFloat(metres) < max_m) {
        dvec3 away = dvec3(away_cells);
        precise dvec3 g = away / root;
        r.gradient_x = toFloat(g.x);
        r.gradient_y = toFloat(g.y);
        r.gradient_z = toFloat(g.z);
      }
      r.squared_cells = squared;
    }
  }
  results[i] = r;
}
