// octomath::Pose6D arithmetic, operation for operation, so that origins and transformed points
// are bit-exact with OctoMap's (and with shaders/transform_points.comp).
#include <cmath>

#include "octovk/octovk.hpp"

namespace octovk {

namespace {

struct Quat {
  float u, x, y, z;
};

// octomath::Quaternion::operator*
Quat mul(const Quat& a, const Quat& b) {
  return {
      a.u * b.u - a.x * b.x - a.y * b.y - a.z * b.z, a.y * b.z - b.y * a.z + a.u * b.x + b.u * a.x,
      a.z * b.x - b.z * a.x + a.u * b.y + b.u * a.y, a.x * b.y - b.x * a.y + a.u * b.z + b.u * a.z};
}

Quat toQuat(const Eigen::Quaternionf& q) { return {q.w(), q.x(), q.y(), q.z()}; }

Eigen::Vector3f rotate(const Quat& q, const Eigen::Vector3f& v) {
  const Quat inv{q.u, -q.x, -q.y, -q.z};
  const Quat r = mul(mul(q, Quat{0.0f, v.x(), v.y(), v.z()}), inv);
  return {r.x, r.y, r.z};
}

}  // namespace

Eigen::Vector3f Pose::transform(const Eigen::Vector3f& v) const {
  const Eigen::Vector3f r = rotate(toQuat(rotation), v);
  return {r.x() + translation.x(), r.y() + translation.y(), r.z() + translation.z()};
}

Pose Pose::inverse() const {
  // rot().inv().normalized(): the norm sums float squares in double, divides in float.
  Quat q{rotation.w(), -rotation.x(), -rotation.y(), -rotation.z()};
  double n = 0;
  for (float c : {q.u, q.x, q.y, q.z}) n += c * c;
  const double len = static_cast<float>(std::sqrt(n));
  if (len > 0) {
    const float l = static_cast<float>(len);
    q = {q.u / l, q.x / l, q.y / l, q.z / l};
  }
  Pose out;
  out.rotation = Eigen::Quaternionf(q.u, q.x, q.y, q.z);
  out.translation = rotate(q, -translation);
  return out;
}

}  // namespace octovk
