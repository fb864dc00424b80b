#version 450
#extension GL_GOOGLE_include_directive : require
// Discretize: one point per end cell (computeDiscreteUpdate). Distinct end keys go into the
// endpoint set; ray_keys (mode 1) then shoots one ray to the centre of each. Non-finite and
// out-of-map points are skipped and counted (OctoMap's unchecked coordToKey would wrap them).
#include "common.glsl"

void main() {
  uint i = invocationIndex();
  if (i >= pc.count) return;
  vec3 p = vec3(points[3u * i], points[3u * i + 1u], points[3u * i + 2u]);
  if (any(isnan(p)) || any(isinf(p))) {
    atomicAdd(counters.skipped_nonfinite, 1u);
    return;
  }
  uvec3 k;
  if (!coordToKeyChecked(p.x, k.x) || !coordToKeyChecked(p.y, k.y) ||
      !coordToKeyChecked(p.z, k.z)) {
    atomicAdd(counters.skipped_outside, 1u);
    return;
  }
  uint64_t key = packKey(k);
  uint cap = params.endpoint_capacity;
  uint s = hashSlot(key, params.endpoint_log2);
  for (uint probe = 0u; probe < 4096u; ++probe) {
    uint64_t prev = atomicCompSwap(endpoint_keys[s], kEmptyKey, key);
    if (prev == kEmptyKey) {
      uint n = atomicAdd(counters.endpoint_entries, 1u);
      if (n >= cap - (cap >> 2)) atomicOr(counters.status, kStatusEndpointHashFull);
      return;
    }
    if (prev == key) return;
    s = (s + 1u) & (cap - 1u);
  }
  atomicOr(counters.status, kStatusEndpointHashFull);
}
