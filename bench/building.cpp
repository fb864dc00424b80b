#include "building.hpp"

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <limits>
#include <numbers>
#include <stdexcept>

namespace octovk::bench {

namespace {

constexpr double kLength = 40.0;     // x
constexpr double kWidth = 16.0;      // y
constexpr double kHeight = 3.0;      // z
constexpr double kCorridorLo = 7.0;  // corridor between y = 7 and y = 9
constexpr double kCorridorHi = 9.0;
constexpr double kRoomLength = 8.0;  // five rooms a side
constexpr double kWall = 0.15;       // inner wall thickness
constexpr double kOuter = 0.3;       // outer walls, floor and ceiling slabs
constexpr double kDoorWidth = 1.0;
constexpr double kDoorHeight = 2.1;

double radians(double deg) { return deg * std::numbers::pi / 180.0; }

}  // namespace

double Rng::uniform(double lo, double hi) {
  state_ += 0x9E3779B97F4A7C15ull;
  std::uint64_t z = state_;
  z = (z ^ (z >> 30)) * 0xBF58476D1CE4E5B9ull;
  z = (z ^ (z >> 27)) * 0x94D049BB133111EBull;
  z ^= z >> 31;
  return lo + (hi - lo) * static_cast<double>(z >> 11) * 0x1.0p-53;
}

Building::Building() {
  // Shell: floor, ceiling, four outer walls.
  add(-kOuter, -kOuter, -kOuter, kLength + kOuter, kWidth + kOuter, 0.0);
  add(-kOuter, -kOuter, kHeight, kLength + kOuter, kWidth + kOuter, kHeight + kOuter);
  add(-kOuter, -kOuter, 0.0, 0.0, kWidth + kOuter, kHeight);
  add(kLength, -kOuter, 0.0, kLength + kOuter, kWidth + kOuter, kHeight);
  add(0.0, -kOuter, 0.0, kLength, 0.0, kHeight);
  add(0.0, kWidth, 0.0, kLength, kWidth + kOuter, kHeight);

  // Corridor walls with one door per room, at varying places.
  const int rooms = static_cast<int>(kLength / kRoomLength);
  std::vector<double> south_doors, north_doors;
  for (int i = 0; i < rooms; ++i) {
    south_doors.push_back(i * kRoomLength + 1.5 + (i % 3) * 2.0);
    north_doors.push_back(i * kRoomLength + 6.5 - (i % 2) * 3.0);
  }
  addWallAlongX(kCorridorLo, 0.0, kLength, south_doors);
  addWallAlongX(kCorridorHi, 0.0, kLength, north_doors);

  // Walls between rooms; some have a connecting door.
  for (int i = 1; i < rooms; ++i) {
    const double x = i * kRoomLength;
    addWallAlongY(x, 0.0, kCorridorLo,
                  i % 2 == 1 ? std::vector<double>{3.5} : std::vector<double>{});
    addWallAlongY(x, kCorridorHi, kWidth,
                  i % 2 == 0 ? std::vector<double>{12.5} : std::vector<double>{});
  }

  for (int i = 0; i < rooms; ++i) {
    furnishRoom(i * kRoomLength, 0.0, (i + 1) * kRoomLength, kCorridorLo, 2u * i + 1u);
    furnishRoom(i * kRoomLength, kCorridorHi, (i + 1) * kRoomLength, kWidth, 2u * i + 2u);
  }
  // Two pillars and a bench in the corridor.
  add(13.8, 7.3, 0.0, 14.2, 7.7, kHeight);
  add(27.8, 8.3, 0.0, 28.2, 8.7, kHeight);
  add(20.0, 8.5, 0.0, 22.0, 8.9, 0.45);
}

void Building::add(double x0, double y0, double z0, double x1, double y1, double z1) {
  boxes_.push_back({{x0, y0, z0}, {x1, y1, z1}});
}

// A wall of thickness kWall centred on y, from x0 to x1, with doors (width kDoorWidth,
// height kDoorHeight) centred at the given x; above each door a lintel.
void Building::addWallAlongX(double y, double x0, double x1, std::vector<double> door_centres) {
  std::sort(door_centres.begin(), door_centres.end());
  double start = x0;
  for (double c : door_centres) {
    add(start, y - kWall / 2, 0.0, c - kDoorWidth / 2, y + kWall / 2, kHeight);
    add(c - kDoorWidth / 2, y - kWall / 2, kDoorHeight, c + kDoorWidth / 2, y + kWall / 2, kHeight);
    start = c + kDoorWidth / 2;
  }
  add(start, y - kWall / 2, 0.0, x1, y + kWall / 2, kHeight);
}

void Building::addWallAlongY(double x, double y0, double y1, std::vector<double> door_centres) {
  std::sort(door_centres.begin(), door_centres.end());
  double start = y0;
  for (double c : door_centres) {
    add(x - kWall / 2, start, 0.0, x + kWall / 2, c - kDoorWidth / 2, kHeight);
    add(x - kWall / 2, c - kDoorWidth / 2, kDoorHeight, x + kWall / 2, c + kDoorWidth / 2, kHeight);
    start = c + kDoorWidth / 2;
  }
  add(x - kWall / 2, start, 0.0, x + kWall / 2, y1, kHeight);
}

// A table with four legs and four chairs near the middle, a cabinet against the far wall and
// a sofa against the west wall. Positions vary with `seed`.
void Building::furnishRoom(double x0, double y0, double x1, double y1, unsigned seed) {
  Rng rng(seed);
  const double cx = (x0 + x1) / 2 + rng.uniform(-1.0, 1.0);
  const double cy = (y0 + y1) / 2 + rng.uniform(-0.8, 0.8);
  const bool turned = rng.uniform(0.0, 1.0) < 0.5;
  const double hx = turned ? 0.4 : 0.8, hy = turned ? 0.8 : 0.4;
  add(cx - hx, cy - hy, 0.72, cx + hx, cy + hy, 0.76);
  for (int sx = -1; sx <= 1; sx += 2)
    for (int sy = -1; sy <= 1; sy += 2) {
      const double lx = cx + sx * (hx - 0.06), ly = cy + sy * (hy - 0.06);
      add(lx - 0.025, ly - 0.025, 0.0, lx + 0.025, ly + 0.025, 0.72);
    }
  // Chairs on the long sides: seat, post, backrest away from the table.
  for (int side = -1; side <= 1; side += 2)
    for (int k = -1; k <= 1; k += 2) {
      const double along = k * 0.4 + rng.uniform(-0.1, 0.1);
      const double px = turned ? cx + side * (hx + 0.35) : cx + along;
      const double py = turned ? cy + along : cy + side * (hy + 0.35);
      add(px - 0.22, py - 0.22, 0.43, px + 0.22, py + 0.22, 0.47);
      add(px - 0.03, py - 0.03, 0.0, px + 0.03, py + 0.03, 0.43);
      if (turned)
        add(px + side * 0.2 - 0.02, py - 0.22, 0.47, px + side * 0.2 + 0.02, py + 0.22, 0.9);
      else
        add(px - 0.22, py + side * 0.2 - 0.02, 0.47, px + 0.22, py + side * 0.2 + 0.02, 0.9);
    }
  // Cabinet against the wall away from the corridor.
  const bool south_room = y1 <= kCorridorLo;
  const double kx = rng.uniform(x0 + 1.5, x1 - 2.5);
  if (south_room)
    add(kx, y0 + kWall / 2, 0.0, kx + 1.2, y0 + 0.55, 2.0);
  else
    add(kx, y1 - 0.55, 0.0, kx + 1.2, y1 - kWall / 2, 2.0);
  // Sofa (seat and back) against the west wall.
  const double sy = rng.uniform(y0 + 1.5, y1 - 3.0);
  add(x0 + kWall / 2, sy, 0.0, x0 + 0.95, sy + 2.0, 0.45);
  add(x0 + kWall / 2, sy, 0.45, x0 + 0.3, sy + 2.0, 0.85);
}

double Building::castRay(const Eigen::Vector3d& origin, const Eigen::Vector3d& direction) const {
  double best = std::numeric_limits<double>::infinity();
  for (const Box& box : boxes_) {
    double t_near = -std::numeric_limits<double>::infinity();
    double t_far = std::numeric_limits<double>::infinity();
    bool miss = false;
    for (int a = 0; a < 3 && !miss; ++a) {
      if (direction[a] == 0.0) {
        miss = origin[a] < box.lo[a] || origin[a] > box.hi[a];
        continue;
      }
      double t0 = (box.lo[a] - origin[a]) / direction[a];
      double t1 = (box.hi[a] - origin[a]) / direction[a];
      if (t0 > t1) std::swap(t0, t1);
      t_near = std::max(t_near, t0);
      t_far = std::min(t_far, t1);
      miss = t_near > t_far;
    }
    if (!miss && t_near > 0.0 && t_near < best) best = t_near;
  }
  return std::isfinite(best) ? best : -1.0;
}

Box Building::bounds() const {
  Box b{boxes_.front().lo, boxes_.front().hi};
  for (const Box& box : boxes_) {
    b.lo = b.lo.cwiseMin(box.lo);
    b.hi = b.hi.cwiseMax(box.hi);
  }
  return b;
}

std::vector<SensorPose> paperViews() {
  return {
      {"corridor, looking east", {1.0, 8.0, 1.5}, 0.0, 5.0},
      {"room S1", {9.0, 1.0, 1.4}, 35.0, 10.0},
      {"room N2", {23.0, 15.0, 1.6}, -145.0, 15.0},
      {"corridor, looking west", {38.5, 8.3, 1.2}, 180.0, -5.0},
      {"room S4", {39.0, 6.0, 1.3}, -120.0, 8.0},
      {"room N0", {1.0, 10.0, 1.7}, 50.0, 20.0},
  };
}

std::vector<Eigen::Vector3f> rangeImage(const Building& building, const SensorPose& pose,
                                        std::size_t width, std::size_t height) {
  const double f = static_cast<double>(width) / 2.0;  // 90 degrees horizontal field of view
  const double cx = static_cast<double>(width) / 2.0, cy = static_cast<double>(height) / 2.0;
  const double cyaw = std::cos(radians(pose.yaw_deg)), syaw = std::sin(radians(pose.yaw_deg));
  const double cp = std::cos(radians(pose.pitch_deg)), sp = std::sin(radians(pose.pitch_deg));
  std::vector<Eigen::Vector3f> points;
  points.reserve(width * height);
  for (std::size_t v = 0; v < height; ++v)
    for (std::size_t u = 0; u < width; ++u) {
      // Camera frame: x forward, y left, z up; pitch about y (down positive), then yaw about z.
      const Eigen::Vector3d cam(f, cx - (static_cast<double>(u) + 0.5),
                                cy - (static_cast<double>(v) + 0.5));
      const Eigen::Vector3d pitched(cp * cam.x() + sp * cam.z(), cam.y(),
                                    -sp * cam.x() + cp * cam.z());
      const Eigen::Vector3d dir =
          Eigen::Vector3d(cyaw * pitched.x() - syaw * pitched.y(),
                          syaw * pitched.x() + cyaw * pitched.y(), pitched.z())
              .normalized();
      const double t = building.castRay(pose.position, dir);
      if (t > 0.0) points.push_back((pose.position + t * dir).cast<float>());
    }
  return points;
}

void imageSizeFor(std::size_t rays, std::size_t* width, std::size_t* height) {
  *width = static_cast<std::size_t>(std::lround(std::sqrt(static_cast<double>(rays) * 4.0 / 3.0)));
  *height = static_cast<std::size_t>(
      std::lround(static_cast<double>(rays) / static_cast<double>(*width)));
}

}  // namespace octovk::bench
