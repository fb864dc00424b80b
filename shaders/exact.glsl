// The exact arithmetic every pass shares with OctoMap's host code: float roundings done on the
// bits, and float division and norm as OctoMap computes them. No bindings: the device probe
// (device_probe.comp) includes it too and checks it, bit for bit, against the host.
// Needs GL_EXT_shader_explicit_arithmetic_types_int64 (enabled by the includer).
#ifndef OCTOVK_EXACT_GLSL
#define OCTOVK_EXACT_GLSL

// ---- float helpers that match IEEE single precision on the host ----

// x rounded to the nearest float (ties to even), returned as the double that holds exactly that
// float's value. Done on the bits in integer arithmetic, because no Vulkan rule protects a
// rounding done by conversion: the rounding mode of OpFConvert is not fixed, `precise` does not
// cover conversions, and compilers fold double(float(x)) back to x (Mesa 25 does). A value that is
// already a float converts to float and back unchanged whatever the compiler does.
double roundedToFloat(double x) {
  uvec2 w = unpackDouble2x32(x);
  uint sign = w.y & 0x80000000u;
  int biased = int((w.y >> 20) & 0x7FFu);
  if (biased == 0x7FF) return x;                                // inf, NaN
  if (biased == 0) return packDouble2x32(uvec2(0u, sign));      // |x| < 2^-1022: float 0
  int e = biased - 1023;
  if (e > 128) return packDouble2x32(uvec2(0u, sign | 0x7FF00000u));  // beyond float: inf
  // The 53-bit significand loses 29 bits for a normal float, more below float's normal range.
  uint64_t sig = (uint64_t(w.y & 0xFFFFFu) << 32) | uint64_t(w.x) | (1ul << 52);
  uint drop = 29u + uint(max(-126 - e, 0));
  if (drop > 54u) return packDouble2x32(uvec2(0u, sign));       // below half the least subnormal
  uint64_t unit = 1ul << drop;
  uint64_t rest = sig & (unit - 1ul);
  uint64_t half_unit = unit >> 1;
  sig -= rest;
  if (rest > half_unit || (rest == half_unit && (sig & unit) != 0ul)) sig += unit;
  if (sig == 0ul) return packDouble2x32(uvec2(0u, sign));
  if (sig >= (1ul << 53)) {                                     // carried into the next binade
    sig >>= 1;
    ++e;
  }
  if (e > 127) return packDouble2x32(uvec2(0u, sign | 0x7FF00000u));  // rounded up past FLT_MAX
  uint64_t bits = (uint64_t(e + 1023) << 52) | (sig & ((1ul << 52) - 1ul));
  return packDouble2x32(uvec2(uint(bits), uint(bits >> 32) | sign));
}

// float(x) with IEEE round-to-nearest-even, whatever the device and compiler do with conversions.
float toFloat(double x) { return float(roundedToFloat(x)); }
vec3 toFloat(dvec3 x) { return vec3(toFloat(x.x), toFloat(x.y), toFloat(x.z)); }

// Whether x is finite, decided on its bits: a compiler that assumes no NaN or inf may fold
// isnan / isinf away (SPIR-V leaves that to float-controls modes these shaders do not set).
bool finiteBits(float x) { return (floatBitsToUint(x) & 0x7F800000u) != 0x7F800000u; }
bool finiteBits(vec3 v) { return finiteBits(v.x) && finiteBits(v.y) && finiteBits(v.z); }

// Correctly rounded a / b in float: double has more than 2 * 24 + 2 bits, so rounding the
// correctly rounded double quotient to float gives the correctly rounded float quotient (Vulkan
// allows 2.5 ULP for a float division; the double division is checked by the device probe).
float divFloat(float a, float b) {
  precise double q = double(a) / double(b);
  return toFloat(q);
}

// Vector3::norm(): the squared norm summed in float, its square root taken in double.
double normOf(float x, float y, float z) {
  precise float sq = x * x + y * y + z * z;
  return sqrt(double(sq));
}

#endif  // OCTOVK_EXACT_GLSL
