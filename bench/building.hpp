// The benchmark's synthetic scene: a deterministic indoor building (rooms, corridor, doors,
// furniture) made of axis-aligned boxes, and a 2D range sensor that ray-casts into it.
#pragma once

#include <Eigen/Core>
#include <cstddef>
#include <cstdint>
#include <string>
#include <vector>

namespace octovk::bench {

struct Box {
  Eigen::Vector3d lo;
  Eigen::Vector3d hi;
};

/// splitmix64: the same numbers on every platform (std:: distributions are not portable).
class Rng {
 public:
  explicit Rng(std::uint64_t seed) : state_(seed) {}
  /// Uniform in [lo, hi).
  double uniform(double lo, double hi);

 private:
  std::uint64_t state_;
};

/// A closed two-row office floor: a 40 m corridor between ten 8 m x 7 m rooms, walls with doors,
/// a table, chairs, a cabinet and a sofa in every room. Every ray from inside hits something.
class Building {
 public:
  Building();

  /// Distance along `direction` (unit) from `origin` to the first surface; negative if none.
  double castRay(const Eigen::Vector3d& origin, const Eigen::Vector3d& direction) const;

  std::size_t boxCount() const noexcept { return boxes_.size(); }
  /// The smallest axis-aligned box around the whole building (slabs and outer walls included).
  Box bounds() const;

 private:
  void add(double x0, double y0, double z0, double x1, double y1, double z1);
  void addWallAlongX(double y, double x0, double x1, std::vector<double> door_centres);
  void addWallAlongY(double x, double y0, double y1, std::vector<double> door_centres);
  void furnishRoom(double x0, double y0, double x1, double y1, unsigned seed);

  std::vector<Box> boxes_;
};

/// Where a range sensor stands and looks: yaw about z, then pitch (positive looks down).
struct SensorPose {
  std::string name;
  Eigen::Vector3d position;
  double yaw_deg = 0.0;
  double pitch_deg = 0.0;
};

/// The six views of the paper's setup: two in the corridor, four in rooms.
std::vector<SensorPose> paperViews();

/// A pinhole range image of width x height rays with a 90 degree horizontal field of view; the
/// points are in the world frame, one per ray that hits (all of them inside the building),
/// converted to float once so that both mappers get the same bits.
std::vector<Eigen::Vector3f> rangeImage(const Building& building, const SensorPose& pose,
                                        std::size_t width, std::size_t height);

/// Width and height of a 4:3 image with about `rays` rays.
void imageSizeFor(std::size_t rays, std::size_t* width, std::size_t* height);

}  // namespace octovk::bench
