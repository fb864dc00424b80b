// Scans through ray tracing (MapParams::scan_rays, ray tracing): the cells of OctoMap's
// computeRayKeys for every point (kRayKeysPoints) or distinct end cell (kRayKeysEndCells), as
// ray_keys.comp marks them, except cells whose leaf is clamped free: a free update there is a
// no-op (updateNode's early abort), so those cells may be left out of the cell set exactly.
// The boxes (accel_boxes.comp, kAccelBoxesScan) cover every other cell of the map: leaves above
// clamp_min_log and unknown regions, each enlarged by a 64th of a cell. Per ray a ray query finds
// the nearest box; the walk jumps exactly (walkJumpTo: the same tMax bits as stepping) to
// just before it, then steps OctoMap's DDA, marking each cell whose node is not clamped free
// (a tree lookup, cached per node), and traces again from the first clamped-free cell past the
// box's entry. Every cell marked is one computeRayKeys visits (the walk is OctoMap's, jumps
// included); every cell it visits that a free update changes is marked (no box starts before a
// jump's target; stepped cells are looked up). The end cell is marked occupied from the point,
// as ray_keys does.
//
// The per-point checks and the ray's start are ray_keys.comp's (scan_point.glsl). Runs only
// where loops have no driver limit (the host refuses it elsewhere), so every ray is walked in one
// go. Built twice: scan_rays_rt.comp traces with ray queries, scan_rays_rt.rgen (with
// OCTOVK_RAY_PIPELINE, one invocation per point) through a ray-tracing pipeline.
#ifndef OCTOVK_SCAN_RAYS_RT_GLSL
#define OCTOVK_SCAN_RAYS_RT_GLSL

#define OCTOVK_NODES_READ_ONLY
#ifndef OCTOVK_RAY_PIPELINE
#define OCTOVK_RAY_QUERY
#endif
#include "cell_set.glsl"
#include "walk_cells.glsl"
#include "accel_trace.glsl"

#ifndef OCTOVK_RAY_PIPELINE
layout(push_constant) uniform PushBlock { ScanRaysRtConstants pc; };
#else
OCTOVK_RAY_CONSTANTS(ScanRaysRtConstants);
#endif

#include "scan_point.glsl"

// Whether a free update of cell k is a no-op: search() finds a node at clamp_min_log
// (classify's early abort). The cache answers for every cell of the node it last found.
bool clampedFree(uvec3 k, inout CellCache cache) {
  uint cost;
  return walkCellState(k, cache, cost) != kCellUnknown && cache.log_odds <= params.clamp_min_log;
}

// The walk from the origin's cell (marked by the caller) to the end. A ray query finds the
// nearest box; the walk jumps exactly to just before it, then steps, marking every cell a free
// update can change, until it steps into a cell clamped free past the box's entry: then the
// next box is traced from there. Neighbouring boxes cost one ray query together, not one each.
void walkTraced() {
  CellCache cache = walkEmptyCache();
  if (pool.root_exists == 0u) {  // an empty map is unknown everywhere: every cell is updated
    while (!rayKeysStep(w, key_end, len))
      if (!markCell(w.key, false)) return;  // a full set: the scan is redone with a larger one
    return;
  }
  AccelRef scene = AccelRef(pc.boxes);
  double dir_len = walkDirLength(w);
  // Jumps stop two cells short of the end, so that no jump passes the end cell or the cell where
  // OctoMap's length test ends the walk (a cell entered before t_limit is left before the
  // length); the last cells are stepped.
  double t_limit = (double(len) - 2.0lf * params.resolution - double(len) * kRangeMargin) /
                   (dir_len * (1.0lf + kRangeMargin));
  // Boxes beyond the end do not matter.
  float t_to = float((double(len) + 2.0lf * params.resolution) / dir_len);
  for (;;) {
    double t_from = walkMinTMax(w) - slack(walkMinTMax(w), w.org, dir_len);
    double t_enter = 1.0e300lf, t_exit;
    bool found = t_from < double(t_to) &&
                 nearestBox(scene, w, t_from, t_to, /*fixed_axes=*/true, t_enter, t_exit);
    double target = min(t_enter, t_limit);
    target -= slack(target, w.org, dir_len);
    // The cells the jump passes lie in no box (clamped free): their updates are no-ops. The
    // cell it lands in is entered before the target: in no box either. (A jump that cannot tell
    // is not taken: the cells are then stepped and looked up.)
    int no_budget = 0;
    if (target > walkMinTMax(w)) walkJumpTo(w, target, no_budget, 0);
    // A clamped-free cell before the box's entry (and its slack) is still on the way in. Past
    // it, a run of kRetraceAfter clamped-free cells ends the stretch: near surfaces, where
    // clamped cells and cells not clamped yet alternate, a ray query per clamped cell costs
    // more than stepping a few cells (on lavapipe a query costs tens of steps).
    const uint kRetraceAfter = 8u;
    double t_in = found ? t_enter + 2.0lf * slack(t_enter, w.org, dir_len) : 1.0e300lf;
    uint clamped_run = 0u;
    for (;;) {
      if (rayKeysStep(w, key_end, len)) return;
      if (!clampedFree(w.key, cache)) {
        clamped_run = 0u;
        if (!markCell(w.key, false)) return;  // a full set: the scan is redone
      } else if (walkMinTMax(w) > t_in && ++clamped_run >= kRetraceAfter) {
        break;
      }
    }
  }
}

void main() {
  uint i = invocationIndex();
  // Behind a scan the device refused (PoolState::halted), tree_gate refuses this scan too.
  if (pool.halted != 0u) return;
  vec3 e;
  if (startPoint(i, e)) {
    setUpWalk(e, true);
    walkTraced();
  }
  flushMarks();
}

#endif  // OCTOVK_SCAN_RAYS_RT_GLSL
