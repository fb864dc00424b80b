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
#include "walk_cells.glsl"

layout(push_constant) uniform PushBlock { CastRayConstants pc; };

layout(std430, binding = kBindQueryIn) buffer QueryInBuf { RayQuery rays[]; };
layout(std430, binding = kBindQueryOut) buffer QueryOutBuf { RayResult ray_results[]; };
// The same buffer as RayStates, past the results: ray i's walk is saved in element
// pc.first_state + i, which also holds entry i of the two lists of unfinished walks
// (RayState::unfinished). Their fields are written one by one: a whole-struct store would
// overwrite a list entry that another invocation writes.
layout(std430, binding = kBindQueryOut) buffer RayStateBuf { RayState ray_states[]; };

// The walk of this invocation's ray (ray_walk.glsl, walk_cells.glsl).
RayWalk w;
CastRayRange range;
CellCache cache;
bool ignore_unknown;
int budget;
// What one iteration of a jump costs in `budget`. Where the driver limits loops (llvmpipe of Mesa
// 22.3), it counts iterations for a SIMD batch as a whole: the lanes' jumps, taken at different
// steps, add up in the batch's count while each lane's budget sees only its own. Charging a jump
// iteration for a whole batch of 8 lanes keeps the batch's jump iterations within the budget of
// one lane, as its steps are. Where loops are not limited (pc.budget 0x7FFFFFFF), 1.
int jump_charge = 1;
bool jump_tried = true;  // whether the walk already tried to jump across the cached region

// Lists ray i's walk as unfinished in `list`.
void postpone(uint list, uint i) {
  uint at = atomicAdd(counters.walk_count[list], 1u);
  if (at % kWorkgroupSize == 0u) OCTOVK_COVER_LIST(counters.walk_args[list], at + 1u);
  ray_states[pc.first_state + at].unfinished[list] = i;
}

void saveState(uint i, uint done) {
  uint s = pc.first_state + i;
  ray_states[s].t_max_x = w.t_max.x;
  ray_states[s].t_max_y = w.t_max.y;
  ray_states[s].t_max_z = w.t_max.z;
  ray_states[s].key_x = w.key.x;
  ray_states[s].key_y = w.key.y;
  ray_states[s].key_z = w.key.z;
  ray_states[s].done = done;
}

void loadState(uint i) {
  uint s = pc.first_state + i;
  w.t_max = dvec3(ray_states[s].t_max_x, ray_states[s].t_max_y, ray_states[s].t_max_z);
  w.key = uvec3(ray_states[s].key_x, ray_states[s].key_y, ray_states[s].key_z);
}

void finish(uint i, uint hit, vec3 end) {
  ray_results[i] = RayResult(hit, end.x, end.y, end.z);
  saveState(i, 1u);
}

// Steps until the ray has its result (true) or the segment's budget is spent (false). After
// each new lookup (a node not cached yet) the walk first tries to jump across that node.
bool walk(uint i) {
  while (budget > 0) {
    if (!jump_tried) {
      jump_tried = true;
      walkJumpAcrossRegion(w, cache, range, kJumpMinShiftBudgeted, budget, jump_charge);
      if (budget <= 0) break;
    }
    --budget;
    uint hit, cost;
    vec3 end;
    bool done = castRayStep(w, range, cache, ignore_unknown, hit, end, cost);
    budget -= int(cost);
    if (cost != 0u) jump_tried = false;
    if (done) {
      finish(i, hit, end);
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
  ignore_unknown = q.ignore_unknown != 0u;
  cache = walkEmptyCache();

  if (pc.resume != 0u) {
    loadState(i);
    walkSetUp(w, vec3(q.origin_x, q.origin_y, q.origin_z),
              castRayDirection(vec3(q.direction_x, q.direction_y, q.direction_z)), false,
              kHalfStepDouble);
    range = castRayRange(q.max_range, w);
    if (!walk(i)) {
      saveState(i, 0u);
      postpone(2u - pc.resume, i);
    }
    return;
  }

  // Until the walk finishes (this dispatch or a continuation) the result says so.
  ray_results[i].hit = kRayUnfinished;
  uint hit;
  vec3 end;
  if (castRayStart(q, w, cache, range, hit, end)) {
    finish(i, hit, end);
    return;
  }
  jump_tried = false;  // the origin's lookup
  if (!walk(i)) {
    saveState(i, 0u);
    postpone(0u, i);
  }
}
