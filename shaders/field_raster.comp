#version 450
#extension GL_GOOGLE_include_directive : require
// The distance field's obstacles: for each cell of the box at the finest depth, OctoMap's
// search(key) and isNodeOccupied (log-odds >= the occupancy threshold); a cell search() does not
// find is unknown, an obstacle only with FieldHeader::unknown_occupied (DynamicEDTOctomap's
// treatUnknownAsOccupied). A pruned leaf answers for each of its finest cells. Writes array A:
// squared distance 0 and the cell itself as site on an obstacle, kFieldFar elsewhere.
// No node is written in this pass: links are read plainly (see linkOf).
#define OCTOVK_NODES_READ_ONLY
#include "tree_search.glsl"
#include "field.glsl"

layout(push_constant) uniform PushBlock { FieldRasterConstants pc; };

void main() {
  uint i = invocationIndex();
  if (i >= pc.cell_count) return;
  FieldHeaderRef f = FieldHeaderRef(pc.header);
  uvec3 k = fieldMinKey(f) + fieldCell(i, fieldSize(f));
  uint node, depth;
  bool occupied = f.h.unknown_occupied != 0u;
  if (searchNode(k, node, depth)) occupied = nodes[node].log_odds >= params.occupancy_log;
  FieldCellsRef(f.h.cells_a).v[i] =
      occupied ? FieldCell(0u, i) : FieldCell(kFieldFar, kFieldNoSite);
}
