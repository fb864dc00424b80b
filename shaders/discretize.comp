#version 450
#extension GL_GOOGLE_include_directive : require
// Discretize: one point per end cell (computeDiscreteUpdate). Distinct end keys go into the
// endpoint set; ray_keys (mode 1) then shoots one ray to the centre of each. Non-finite and
// out-of-map points are skipped and counted (OctoMap's unchecked coordToKey would wrap them).
#include "cell_set.glsl"

layout(push_constant) uniform PushBlock { DiscretizeConstants pc; };

void main() {
  uint i = invocationIndex();
  // Behind a scan the device refused (PoolState::halted, set by an earlier submission), tree_gate
  // refuses this scan too and the host runs it again later: its cells are not needed now.
  if (pool.halted != 0u) return;
  if (i >= pc.point_count) return;
  vec3 p = vec3(POINTS[3u * i], POINTS[3u * i + 1u], POINTS[3u * i + 2u]);
  if (!finiteBits(p)) {
    atomicAdd(counters.skipped_nonfinite, 1u);
    return;
  }
  uvec3 k;
  if (!coordToKeyChecked(p.x, k.x) || !coordToKeyChecked(p.y, k.y) ||
      !coordToKeyChecked(p.z, k.z)) {
    atomicAdd(counters.skipped_outside, 1u);
    return;
  }
  uint slot;
  if (insertEndpoint(prefixKey(k, kTreeDepth), slot) == 1u)
    countEndpointEntry(atomicAdd(counters.endpoint_entries, 1u), slot);
}
