#version 450
#extension GL_GOOGLE_include_directive : require
// castRay: OccupancyOcTreeBase::castRay for each query ray, step for step (the same DDA in the
// same precision, so the same cells and the same `end`). Cells inside a node already looked up
// (a large free node, or an unknown region) reuse that lookup instead of searching the tree.
//
// The walk runs in resumable segments: pc.resume 0 starts every ray, 1 and 2 continue the
// unfinished ones listed in list 0 or 1 (indirect dispatch) and list those still unfinished in
// the other. A segment stops after about pc.budget loop iterations, below the loop limit the
// device probe measured (Mesa 22.3's llvmpipe: 65535 iterations in total); where none was seen
// the host passes a budget that finishes every ray in one segment.
// No node is written in this pass: links are read plainly (see linkOf).
#define OCTOVK_NODES_READ_ONLY
#include "tree_search.glsl"

layout(push_constant) uniform PushBlock { CastRayConstants pc; };

layout(std430, binding = kBindQueryIn) buffer QueryInBuf { RayQuery rays[]; };
layout(std430, binding = kBindQueryOut) buffer QueryOutBuf { RayResult ray_results[]; };
// The same buffer as RayStates, past the results: ray i's walk is saved in element
// pc.first_state + i, which also holds entry i of the two lists of unfinished walks
// (RayState::unfinished). Their fields are written one by one: a whole-struct store would
// overwrite a list entry that another invocation writes.
layout(std430, binding = kBindQueryOut) buffer RayStateBuf { RayState ray_states[]; };

// The walk of this invocation's ray.
uint key[3];
int step[3];
double t_max[3];
double t_delta[3];
float org[3];
bool max_range_set;
double max_range_sq;
// A step whose tMax (the value it is chosen by) is at most t_safe enters a cell whose centre is
// certainly within max range, so the exact distance test is skipped (see setUp).
double t_safe;
bool ignore_unknown;
int budget;
// What one iteration of a jump costs in `budget`. Where the driver limits loops (llvmpipe of Mesa
// 22.3), it counts iterations for a SIMD batch as a whole: the lanes' jumps, taken at different
// steps, add up in the batch's count while each lane's budget sees only its own. Charging a jump
// iteration for a whole batch of 8 lanes keeps the batch's jump iterations within the budget of
// one lane, as its steps are. Where loops are not limited (pc.budget 0x7FFFFFFF), 1.
int jump_charge = 1;

const double kDoubleMax = 1.7976931348623157e308lf;

// The region of the last lookup: keys whose bits above `shift` equal `prefix` share its answer.
uvec3 cached_prefix;
uint cached_shift = 32u;  // 32: nothing cached
uint cached_state = kCellUnknown;
bool jump_tried = true;  // whether the walk already tried to jump across the cached region

uint cellState(uvec3 k) {
  if (cached_shift < 32u && (k >> cached_shift) == cached_prefix) return cached_state;
  uint node, depth;
  bool found = searchNode(k, node, depth);
  budget -= int(depth) + 1;
  // Found: the node at `depth` covers the keys sharing its prefix. Not found: the missing child
  // one level below the deepest node covers them.
  uint covered = found ? depth : depth + 1u;
  cached_shift = kTreeDepth - covered;
  cached_prefix = k >> cached_shift;
  cached_state = !found
                     ? kCellUnknown
                     : (nodes[node].log_odds >= params.occupancy_log ? kCellOccupied : kCellFree);
  jump_tried = false;
  return cached_state;
}

vec3 keyCentre(uvec3 k) {
  return vec3(toFloat(keyToCoord(k.x)), toFloat(keyToCoord(k.y)), toFloat(keyToCoord(k.z)));
}

// ---- jumping across a region: many of one axis's additions tMax += tDelta at once ----
//
// Each axis's tMax takes the values s, s + d, (s + d) + d, ... (rounded after every addition),
// and the walk takes the smallest of the three (ties: the later axis), so the cells it visits
// are the merge of the three sequences in the order (value, -axis). Inside a region whose answer
// does not end the ray, only leaving the region (or the map), or max range, can end it: the walk
// there is fully known from the sequences, and a jump computes where it leaves without the
// per-cell work, exactly. The additions are not replaced by a formula over the reals: within one
// binade [2^e, 2^(e+1)] every value is a multiple of u = 2^(e-52) and the rounded sum
// t + d is t + round(d / u) * u, the same step for every t there, except when d / u lies exactly
// halfway, where ties-to-even makes the first step of the binade differ and all the later ones
// equal. So two equal consecutive steps inside a binade (observed with real additions) fix the
// step for the rest of it, and the values there are counted in integers, exactly.

