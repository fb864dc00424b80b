// What a walk (ray_walk.glsl) finds in the tree, for the passes that look cells up as they walk
// (cast_ray.comp, cast_ray_rt.glsl, scan_rays_rt.comp): a tree lookup cached per node, castRay's
// start and step (border, max range, lookup) and the exact jump across a node a lookup found.
// The including pass writes no node (OCTOVK_NODES_READ_ONLY: links are read plainly).
#ifndef OCTOVK_WALK_CELLS_GLSL
#define OCTOVK_WALK_CELLS_GLSL

#include "ray_walk.glsl"
#include "tree_search.glsl"

// ---- the cell cache ----

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

CellCache walkEmptyCache() {
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

// kCellUnknown / kCellFree / kCellOccupied of cell k (OctoMap's search, isNodeOccupied). The
// search resumed from path[depth] visits the nodes a search from the root visits below that
// depth (the node is on both keys' paths, and no node changes while a pass walks), so it finds
// the same node. Over an empty map (no root) the whole map is one unknown region.
// `cost`: 0 when the cache answered, else the iterations of the search's loop and one (for walk
// budgets, and to tell a new lookup).
uint walkCellState(uvec3 k, inout CellCache c, out uint cost) {
  cost = 0u;
  if (c.shift < 32u && (k >> c.shift) == c.prefix) return c.state;
  cost = 1u;
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
    ++cost;
    uint block = childBlock(node);
    if (block == kNoChildren) break;  // a leaf (search() finds it)
    uint child = block * 8u + childIndex(k, depth);
    if (!linkLive(linkOf(child))) {  // a node with other children but not this one
      found = false;
      break;
    }
    node = child;
    c.path[depth + 1u] = child;
  }
  c.key = k;
  c.path_depth = depth;
  // Found: the node at `depth` covers the keys sharing its prefix. Not found: the missing child
  // one level below the deepest node covers them.
  uint covered = found ? depth : depth + 1u;
  c.shift = kTreeDepth - covered;
  c.prefix = k >> c.shift;
  c.log_odds = found ? nodeLogOdds(node) : 0.0;
  c.state = !found ? kCellUnknown
                   : (c.log_odds >= params.occupancy_log ? kCellOccupied : kCellFree);
  return c.state;
}

// ---- castRay ----

// castRay up to its incremental phase: the origin's key and cell, then the set-up. True when the
// ray has its answer already (`hit`, `end`): the origin outside the map or in a cell that ends
// the ray, or the direction (0, 0, 0), which OctoMap refuses. Where OctoMap leaves `end`
// untouched, it is the origin.
bool castRayStart(RayQuery q, inout RayWalk w, inout CellCache c, out CastRayRange range,
                  out uint hit, out vec3 end) {
  vec3 origin = vec3(q.origin_x, q.origin_y, q.origin_z);
  hit = 0u;
  end = origin;
  range.set = false;
  if (!coordToKeyChecked(q.origin_x, w.key.x) || !coordToKeyChecked(q.origin_y, w.key.y) ||
      !coordToKeyChecked(q.origin_z, w.key.z))
    return true;
  uint cost;
  uint start = walkCellState(w.key, c, cost);
  if (start == kCellOccupied || (start == kCellUnknown && q.ignore_unknown == 0u)) {
    hit = start == kCellOccupied ? 1u : 0u;
    end = walkCellCentre(w.key);
    return true;
  }
  vec3 dir = castRayDirection(vec3(q.direction_x, q.direction_y, q.direction_z));
  walkSetUp(w, origin, dir, true, kHalfStepDouble);
  range = castRayRange(q.max_range, w);
  return w.step == ivec3(0);
}

// One step of castRay's walk and what the new cell says: true when the ray has its answer
// (`hit`, `end`): the map's border, the first cell beyond the max range, an occupied cell, or an
// unknown one unless ignored. `cost`: the lookup's (walkCellState).
bool castRayStep(inout RayWalk w, CastRayRange range, inout CellCache c, bool ignore_unknown,
                 out uint hit, out vec3 end, out uint cost) {
  hit = 0u;
  cost = 0u;
  bvec3 axis = walkNextAxis(w);
  if (walkAtBorder(w, axis)) {
    end = walkCellCentre(w.key);  // OctoMap returns the border cell
    return true;
  }
  double chosen = walkMinTMax(w);  // the tMax this step is chosen by
  walkStep(w, axis);
  end = vec3(0.0);
  if (range.set && !(chosen <= range.test_after)) {
    end = walkCellCentre(w.key);
    if (castRayBeyondRange(range, w.org, end)) return true;
  }
  uint state = walkCellState(w.key, c, cost);
  if (state == kCellOccupied || (state == kCellUnknown && !ignore_unknown)) {
    hit = state == kCellOccupied ? 1u : 0u;
    end = walkCellCentre(w.key);
    return true;
  }
  return false;
}

