// OctoMap's ray walk, written once for every pass that walks it: the DDA (Amanatides-Woo) of
// OcTreeBaseImpl::computeRayKeys (ray_keys.comp, scan_rays_rt.comp) and of
// OccupancyOcTreeBase::castRay (cast_ray.comp, cast_ray_rt.glsl): the direction, the set-up, one
// step, the exact jump over many steps, the constants and castRay's max-range margin. The cell
// lookups of a walk (the cached search, castRay's step with its lookup, the jump across a node)
// are in walk_cells.glsl, which needs the tree.
//
// Everything follows OctoMap 1.9.7 operation for operation: the direction normalised in float,
// tMax / tDelta in double, ties to the later axis, keys as uint16. The two OctoMap walks differ
// in exactly two places, and each is a named choice here: how the direction is normalised
// (rayKeysDirection / castRayDirection) and how the first border is rounded (kHalfStepFloat /
// kHalfStepDouble). No bindings beyond keys.glsl's, no mutable globals: callers hold the walk.
#ifndef OCTOVK_RAY_WALK_GLSL
#define OCTOVK_RAY_WALK_GLSL

#include "keys.glsl"

// std::numeric_limits<double>::max(): tMax and tDelta of an axis the walk never steps along.
const double kDoubleMax = 1.7976931348623157e308lf;

// One walk. Vectors, not arrays: the walk picks its axis with selects, never by a dynamic index
// (which llvmpipe lowers to per-lane memory accesses).
struct RayWalk {
  uvec3 key;      // the current cell
  ivec3 step;     // -1, 0, 1 per axis
  dvec3 t_max;    // ray parameter of the next border per axis (accumulated as OctoMap does)
  dvec3 t_delta;  // parameter between two borders per axis
  vec3 org;       // the origin, as given
  vec3 dir;       // the normalised direction (float), 0 on the axes the walk never steps along:
                  // the line the walk follows, for the traced passes (a zero or NaN component
                  // of a direction OctoMap could not normalise is not followed)
};

// ---- set-up ----

// computeRayKeys: direction = end - origin, length = (float) direction.norm(), direction /=
// length (no test of the length: origin and end lie in different cells).
vec3 rayKeysDirection(vec3 o, vec3 e, out float len) {
  precise float dir[3];
  dir[0] = e.x - o.x;
  dir[1] = e.y - o.y;
  dir[2] = e.z - o.z;
  len = toFloat(normOf(dir[0], dir[1], dir[2]));
  dir[0] = divFloat(dir[0], len);
  dir[1] = divFloat(dir[1], len);
  dir[2] = divFloat(dir[2], len);
  return vec3(dir[0], dir[1], dir[2]);
}

// castRay: directionP.normalized(): the norm in double of the float squared norm, and the
// components divided by its float only when it is > 0.
vec3 castRayDirection(vec3 d) {
  precise float dir[3];
  dir[0] = d.x;
  dir[1] = d.y;
  dir[2] = d.z;
  double len = normOf(dir[0], dir[1], dir[2]);
  if (len > 0.0lf) {
    float l = toFloat(len);
    dir[0] = divFloat(dir[0], l);
    dir[1] = divFloat(dir[1], l);
    dir[2] = divFloat(dir[2], l);
  }
  return vec3(dir[0], dir[1], dir[2]);
}

// Where the first border of each axis lies: keyToCoord(key) + step * resolution * 0.5, that half
// step rounded to float in computeRayKeys (`(float) (step[i] * resolution * 0.5)`) and kept in
// double in castRay (`double(...)`). At a resolution whose half is not a float (0.05: 0.025 is
// not) the two give different tMax bits, so each walk uses its own.
const bool kHalfStepFloat = true;    // computeRayKeys (ray_keys, scan_rays_rt)
const bool kHalfStepDouble = false;  // castRay (cast_ray, cast_ray_rt)

