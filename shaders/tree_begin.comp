#version 450
#extension GL_GOOGLE_include_directive : require
// Creates the root if the map is empty (OccupancyOcTreeBase::updateNode creates it on demand):
// only for a scan that tree_gate let through and that updates at least one cell.
#include "node.glsl"

void main() {
  if (invocationIndex() != 0u) return;
  if ((counters.status & kStatusNotApplied) != 0u) return;
  if (counters.active_cells + counters.leaf_cells == 0u) return;
  if (pool.root_exists == 0u) {
    setNodeData(kRootNode, newNodeData());
    setLink(kRootNode, kNoChildren | kFlagLive);
    BLOCK_PARENT[0] = kNoBlock;
    pool.root_exists = 1u;
    pool.live_nodes = 1u;
  }
}
