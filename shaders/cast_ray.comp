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
#include "common.glsl"

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
bool ignore_unknown;
int budget;

// The region of the last lookup: keys whose bits above `shift` equal `prefix` share its answer.
uvec3 cached_prefix;
uint cached_shift = 32u;  // 32: nothing cached
uint cached_state = kCellUnknown;

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
  return cached_state;
}

vec3 keyCentre(uvec3 k) {
  return vec3(toFloat(keyToCoord(k.x)), toFloat(keyToCoord(k.y)), toFloat(keyToCoord(k.z)));
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
  const double kDoubleMax = 1.7976931348623157e308lf;
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
  ignore_unknown = q.ignore_unknown != 0u;
  return step[0] != 0 || step[1] != 0 || step[2] != 0;
}

// Steps until the ray has its result (true) or the segment's budget is spent (false).
bool walk(uint i) {
  for (; budget > 0; --budget) {
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
    key[dim] = uint(int(key[dim]) + step[dim]);
    t_max[dim] += t_delta[dim];
    uvec3 k = uvec3(key[0], key[1], key[2]);
    vec3 e = keyCentre(k);
    if (max_range_set) {
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
      finish(i, 1u, e);
      return true;
    }
    if (state == kCellUnknown && !ignore_unknown) {
      finish(i, 0u, e);
      return true;
    }
  }
  return false;
}

void main() {
  uint i = invocationIndex();
  budget = int(pc.budget);
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