// Steps and tDelta of the walk from w.key along `dir` (the normalised direction), and tMax when
// `start` (else w.t_max is kept: a walk resumed from a saved state).
void walkSetUp(inout RayWalk w, vec3 org, vec3 dir, bool start, bool half_step_float) {
  w.org = org;
  for (int i = 0; i < 3; ++i) {
    w.step[i] = dir[i] > 0.0 ? 1 : (dir[i] < 0.0 ? -1 : 0);
    if (w.step[i] != 0) {
      w.t_delta[i] = params.resolution / double(abs(dir[i]));
      if (start) {
        precise double border = keyToCoord(w.key[i]);
        precise double half_step = double(w.step[i]) * params.resolution * 0.5lf;
        border += half_step_float ? roundedToFloat(half_step) : half_step;
        w.t_max[i] = (border - double(org[i])) / double(dir[i]);
      }
    } else {
      w.t_delta[i] = kDoubleMax;
      if (start) w.t_max[i] = kDoubleMax;
    }
  }
  w.dir = mix(vec3(0.0), dir, notEqual(w.step, ivec3(0)));
}

// |w.dir| in double: the length of the walk's line per unit of ray parameter (1 up to float
// rounding, unless OctoMap could not normalise the direction). Only margins use it (castRay's
// range bound, the traced passes' slack and limits), each with far more room than its rounding.
double walkDirLength(RayWalk w) {
  precise double sq = double(w.dir.x) * double(w.dir.x) + double(w.dir.y) * double(w.dir.y) +
                      double(w.dir.z) * double(w.dir.z);
  return sqrt(sq);
}

// ---- one step ----

// The axis of the next step, as a mask with one component set: the smallest tMax, ties to the
// later axis (OctoMap's `<`, not `<=`).
bvec3 walkNextAxis(RayWalk w) {
  bool x_first = w.t_max.x < w.t_max.y ? w.t_max.x < w.t_max.z : false;
  bool y_first = w.t_max.x < w.t_max.y ? false : w.t_max.y < w.t_max.z;
  return bvec3(x_first, y_first, !x_first && !y_first);
}

// Whether stepping along `axis` would leave the map (castRay's overflow check).
bool walkAtBorder(RayWalk w, bvec3 axis) {
  uint k = axis.x ? w.key.x : (axis.y ? w.key.y : w.key.z);
  int s = axis.x ? w.step.x : (axis.y ? w.step.y : w.step.z);
  return (s < 0 && k == 0u) || (s > 0 && k == 2u * kTreeMaxVal - 1u);
}

// current_key[dim] += step[dim] (a uint16 key, as OctoMap's); tMax[dim] += tDelta[dim].
void walkStep(inout RayWalk w, bvec3 axis) {
  w.key = mix(w.key, uvec3(ivec3(w.key) + w.step) & uvec3(0xFFFFu), axis);
  precise dvec3 advanced = w.t_max + w.t_delta;
  w.t_max = mix(w.t_max, advanced, axis);
}

// min(tMax): the parameter of the next border.
double walkMinTMax(RayWalk w) {
  double m01 = w.t_max.y < w.t_max.x ? w.t_max.y : w.t_max.x;
  return w.t_max.z < m01 ? w.t_max.z : m01;
}

// One step of computeRayKeys: true when the walk is done (it entered the end cell, which is not
// part of the ray, or its next border lies beyond the length).
bool rayKeysStep(inout RayWalk w, uvec3 key_end, float len) {
  walkStep(w, walkNextAxis(w));
  if (w.key == key_end) return true;
  return walkMinTMax(w) > double(len);
}

// ---- castRay's max range ----

// castRay's max-range test runs on every cell entered; a step whose tMax (the value it is chosen
// by) is at most `test_after` enters a cell whose centre certainly passes it, so the test is
// skipped there and jumps may pass such cells.
struct CastRayRange {
  bool set;           // maxRange > 0
  double sq;          // maxRange * maxRange
  double test_after;  // see above; -kDoubleMax when no step is certainly within range
};

