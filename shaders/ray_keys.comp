#version 450
#extension GL_GOOGLE_include_directive : require
// Ray keys and hash set: for every point (kRayKeysPoints) or every distinct end cell
// (kRayKeysEndCells, discretize), the cells of OctoMap's computeRayKeys go into the scan's cell
// set as free and the end cell as occupied (occupied wins: it is a flag on the same entry).
// Mirrors OccupancyOcTreeBase::computeUpdate.
//
// A walk stops after pc.budget loop iterations (steps and hash probes) and is saved to a list;
// kRayKeysContinue continues the walks of one list (pc.from_list) and saves the unfinished ones to
// the other (kRayKeysContinueLast, the last round, reports them instead). Where the device probe
// measured a loop limit (Mesa 22.3's llvmpipe: 65535 iterations in total) the budget stays below
// it; elsewhere it finishes every ray at once.
#include "cell_set.glsl"
#include "ray_walk.glsl"

layout(push_constant) uniform PushBlock { RayKeysConstants pc; };

#include "scan_point.glsl"  // the point's set-up, shared with scan_rays_rt.comp

int budget;  // loop iterations left to this invocation's walk

// Steps until the ray is done (true) or the budget of loop iterations (the walk's and the set's
// probes) is spent (false). The inner loop steps through one brick, only noting the cells it
// marks; the brick lookup comes when the ray enters the next one. In SIMD (lavapipe runs 8 rays
// per instruction) this does the lookups of all lanes together rather than one lane's lookup at
// most steps.
bool walk() {
  while (budget - probes_spent > 0) {
    bool entered = false;
    uvec3 c;
    while (budget - probes_spent > 0) {
      --budget;
      if (rayKeysStep(w, key_end, len)) return true;
      c = w.key;
      if ((c >> 2) != marked_brick) {
        entered = true;
        break;
      }
      noteMark(c);
    }
    if (!entered) return false;
    // A full set ends the walk: the scan is redone with a larger one.
    if (!markCell(c, false)) return true;
  }
  return false;
}

// The lists hold walk_capacity walks each (sized to what scans leave unfinished, not to every
// point): a walk past that is lost, and the scan refused (kStatusWalksShort) and run again with
// longer lists.
void save(uint list, vec3 e) {
  uint at = atomicAdd(counters.walk_count[list], 1u);
  if (at >= params.walk_capacity) {
    atomicOr(counters.status, kStatusWalksShort);
    return;
  }
  if (at % kWorkgroupSize == 0u) OCTOVK_COVER_LIST(counters.walk_args[list], at + 1u);
  WALKS[list * params.walk_capacity + at] =
      WalkState(w.t_max.x, w.t_max.y, w.t_max.z, e.x, e.y, e.z, w.key.x | (w.key.y << 16), w.key.z,
                0u);
}

// A walk saved by an earlier round: its end and DDA state.
bool resumeWalk(uint i, out vec3 e) {
  e = vec3(0.0);
  uint from = pc.from_list;
  if (i >= min(counters.walk_count[from], params.walk_capacity)) return false;
  WalkState saved = WALKS[from * params.walk_capacity + i];
  e = vec3(saved.end_x, saved.end_y, saved.end_z);
  coordToKeyChecked(e.x, key_end.x);
  coordToKeyChecked(e.y, key_end.y);
  coordToKeyChecked(e.z, key_end.z);
  w.t_max = dvec3(saved.t_max_x, saved.t_max_y, saved.t_max_z);
  w.key = uvec3(saved.key_xy & 0xFFFFu, saved.key_xy >> 16, saved.key_z);
  return true;
}

// Each piece of the walk (set-up, steps, set probes) appears once in this shader, whatever the
// mode: llvmpipe (Mesa 22.3) runs the code of every branch for a group of lanes, masked, even
// when no lane takes it, so a second copy of the walk costs every ray that copy's time.
void main() {
  uint i = invocationIndex();
  budget = int(pc.budget);
  // Behind a scan the device refused (PoolState::halted, set by an earlier submission), tree_gate
  // refuses this scan too and the host runs it again later: its cells are not needed now.
  if (pool.halted != 0u) return;
  bool resumed = pc.mode == kRayKeysContinue || pc.mode == kRayKeysContinueLast;
  vec3 e;
  bool walking = resumed ? resumeWalk(i, e) : startPoint(i, e);
  if (walking) {
    setUpWalk(e, !resumed);
    if (!walk()) {
      // After the last continuation a walk still unfinished is an error, not a silently
      // shortened ray.
      if (pc.mode == kRayKeysContinueLast) atomicOr(counters.status, kStatusRayCut);
      else save(resumed ? 1u - pc.from_list : 0u, e);
    }
  }
  flushMarks();
}
