// OccupancyOcTreeBase::castRay's walk, as functions on a CastRayWalk, for the passes that walk
// it (cast_ray_rt.comp; cast_ray.comp spells the same arithmetic inline). Everything follows
// OctoMap 1.9.7 operation for operation: the direction normalised in float, tMax / tDelta in
// double, ties to the later axis, the max-range test on the float cell centre.
#ifndef OCTOVK_CAST_RAY_WALK_GLSL
#define OCTOVK_CAST_RAY_WALK_GLSL

#include "tree_search.glsl"

struct CastRayWalk {
  uvec3 key;           // the current cell
  ivec3 step;          // -1, 0, 1 per axis
  double t_max[3];     // ray parameter of the next border per axis (accumulated as OctoMap does)
  double t_delta[3];   // parameter between two borders per axis
  vec3 org;            // the origin, as given
  vec3 dir;            // direction.normalized() in float
  bool max_range_set;  // maxRange > 0
  double max_range_sq;
};

vec3 castRayCellCentre(uvec3 k) {
  return vec3(toFloat(keyToCoord(k.x)), toFloat(keyToCoord(k.y)), toFloat(keyToCoord(k.z)));
}

// Direction, steps and tDelta of ray q, and tMax from w.key when `start` (else w.t_max is
// kept). False for the direction (0, 0, 0), which OctoMap refuses.
bool castRaySetUp(RayQuery q, bool start, inout CastRayWalk w) {
  w.org = vec3(q.origin_x, q.origin_y, q.origin_z);
  precise float dir[3];
  dir[0] = q.direction_x;
  dir[1] = q.direction_y;
  dir[2] = q.direction_z;
  double len = normOf(dir[0], dir[1], dir[2]);
  if (len > 0.0lf) {
    float l = toFloat(len);
    dir[0] = divFloat(dir[0], l);
    dir[1] = divFloat(dir[1], l);
    dir[2] = divFloat(dir[2], l);
  }
  w.dir = vec3(dir[0], dir[1], dir[2]);
  const double kDoubleMax = 1.7976931348623157e308lf;
  for (int a = 0; a < 3; ++a) {
    w.step[a] = dir[a] > 0.0 ? 1 : (dir[a] < 0.0 ? -1 : 0);
    if (w.step[a] != 0) {
      w.t_delta[a] = params.resolution / double(abs(dir[a]));
      if (start) {
        precise double border = keyToCoord(w.key[a]);
        precise double half_step = double(w.step[a]) * params.resolution * 0.5lf;
        border += half_step;
        w.t_max[a] = (border - double(w.org[a])) / double(dir[a]);
      }
    } else {
      w.t_delta[a] = kDoubleMax;
      if (start) w.t_max[a] = kDoubleMax;
    }
  }
  w.max_range_set = q.max_range > 0.0lf;
  w.max_range_sq = q.max_range * q.max_range;
  return w.step[0] != 0 || w.step[1] != 0 || w.step[2] != 0;
}

// The axis of the next step: the smallest tMax, ties to the later axis.
int castRayNextAxis(CastRayWalk w) {
  if (w.t_max[0] < w.t_max[1]) return w.t_max[0] < w.t_max[2] ? 0 : 2;
  return w.t_max[1] < w.t_max[2] ? 1 : 2;
}

// Whether stepping along `dim` would leave the map (OctoMap returns false, `end` = this cell).
bool castRayAtBorder(CastRayWalk w, int dim) {
  return (w.step[dim] < 0 && w.key[dim] == 0u) ||
         (w.step[dim] > 0 && w.key[dim] == 2u * kTreeMaxVal - 1u);
}

void castRayStep(inout CastRayWalk w, int dim) {
  w.key[dim] = uint(int(w.key[dim]) + w.step[dim]);
  precise double t = w.t_max[dim] + w.t_delta[dim];
  w.t_max[dim] = t;
}

// OctoMap's max-range test of cell centre e: the float differences squared in float, summed
// in double.
bool castRayBeyondRange(CastRayWalk w, vec3 e) {
  if (!w.max_range_set) return false;
  precise float dx = e.x - w.org.x;
  precise float dy = e.y - w.org.y;
  precise float dz = e.z - w.org.z;
  precise float sx = dx * dx;
  precise float sy = dy * dy;
  precise float sz = dz * dz;
  precise double dist_sq = 0.0lf;
  dist_sq += double(sx);
  dist_sq += double(sy);
  dist_sq += double(sz);
  return dist_sq > w.max_range_sq;
}

double castRayMinTMax(CastRayWalk w) { return min(w.t_max[0], min(w.t_max[1], w.t_max[2])); }