// The margin of test_after, relative to the max range. Why it holds: a walk's tMax values are
// where org + t * dir crosses the cell borders, to far below a cell (the set-up's rounding, at
// most 2^-25 cells from a float half step, plus at most 3 * 65536 additions each rounded by
// 2^-53 relative: 2^-36 relative), so the point at a step's tMax lies on the face of the cell
// that step enters (on an axis the walk never steps along, org stays in the origin's cell slab),
// and that cell's centre is within sqrt(3) / 2 cells of it. The test itself errs by the centre
// rounded to float (2^-24 of a coordinate below 2^15 cells: under 2^-9 cells) and by the float
// difference, squares and sum (under 2^-22 relative). So with
//   tMax * |dir| <= (maxRange * (1 - m) - 2 cells) / (1 + m)
// the computed squared distance stays below maxRange^2 for any m above about 2^-22: 2 cells cover
// sqrt(3) / 2 cells and the absolute errors, m the relative ones. m = 2^-16 leaves a factor of 64
// (cast_ray had 2^-20 and cast_ray_rt 2^-16, both valid: a smaller test_after only runs more
// exact tests and stops jumps earlier, so it cannot change an answer; the walk's cost of the
// larger margin is 2^-16 of the range, far below a cell). m is kRangeMargin (keys.glsl).

CastRayRange castRayRange(double max_range, RayWalk w) {
  CastRayRange r;
  r.set = max_range > 0.0lf;
  r.sq = max_range * max_range;
  r.test_after = -kDoubleMax;
  if (r.set) {
    precise double bound = (max_range * (1.0lf - kRangeMargin) - 2.0lf * params.resolution) /
                           (walkDirLength(w) * (1.0lf + kRangeMargin));
    if (bound > 0.0lf && bound <= kDoubleMax) r.test_after = bound;
  }
  return r;
}

// OctoMap's max-range test of the cell centre e: the float differences squared in float, summed
// in double.
bool castRayBeyondRange(CastRayRange r, vec3 org, vec3 e) {
  precise float dx = e.x - org.x;
  precise float dy = e.y - org.y;
  precise float dz = e.z - org.z;
  precise float sx = dx * dx;
  precise float sy = dy * dy;
  precise float sz = dz * dz;
  precise double dist_sq = 0.0lf;
  dist_sq += double(sx);
  dist_sq += double(sy);
  dist_sq += double(sz);
  return dist_sq > r.sq;
}

// The centre of cell k as OctoMap's `end`: keyToCoord in double, stored in a float point3d.
vec3 walkCellCentre(uvec3 k) {
  return vec3(toFloat(keyToCoord(k.x)), toFloat(keyToCoord(k.y)), toFloat(keyToCoord(k.z)));
}

// ---- the exact jump: many of one axis's additions tMax += tDelta at once ----
//
// Each axis's tMax takes the values s, s + d, (s + d) + d, ... (rounded after every addition),
// and the walk takes the smallest of the three (ties: the later axis), so the cells it visits are
// the merge of the three sequences in the order (value, -axis). Where nothing can end the walk,
// a jump computes the state after many steps without the per-cell work, exactly: it produces the
// very values of the additions. Not by a formula over the reals: within one binade [2^e, 2^(e+1)]
// every value is a multiple of u = 2^(e-52), and the rounded sum t + d is t + round(d / u) * u,
// the same step for every t there, except when d / u lies exactly halfway: then ties-to-even can
// make the first step in the binade differ from the others, and every later step is the same
// (after one step the value's parity fixes the tie the same way each time). So two equal
// consecutive steps inside a binade (observed with real additions) fix the step for the rest of
// it, and the values there are counted in integers, exactly (a value that reaches 2^(e+1) exactly
// is still a multiple of u; a sum above it would be rounded in the next binade, so the count
// stops at it). Whether a jump is worth it, and where it may go, is the caller's.

const uint64_t kUnits52 = 1ul << 52;
const uint64_t kUnits53 = 1ul << 53;
// Iterations one sequence may take: about 4 per binade (3 real additions and one count). After
// its first addition a sequence is at least d, and a jump stays inside the map (at most 2^16 + 1
// additions per axis), so it crosses at most 18 binades: 160 leaves room. A sequence that needs
// more is not jumped (the walk steps instead).
const uint kSeqIterations = 160u;

int walkBiasedExponent(double x) { return int(unpackDouble2x32(x).y >> 20u); }  // sign included

uint64_t walkSignificand(double x) {
  uvec2 w = unpackDouble2x32(x);
  return ((uint64_t(w.y & 0xFFFFFu) << 32) | uint64_t(w.x)) | kUnits52;
}

// x (> 0) in units of binade e's spacing when x lies in [2^e, 2^(e+1)], else 0.
uint64_t walkUnitsIn(double x, int e) {
  int ex = walkBiasedExponent(x);
  if (ex == e) return walkSignificand(x);
  if (ex == e + 1 && walkSignificand(x) == kUnits52) return kUnits53;
  return 0ul;
}

