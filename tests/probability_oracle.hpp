// What the checks of integrateNodeColor's weight (shaders/probability.glsl) share, in
// tests/payload_oracle_test.cpp and bench/probability_exhaustive.cpp: floats walked in the order of
// their values, and OctoMap's integrateNodeColor step on one channel as liboctomap computes it.
#pragma once

#include <bit>
#include <cstdint>

namespace octovk::test {

/// Floats in the order of their values: ordinal 0 is +-0, n > 0 the n-th float above 0, -n below.
inline float floatOfOrdinal(std::int64_t o) {
  const auto magnitude = std::bit_cast<float>(static_cast<std::uint32_t>(o < 0 ? -o : o));
  return o < 0 ? -magnitude : magnitude;
}
inline std::int64_t ordinalOf(float f) {
  const auto bits = std::bit_cast<std::uint32_t>(f);
  const auto magnitude = static_cast<std::int64_t>(bits & 0x7FFFFFFFu);
  return (bits & 0x80000000u) ? -magnitude : magnitude;
}

/// What integrateNodeColor makes of one channel (old, new) at occupancy p: the double, converted
/// to uint8_t as liboctomap on x86-64 does (cvttsd2si: toward zero to int32, the low 8 bits).
inline std::uint8_t integratedChannel(int old, int c, double p) {
  const double v = static_cast<double>(old) * p + static_cast<double>(c) * (0.99 - p);
  return static_cast<std::uint8_t>(static_cast<std::int32_t>(v) & 0xFF);
}

}  // namespace octovk::test