// Adds d (> 0) to s one addition at a time, as the walk does (s = s + d rounded), until s >= t,
// and returns the number of additions, without doing them one by one: within a binade of s the
// rounding of s + d adds the same multiple of s's ulp each time (after at most one step that
// settles a tie to even), so that stretch is one exact multiply-add of integers times the ulp.
// The result is bit for bit the one of the additions.
uint castRayAdvanceSum(inout double s, double d, double t) {
  uint n = 0u;
  while (s < t) {
    precise double s1 = s + d;
    ++n;
    if (s1 >= t || s <= 0.0lf) {
      s = s1;
      continue;
    }
    // The binade of s: [2^(e-1), 2^e); `upper` = 2^e (the exponent field + 1).
    uint hi = unpackDouble2x32(s).y;
    double upper = packDouble2x32(uvec2(0u, ((hi >> 20) + 1u) << 20));
    precise double s2 = s1 + d;
    if (s2 >= upper || s2 >= t) {
      s = s1;
      continue;
    }
    // s, s1, s2 in one binade: differences are exact multiples of its ulp.
    precise double r1 = s1 - s;
    precise double r2 = s2 - s1;
    if (r1 != r2) {  // a tie settled to even at s1; the increments are constant from there
      s = s1;
      continue;
    }
    // s1 + k * r for every k with s1 + k * r < min(t, upper): exact (the product and the sum
    // are integers below 2^53 times the ulp).
    double bound = min(t, upper);
    precise double room = bound - s1;
    double k = max(floor(room / r1) - 1.0lf, 0.0lf);
    for (;;) {
      precise double next = s1 + (k + 1.0lf) * r1;
      if (next >= bound) break;
      k += 1.0lf;
    }
    precise double sk = s1 + k * r1;
    s = sk;
    n += uint(k);
  }
  return n;
}

// Moves the walk to where OctoMap's walk is once every tMax >= t: each axis stepped until its
// tMax (accumulated as the walk does) reaches t. The caller makes sure that no cell the walk
// enters before t ends it (no occupied or, where it matters, unknown cell; none beyond the max
// range; not the map's border).
void castRayJumpTo(inout CastRayWalk w, double t) {
  for (int a = 0; a < 3; ++a) {
    if (w.step[a] == 0 || w.t_max[a] >= t) continue;
    double s = w.t_max[a];
    uint n = castRayAdvanceSum(s, w.t_delta[a], t);
    w.t_max[a] = s;
    w.key[a] = uint(int(w.key[a]) + w.step[a] * int(n));
  }
}

// A tree lookup whose answer is kept for every later cell inside the same node (a large free
// node, or an unknown region): keys whose bits above `shift` equal `prefix`. The nodes of the
// last search's path are kept too, so that the next search starts where the two keys' paths
// part instead of at the root.
struct CellCache {
  uvec3 prefix;
  uint shift;  // 32: nothing cached
  uint state;
  float log_odds;   // the found node's (kCellFree, kCellOccupied)
  uvec3 key;        // the key last searched
  uint path_depth;  // path[0 .. path_depth] are the nodes on its path (0: none)
  uint path[kTreeDepth + 1u];
};

CellCache castRayEmptyCache() {
  CellCache c;
  c.prefix = uvec3(0u);
  c.shift = 32u;
  c.state = kCellUnknown;
  c.log_odds = 0.0;
  c.key = uvec3(0u);
  c.path_depth = 0u;
  c.path[0] = kRootNode;
  return c;
}

// kCellUnknown / kCellFree / kCellOccupied of the cell k (OctoMap's search, isNodeOccupied).
// `searched` gets the levels descended (0 when the cache answered), for walk budgets.
uint castRayCellState(uvec3 k, inout CellCache c, out uint searched) {
  searched = 0u;
  if (c.shift < 32u && (k >> c.shift) == c.prefix) return c.state;
  if (pool.root_exists == 0u) {
    c.prefix = uvec3(0u);  // nothing is known anywhere: the whole map is unknown
    c.shift = kTreeDepth;
    c.state = kCellUnknown;
    return kCellUnknown;
  }
  // The node at depth d covers the keys sharing their top d bits: resume from the deepest node
  // of the last path that k shares.
  uvec3 diff = k ^ c.key;
  uint differ = diff.x | diff.y | diff.z;
  uint common_depth = differ == 0u ? kTreeDepth : kTreeDepth - 1u - uint(findMSB(differ));
  uint depth = min(common_depth, c.path_depth);
  uint node = c.path[depth];
  bool found = true;
  for (; depth < kTreeDepth; ++depth) {
    uint block = childBlock(node);
    if (block == kNoChildren) break;  // a leaf (search() finds it)
    uint child = block * 8u + childIndex(k, depth);
    if ((linkOf(child) & kFlagLive) == 0u) {  // a node with other children but not this one
      found = false;
      break;
    }
    node = child;
    c.path[depth + 1u] = child;
    ++searched;
  }
  c.key = k;
  c.path_depth = depth;
  // Found: the node at `depth` covers the keys sharing its prefix. Not found: the missing child
  // one level below the deepest node covers them.
  uint covered = found ? depth : depth + 1u;
  c.shift = kTreeDepth - covered;
  c.prefix = k >> c.shift;
  c.log_odds = found ? nodes[node].log_odds : 0.0;
  c.state = !found ? kCellUnknown
                   : (c.log_odds >= params.occupancy_log ? kCellOccupied : kCellFree);
  return c.state;
}

#endif  // OCTOVK_CAST_RAY_WALK_GLSL