const uint64_t kUnits52 = 1ul << 52;
const uint64_t kUnits53 = 1ul << 53;
const uint kSeqIterations = 160u;  // iterations one sequence may take (about 4 per binade)
// Budget a jump may need: five or six sequences and a little.
const int kJumpBudget = int(6u * kSeqIterations) + 8;
// Regions smaller than 2^kJumpMinShift cells a side are walked cell by cell.
const uint kJumpMinShift = 7u;

int biasedExponent(double x) { return int(unpackDouble2x32(x).y >> 20u); }  // sign bit included

uint64_t significand(double x) {
  uvec2 w = unpackDouble2x32(x);
  return ((uint64_t(w.y & 0xFFFFFu) << 32) | uint64_t(w.x)) | kUnits52;
}

// x (> 0) in units of binade e's spacing when x lies in [2^e, 2^(e+1)], else 0.
uint64_t unitsIn(double x, int e) {
  int ex = biasedExponent(x);
  if (ex == e) return significand(x);
  if (ex == e + 1 && significand(x) == kUnits52) return kUnits53;
  return 0ul;
}

double fromUnits(uint64_t units, int e) {
  if (units == kUnits53) {
    units = kUnits52;
    ++e;
  }
  uint64_t bits = (uint64_t(e) << 52) | (units - kUnits52);
  return packDouble2x32(uvec2(uint(bits), uint(bits >> 32)));
}

bool comesBefore(double v, double limit, bool inclusive) {
  return v < limit || (inclusive && v == limit);
}