double walkFromUnits(uint64_t units, int e) {
  if (units == kUnits53) {
    units = kUnits52;
    ++e;
  }
  uint64_t bits = (uint64_t(e) << 52) | (units - kUnits52);
  return packDouble2x32(uvec2(uint(bits), uint(bits >> 32)));
}

bool walkComesBefore(double v, double limit, bool inclusive) {
  return v < limit || (inclusive && v == limit);
}

// Takes the values s, s + d, ... of one axis's tMax that come before `limit` (v < limit, or
// v <= limit when inclusive), at most max_steps of them; s becomes the first value not taken, as
// the walk's additions would make it. False when it cannot tell within kSeqIterations (or the
// values stop growing or overflow): the caller then steps. Each iteration costs `charge` of
// `budget` (the walk's loop budget where the driver limits loops, see cast_ray.comp; 0 where
// the walk has no budget).
bool walkAdvanceAxis(inout double s, double d, uint max_steps, double limit, bool inclusive,
                     out uint taken, inout int budget, int charge) {
  taken = 0u;
  double a = 0.0lf, b = 0.0lf;  // the two values before s, when `history` real additions led to s
  uint history = 0u;
  for (uint it = 0u; it < kSeqIterations; ++it) {
    budget -= charge;
    if (taken == max_steps || !walkComesBefore(s, limit, inclusive)) return true;
    int e = walkBiasedExponent(a);
    if (history >= 2u && a > 0.0lf && e > 0 && e < 0x7FE && walkBiasedExponent(b) == e) {
      uint64_t au = walkSignificand(a), bu = walkSignificand(b), su = walkUnitsIn(s, e);
      if (su != 0ul && bu - au == su - bu) {  // the binade's step is known: take many at once
        uint64_t inc = su - bu;
        uint64_t k = (kUnits53 - su) / inc;  // steps that stay in the binade (or end at its top)
        k = min(k, uint64_t(max_steps - taken));
        // A limit in this binade is a multiple of u: count the values su + j * inc before it.
        // A limit above the binade is above every value counted here; one below it is
        // impossible (s comes before the limit).
        if (walkBiasedExponent(limit) == e) {
          uint64_t last = walkSignificand(limit) - (inclusive ? 0ul : 1ul);
          k = min(k, last >= su ? (last - su) / inc + 1ul : 0ul);
        }
        if (k > 0ul) {
          s = walkFromUnits(su + k * inc, e);
          taken += uint(k);
          history = 0u;
          continue;
        }
      }
    }
    precise double next = s + d;  // the walk's own addition
    if (!(next > s) || !(next <= kDoubleMax)) return false;
    a = b;
    b = s;
    s = next;
    ++history;
    ++taken;
  }
  return false;
}

// Moves the walk to where its steps take it once every tMax >= t: each axis stepped until its
// tMax (accumulated as the walk does) reaches t. False, and the walk unchanged, where an axis
// cannot tell (walkAdvanceAxis). The caller makes sure that no cell the walk enters before t
// ends it (computeRayKeys: not the end cell, not past the length; castRay: no occupied or, where
// it matters, unknown cell, none beyond the max range, not the map's border).
// (The traced passes had their own jump, a double multiply-add per binade stretch with a
// correction loop. It too produced the additions' own values, so the two agree bit for bit
// wherever both answer; this one is kept because it counts in integers and is bounded in
// iterations, which a driver that limits loops needs.)
bool walkJumpTo(inout RayWalk w, double t, inout int budget, int charge) {
  dvec3 t_max = w.t_max;
  uvec3 n = uvec3(0u);
  for (int a = 0; a < 3; ++a) {
    if (w.step[a] == 0 || w.t_max[a] >= t) continue;
    double s = w.t_max[a];
    if (!walkAdvanceAxis(s, w.t_delta[a], 0xFFFFFFFFu, t, false, n[a], budget, charge))
      return false;
    t_max[a] = s;
  }
  w.t_max = t_max;
  w.key = uvec3(ivec3(w.key) + w.step * ivec3(n));
  return true;
}

#endif  // OCTOVK_RAY_WALK_GLSL