// ---- the jump across a node ----

// Regions smaller than 2^min_shift cells a side are walked cell by cell. A jump's worth is the
// driver's: where loops are budgeted (cast_ray on llvmpipe 22.3) a jump reserves kJumpBudget and
// pays off only across large nodes; without a budget (the ray-tracing castRay) a node of 4 cells
// a side is already worth it. Either value gives the same answers.
const uint kJumpMinShiftBudgeted = 7u;
const uint kJumpMinShiftFree = 2u;
// Budget a jump may need: five or six sequences and a little.
const int kJumpBudget = int(6u * kSeqIterations) + 8;

// In the region the cache holds (the node of the current cell), whose answer does not end the
// ray: advances the walk to just before the first step that leaves the region or that may end
// the ray by max range (its tMax above range.test_after), taking exactly the steps the
// cell-by-cell walk would take (walkAdvanceAxis). Does nothing where it cannot tell. Nothing
// else can end a castRay walk inside such a region: every cell there has the region's answer,
// and the region lies inside the map (no border). (cast_ray_rt jumped to an approximate exit
// parameter of the node less a slack instead: also only steps the walk takes through cells of
// the node, so the same answers; this one needs no slack and reaches the node's last cell.)
void walkJumpAcrossRegion(inout RayWalk w, CellCache c, CastRayRange range, uint min_shift,
                          inout int budget, int charge) {
  uint shift = c.shift;
  if (shift >= 32u || shift < min_shift) return;
  if (budget < kJumpBudget * charge) return;
  // Steps each axis can take without leaving the region's key box.
  uint room[3];
  for (int a = 0; a < 3; ++a) {
    uint lo = c.prefix[a] << shift;
    uint hi = lo + ((1u << shift) - 1u);
    room[a] = w.step[a] > 0 ? hi - w.key[a] : (w.step[a] < 0 ? w.key[a] - lo : 0u);
  }
  if (range.set && !(walkMinTMax(w) <= range.test_after)) return;
  // Axis a's step that leaves the box is chosen by its value after room[a] additions; the first
  // of those (value, then the later axis) is where the walk leaves.
  double leave_value[3];
  int first = -1;
  for (int a = 0; a < 3; ++a) {
    if (w.step[a] == 0) continue;
    double s = w.t_max[a];
    uint taken;
    if (!walkAdvanceAxis(s, w.t_delta[a], room[a], kDoubleMax, true, taken, budget, charge) ||
        taken != room[a])
      return;
    leave_value[a] = s;
    if (first < 0 || s <= leave_value[first]) first = a;
  }
  // Stays below the tMax of an axis that does not step (the largest double), which is then
  // never chosen, as in the walk.
  if (first < 0 || !(leave_value[first] < kDoubleMax)) return;
  // Stop before the step leaving the box, or before the first step above test_after if that
  // comes first: the walk takes every value that comes before.
  bool by_leaving = !range.set || leave_value[first] <= range.test_after;
  double limit = by_leaving ? leave_value[first] : range.test_after;
  double value[3];
  uint taken[3];
  for (int a = 0; a < 3; ++a) {
    value[a] = w.t_max[a];
    taken[a] = 0u;
    if (w.step[a] == 0) continue;
    if (by_leaving && a == first) {
      value[a] = leave_value[a];
      taken[a] = room[a];
      continue;
    }
    // Equal values: the later axis comes first.
    bool inclusive = !by_leaving || a > first;
    if (!walkAdvanceAxis(value[a], w.t_delta[a], room[a], limit, inclusive, taken[a], budget,
                         charge))
      return;
  }
  for (int a = 0; a < 3; ++a) {
    w.key[a] = uint(int(w.key[a]) + w.step[a] * int(taken[a]));
    w.t_max[a] = value[a];
  }
}

#endif  // OCTOVK_WALK_CELLS_GLSL
