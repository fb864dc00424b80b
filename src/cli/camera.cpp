#include "camera.hpp"

namespace octovk::cli {

Vec3 defaultView(const Box& occupied) {
  const Vec3 extent = occupied.max - occupied.min;
  const double elevation = kDefaultElevationDeg * M_PI / 180.0;
  const double skew = kDefaultSkewDeg * M_PI / 180.0;
  // From the side of the longer horizontal axis: -y of an x-long box, -x of a
  // y-long one.
  const Vec3 side = extent.x() >= extent.y() ? Vec3(-std::sin(skew), -std::cos(skew), 0.0)
                                             : Vec3(-std::cos(skew), std::sin(skew), 0.0);
  return std::cos(elevation) * side + std::sin(elevation) * Vec3::UnitZ();
}

// Where the default camera looks and stands, looking along -`view` at `cells`:
// the eye is just far enough from the target for every cell to fit the picture,
// with a margin. With `centre`, the target moves sideways (a few rounds, as
// perspective shifts what is near) until the cells lie centred in the picture;
// without, it stays as given (--look-at).
void frame(const std::vector<OccupancyMap::LeafBoxHost>& cells, const Vec3& view, std::uint32_t w,
           std::uint32_t h, double fov_v_deg, bool centre, Vec3& target, Vec3& eye) {
  const Camera probe(target + view, target, w, h, fov_v_deg);
  const double k_h = probe.tan_half_h * 0.94, k_v = probe.tan_half_v * 0.94;
  const auto fit = [&] {
    double distance = 0.0;
    for (const OccupancyMap::LeafBoxHost& c : cells) {
      const Vec3 q = Vec3(c.center[0], c.center[1], c.center[2]) - target;
      const double reach = 0.87 * c.size;                 // half the cell's diagonal
      const double depth = q.dot(probe.forward) - reach;  // its nearest to the camera
      distance = std::max(distance, (std::abs(q.dot(probe.right)) + reach) / k_h - depth);
      distance = std::max(distance, (std::abs(q.dot(probe.up)) + reach) / k_v - depth);
    }
    return distance;
  };
  double distance = fit();
  for (int round = 0; centre && round < 4; ++round) {
    const Vec3 from = target + view * distance;
    double lo[2] = {std::numeric_limits<double>::max(), std::numeric_limits<double>::max()};
    double hi[2] = {std::numeric_limits<double>::lowest(), std::numeric_limits<double>::lowest()};
    for (const OccupancyMap::LeafBoxHost& c : cells) {
      const Vec3 q = Vec3(c.center[0], c.center[1], c.center[2]) - from;
      const double depth = std::max(q.dot(probe.forward), 1e-9);
      const double sx = q.dot(probe.right) / depth, sy = q.dot(probe.up) / depth;
      lo[0] = std::min(lo[0], sx);
      hi[0] = std::max(hi[0], sx);
      lo[1] = std::min(lo[1], sy);
      hi[1] = std::max(hi[1], sy);
    }
    target += distance * (0.5 * (lo[0] + hi[0]) * probe.right + 0.5 * (lo[1] + hi[1]) * probe.up);
    distance = fit();
  }
  eye = target + view * distance;
}

}  // namespace octovk::cli
