// The render command's camera: a pinhole camera and its rays per pixel, the box
// of the occupied cells and a ray's stretch through it, and where the default
// camera looks from and stands.
#pragma once

#include <Eigen/Core>
#include <algorithm>
#include <cmath>
#include <cstdint>
#include <limits>
#include <utility>
#include <vector>

#include "octovk/octovk.hpp"

namespace octovk::cli {

using Vec3 = Eigen::Vector3d;

// The default camera looks down at this angle, from the side of the box's
// longer horizontal axis and a little from its start, so that the long side
// fills the picture's width.
constexpr double kDefaultElevationDeg = 55.0;
constexpr double kDefaultSkewDeg = 18.0;

// A pinhole camera; pixel (x, y) counts from the top-left corner.
struct Camera {
  Vec3 eye, look_at, forward, right, up;
  double tan_half_h = 0, tan_half_v = 0;
  std::uint32_t width = 0, height = 0;

  Camera(const Vec3& eye_in, const Vec3& look_at_in, std::uint32_t w, std::uint32_t h,
         double fov_v_deg)
      : eye(eye_in), look_at(look_at_in), width(w), height(h) {
    forward = (look_at - eye).normalized();
    // Looking straight up or down, "up" in the picture is +y instead of +z.
    const Vec3 world_up = std::abs(forward.z()) > 0.9999 ? Vec3::UnitY() : Vec3::UnitZ();
    right = forward.cross(world_up).normalized();
    up = right.cross(forward);
    tan_half_v = std::tan(fov_v_deg * M_PI / 360.0);
    tan_half_h = tan_half_v * w / h;
  }

  Vec3 direction(double px, double py) const {
    const double sx = (2.0 * px / width - 1.0) * tan_half_h;
    const double sy = (1.0 - 2.0 * py / height) * tan_half_v;
    return (forward + sx * right + sy * up).normalized();
  }
};

// An axis-aligned box of metric coordinates.
struct Box {
  Vec3 min = Vec3::Constant(std::numeric_limits<double>::max());
  Vec3 max = Vec3::Constant(std::numeric_limits<double>::lowest());
  void add(const OccupancyMap::LeafBoxHost& leaf) {
    const Vec3 c(leaf.center[0], leaf.center[1], leaf.center[2]);
    min = min.cwiseMin(c - Vec3::Constant(0.5 * leaf.size));
    max = max.cwiseMax(c + Vec3::Constant(0.5 * leaf.size));
  }
  // The stretch [t_in, t_out] of the ray origin + t * dir inside the box; false
  // if none ahead.
  bool clip(const Vec3& origin, const Vec3& dir, double& t_in, double& t_out) const {
    t_in = 0.0;
    t_out = std::numeric_limits<double>::max();
    for (int a = 0; a < 3; ++a) {
      if (dir[a] == 0.0) {
        if (origin[a] < min[a] || origin[a] > max[a]) return false;
        continue;
      }
      double t0 = (min[a] - origin[a]) / dir[a];
      double t1 = (max[a] - origin[a]) / dir[a];
      if (t0 > t1) std::swap(t0, t1);
      t_in = std::max(t_in, t0);
      t_out = std::min(t_out, t1);
    }
    return t_in <= t_out;
  }
};

/// The default direction from the target to the eye: from the side of the box's
/// longer horizontal axis, kDefaultSkewDeg off it and kDefaultElevationDeg up.
Vec3 defaultView(const Box& occupied);

// Where the default camera looks and stands, looking along -`view` at `cells`:
// the eye is just far enough from the target for every cell to fit the picture,
// with a margin. With `centre`, the target moves sideways (a few rounds, as
// perspective shifts what is near) until the cells lie centred in the picture;
// without, it stays as given (--look-at).
void frame(const std::vector<OccupancyMap::LeafBoxHost>& cells, const Vec3& view, std::uint32_t w,
           std::uint32_t h, double fov_v_deg, bool centre, Vec3& target, Vec3& eye);

}  // namespace octovk::cli
