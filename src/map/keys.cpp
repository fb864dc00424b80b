// The public key helpers (queries.hpp): OctoMap's coordToKeyChecked and keyToCoord at the finest
// depth, on the host, from the same reference arithmetic the passes are tested against.
#include "map/reference.hpp"
#include "octovk/queries.hpp"

namespace octovk {

std::optional<Key> coordToKey(double resolution, const Eigen::Vector3f& point) {
  const double factor = 1.0 / resolution;
  Key key{};
  for (int a = 0; a < 3; ++a) {
    std::uint32_t k = 0;
    if (!ref::coordToKeyChecked(factor, point[a], k)) return std::nullopt;
    key[static_cast<std::size_t>(a)] = static_cast<std::uint16_t>(k);
  }
  return key;
}

Eigen::Vector3f keyToCoord(double resolution, const Key& key) {
  Eigen::Vector3f centre;
  for (int a = 0; a < 3; ++a)
    centre[a] = static_cast<float>(
        (static_cast<double>(key[static_cast<std::size_t>(a)]) - 32768.0 + 0.5) * resolution);
  return centre;
}

}  // namespace octovk
