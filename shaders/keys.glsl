// Keys of cells: OcTreeBaseImpl::coordToKeyChecked / keyToCoord, packed keys and the child
// index along a key's path.
#ifndef OCTOVK_KEYS_GLSL
#define OCTOVK_KEYS_GLSL

#include "bindings.glsl"

// 2^-16: the relative margin every bound on the walks' float and double rounding uses (the max
// range's test_after, the ray-tracing boxes and their slack), far above the errors it covers
// (ray_walk.glsl's castRayRange says why).
const double kRangeMargin = 1.0lf / 65536.0lf;

bool coordToKeyChecked(float coord, out uint key) {
  precise double scaled = floor(params.resolution_factor * double(coord));
  key = 0u;
  // Also rejects NaN; the range test comes before the int conversion, which is undefined beyond it.
  if (!(scaled >= -32768.0lf && scaled < 32768.0lf)) return false;
  key = uint(int(scaled) + 32768);
  return true;
}

double keyToCoord(uint key) {
  precise double c = (double(int(key) - 32768) + 0.5lf) * params.resolution;
  return c;
}

uint64_t packKey(uvec3 k) {
  return uint64_t(k.x) | (uint64_t(k.y) << 16) | (uint64_t(k.z) << 32);
}

uvec3 unpackKey(uint64_t k) {
  return uvec3(uint(k & 0xFFFFul), uint((k >> 16) & 0xFFFFul), uint((k >> 32) & 0xFFFFul));
}

// Index of the child at depth+1 on the path of key k from a node at `depth` (computeChildIdx).
uint childIndex(uvec3 k, uint depth) {
  uint bit = 15u - depth;
  return ((k.x >> bit) & 1u) | (((k.y >> bit) & 1u) << 1) | (((k.z >> bit) & 1u) << 2);
}

#endif  // OCTOVK_KEYS_GLSL