// Takes the values s, s + d, ... of one axis's tMax that come before `limit` (v < limit, or
// v <= limit when inclusive), at most max_steps of them; s becomes the first value not taken,
// as the walk's additions would make it. False when it cannot tell within its iterations (or
// the values stop growing or overflow): the caller then walks cell by cell.
bool advanceAxis(inout double s, double d, uint max_steps, double limit, bool inclusive,
                 out uint taken) {
  taken = 0u;
  double a = 0.0lf, b = 0.0lf;  // the two values before s, when `history` real additions led to s
  uint history = 0u;
  for (uint it = 0u; it < kSeqIterations; ++it) {
    budget -= jump_charge;
    if (taken == max_steps || !comesBefore(s, limit, inclusive)) return true;
    int e = biasedExponent(a);
    if (history >= 2u && a > 0.0lf && e > 0 && e < 0x7FE && biasedExponent(b) == e) {
      uint64_t au = significand(a), bu = significand(b), su = unitsIn(s, e);
      if (su != 0ul && bu - au == su - bu) {  // the binade's step is known: take many at once
        uint64_t inc = su - bu;
        uint64_t k = (kUnits53 - su) / inc;  // steps that stay in the binade (or end at its top)
        k = min(k, uint64_t(max_steps - taken));
        // A limit in this binade is a multiple of u: count the values su + j * inc before it.
        // A limit above the binade is above every value counted here; one below it is
        // impossible (s comes before the limit).
        if (biasedExponent(limit) == e) {
          uint64_t last = significand(limit) - (inclusive ? 0ul : 1ul);
          k = min(k, last >= su ? (last - su) / inc + 1ul : 0ul);
        }
        if (k > 0ul) {
          s = fromUnits(su + k * inc, e);
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

// In a region (the cached one) whose answer does not end the ray: advances the walk to just
// before the first step that leaves the region or that may end the ray by max range (its tMax
// above t_safe), taking exactly the steps the cell-by-cell walk would take. Does nothing where
// it cannot tell.
void jumpAcrossRegion() {
  jump_tried = true;
  uint shift = cached_shift;
  if (shift >= 32u || shift < kJumpMinShift) return;
  if (budget < kJumpBudget * jump_charge) return;
  // Steps each axis can take without leaving the region's key box.
  uint room[3];
  for (int a = 0; a < 3; ++a) {
    uint lo = cached_prefix[a] << shift;
    uint hi = lo + ((1u << shift) - 1u);
    room[a] = step[a] > 0 ? hi - key[a] : (step[a] < 0 ? key[a] - lo : 0u);
  }
  if (max_range_set && !(min(t_max[0], min(t_max[1], t_max[2])) <= t_safe)) return;
  // Axis a's step that leaves the box is chosen by its value after room[a] additions; the first
  // of those (value, then the later axis) is where the walk leaves.
  double leave_value[3];
  int first = -1;
  for (int a = 0; a < 3; ++a) {
    if (step[a] == 0) continue;
    double s = t_max[a];
    uint taken;
    if (!advanceAxis(s, t_delta[a], room[a], kDoubleMax, true, taken) || taken != room[a]) return;
    leave_value[a] = s;
    if (first < 0 || s <= leave_value[first]) first = a;
  }
  // Stays below the tMax of an axis that does not step (the largest double), which is then
  // never chosen, as in the walk.
  if (first < 0 || !(leave_value[first] < kDoubleMax)) return;
  // Stop before the step leaving the box, or before the first step above t_safe if that comes
  // first: the walk takes every value that comes before.
  bool by_leaving = !max_range_set || leave_value[first] <= t_safe;
  double limit = by_leaving ? leave_value[first] : t_safe;
  double value[3];
  uint taken[3];
  for (int a = 0; a < 3; ++a) {
    value[a] = t_max[a];
    taken[a] = 0u;
    if (step[a] == 0) continue;
    if (by_leaving && a == first) {
      value[a] = leave_value[a];
      taken[a] = room[a];
      continue;
    }
    // Equal values: the later axis comes first.
    bool inclusive = !by_leaving || a > first;
    if (!advanceAxis(value[a], t_delta[a], room[a], limit, inclusive, taken[a])) return;
  }
  for (int a = 0; a < 3; ++a) {
    key[a] = uint(int(key[a]) + step[a] * int(taken[a]));
    t_max[a] = value[a];
  }
}

// Lists ray i's walk as unfinished in `list`.
void postpone(uint list, uint i) {
  uint at = atomicAdd(counters.walk_count[list], 1u);
  if (at % kWorkgroupSize == 0u) OCTOVK_COVER_LIST(counters.walk_args[list], at + 1u);
  ray_states[pc.first_state + at].unfinished[list] = i;
}

void saveState(uint i, uint done) {
  uint s = pc.first_state + i;
  ray_states[s].t_max_x = t_max[0];
  ray_states[s].t_max_y = t_max[1];
  ray_states[s].t_max_z = t_max[2];
  ray_states[s].key_x = key[0];
  ray_states[s].key_y = key[1];
  ray_states[s].key_z = key[2];
  ray_states[s].done = done;
}

void loadState(uint i) {
  uint s = pc.first_state + i;
  t_max = double[3](ray_states[s].t_max_x, ray_states[s].t_max_y, ray_states[s].t_max_z);
  key = uint[3](ray_states[s].key_x, ray_states[s].key_y, ray_states[s].key_z);
}

void finish(uint i, uint hit, vec3 end) {
  ray_results[i] = RayResult(hit, end.x, end.y, end.z);
  saveState(i, 1u);
}

// Direction and origin of ray q as castRay computes them: step, tDelta and (when starting)
// tMax. direction.normalized(): the norm in double of the float squared norm, divided as float.
bool setUp(RayQuery q, bool start) {
  org = float[3](q.origin_x, q.origin_y, q.origin_z);
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
  for (int a = 0; a < 3; ++a) {
    step[a] = dir[a] > 0.0 ? 1 : (dir[a] < 0.0 ? -1 : 0);
    if (step[a] != 0) {
      t_delta[a] = params.resolution / double(abs(dir[a]));
      if (start) {
        precise double border = keyToCoord(key[a]);
        precise double half_step = double(step[a]) * params.resolution * 0.5lf;
        border += half_step;
        t_max[a] = (border - double(org[a])) / double(dir[a]);
      }
    } else {
      t_delta[a] = kDoubleMax;
      if (start) t_max[a] = kDoubleMax;
    }
  }
  max_range_set = q.max_range > 0.0lf;
  max_range_sq = q.max_range * q.max_range;
  // The walk's tMax values are where the ray org + t * dir crosses the cell borders (to far below
  // a cell's size: rounding of the setup and at most 3 * 65536 additions), so the ray point at a
  // step's tMax lies in the cell that step enters (on its entry face), whose centre is within
  // sqrt(3) / 2 cells of it; the centre as float moves by at most 2^-24 of a coordinate below
  // 2^15 cells, and the float distance test errs by a few 2^-24 relative. So with
  // tMax * |dir| <= max_range * (1 - 2^-20) - 2 cells, the test cannot fail. |dir| in double,
  // from the float components (not 1 when the norm underflowed and nothing was normalized).
  t_safe = -kDoubleMax;
  if (max_range_set) {
    precise double dir_len =
        sqrt(double(dir[0]) * double(dir[0]) + double(dir[1]) * double(dir[1]) +
             double(dir[2]) * double(dir[2]));
    const double kSlack = 1.0lf / 1048576.0lf;  // 2^-20
    precise double bound =
        (q.max_range * (1.0lf - kSlack) - 2.0lf * params.resolution) / (dir_len * (1.0lf + kSlack));
    if (bound > 0.0lf && bound <= kDoubleMax) t_safe = bound;
  }
  ignore_unknown = q.ignore_unknown != 0u;
  return step[0] != 0 || step[1] != 0 || step[2] != 0;
}

// Steps until the ray has its result (true) or the segment's budget is spent (false).
bool walk(uint i) {
  while (budget > 0) {
    // The cached region holds the current cell and does not end the ray.
    if (!jump_tried) {
      jumpAcrossRegion();
      if (budget <= 0) break;
    }
    --budget;
    int dim;
    if (t_max[0] < t_max[1])
      dim = t_max[0] < t_max[2] ? 0 : 2;
    else
      dim = t_max[1] < t_max[2] ? 1 : 2;
    if ((step[dim] < 0 && key[dim] == 0u) ||
        (step[dim] > 0 && key[dim] == 2u * kTreeMaxVal - 1u)) {
      finish(i, 0u, keyCentre(uvec3(key[0], key[1], key[2])));  // the map's border
      return true;
    }
    double chosen = t_max[dim];
    key[dim] = uint(int(key[dim]) + step[dim]);
    t_max[dim] += t_delta[dim];
    uvec3 k = uvec3(key[0], key[1], key[2]);
    if (max_range_set && !(chosen <= t_safe)) {
      vec3 e = keyCentre(k);
      precise float dx = e.x - org[0];
      precise float dy = e.y - org[1];
      precise float dz = e.z - org[2];
      precise float sx = dx * dx;
      precise float sy = dy * dy;
      precise float sz = dz * dz;
      precise double dist_sq = 0.0lf;
      dist_sq += double(sx);
      dist_sq += double(sy);
      dist_sq += double(sz);
      if (dist_sq > max_range_sq) {
        finish(i, 0u, e);
        return true;
      }
    }
    uint state = cellState(k);
    if (state == kCellOccupied) {
      finish(i, 1u, keyCentre(k));
      return true;
    }
    if (state == kCellUnknown && !ignore_unknown) {
      finish(i, 0u, keyCentre(k));
      return true;
    }
  }
  return false;
}

void main() {
  uint i = invocationIndex();
  budget = int(pc.budget);
  jump_charge = pc.budget >= 0x7FFFFFFFu ? 1 : 8;
  if (pc.resume != 0u) {  // continue the walks listed in list pc.resume - 1
    uint from = pc.resume - 1u;
    if (i >= counters.walk_count[from]) return;
    i = ray_states[pc.first_state + i].unfinished[from];
  } else if (i >= pc.ray_count) {
    return;
  }
  RayQuery q = rays[i];
  vec3 origin = vec3(q.origin_x, q.origin_y, q.origin_z);

  if (pc.resume != 0u) {
    loadState(i);
    setUp(q, false);
    if (!walk(i)) {
      saveState(i, 0u);
      postpone(2u - pc.resume, i);
    }
    return;
  }

  // Until the walk finishes (this dispatch or a continuation) the result says so.
  ray_results[i].hit = kRayUnfinished;
  // Start: where OctoMap leaves `end` untouched, it is the origin.
  if (!coordToKeyChecked(q.origin_x, key[0]) || !coordToKeyChecked(q.origin_y, key[1]) ||
      !coordToKeyChecked(q.origin_z, key[2])) {
    finish(i, 0u, origin);
    return;
  }
  uvec3 k0 = uvec3(key[0], key[1], key[2]);
  uint start = cellState(k0);
  if (start == kCellOccupied) {
    finish(i, 1u, keyCentre(k0));
    return;
  }
  if (start == kCellUnknown && q.ignore_unknown == 0u) {
    finish(i, 0u, keyCentre(k0));
    return;
  }
  if (!setUp(q, true)) {  // direction (0, 0, 0): OctoMap refuses
    finish(i, 0u, origin);
    return;
  }
  if (!walk(i)) {
    saveState(i, 0u);
    postpone(0u, i);
  }
}
