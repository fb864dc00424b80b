// Host twins of the map math in shaders/keys.glsl, in OctoMap's arithmetic.
#pragma once

#include <cmath>
#include <cstdint>

#include "octovk/octovk.hpp"

namespace octovk::ref {

/// octomap::logodds: computed in double, stored as float.
inline float logodds(double probability) {
  return static_cast<float>(std::log(probability / (1.0 - probability)));
}

struct LogOddsParams {
  float hit = 0, miss = 0, clamp_min = 0, clamp_max = 0, occupancy = 0;
  static LogOddsParams from(const MapParams& p) {
    return {logodds(p.prob_hit), logodds(p.prob_miss), logodds(p.clamping_min),
            logodds(p.clamping_max), logodds(p.occupancy_threshold)};
  }
};

/// OcTreeBaseImpl::coordToKeyChecked for one coordinate (NaN and out-of-map fail).
inline bool coordToKeyChecked(double resolution_factor, float coordinate, std::uint32_t& key) {
  const double scaled = std::floor(resolution_factor * coordinate);
  if (!(scaled >= -32768.0 && scaled < 32768.0)) return false;
  key = static_cast<std::uint32_t>(static_cast<int>(scaled) + 32768);
  return true;
}

}  // namespace octovk::ref
