#version 450
#extension GL_GOOGLE_include_directive : require
// The log-odds update of every active cell's leaf (updateNodeLogOdds): add, then clamp, in float.
// Each leaf's parent is listed for the prune pass, which then lists its own parents level by level.
#include "common.glsl"
#include "tree.glsl"

void main() {
  uint i = invocationIndex();
  if (i >= pc.count) return;
  // pc.offset cells that descended at the front of `cells`, the ones whose leaf existed at the
  // back (see classify).
  ActiveCell cell = cells[i < pc.offset ? i : params.hash_capacity - 1u - (i - pc.offset)];
  uint n = resolveNode(cell);
  precise float value = nodes[n].log_odds + cellUpdate(cell.slot);
  if (value < params.clamp_min_log) value = params.clamp_min_log;
  else if (value > params.clamp_max_log) value = params.clamp_max_log;
  nodes[n].log_odds = value;
  nodes[n].mask = 0u;
  listParent(kTreeDepth - 1u, n);
}
