#include "map/walk_budget.hpp"

#include <algorithm>

namespace octovk {

std::uint32_t walkBudget(const vk::Device& device) noexcept {
  const std::uint32_t limit = device.loopLimit();
  return limit == 0 ? 0x7FFFFFFFu
                    : static_cast<std::uint32_t>(std::uint64_t{limit} * 30000u / 65535u);
}

std::uint32_t walkContinuations(const vk::Device& device, std::uint64_t worst_iterations) noexcept {
  if (device.loopLimit() == 0) return 0u;
  const std::uint64_t budget = walkBudget(device);
  return static_cast<std::uint32_t>((worst_iterations + budget - 1) / budget);
}

std::uint32_t fullWalkRounds(const vk::Device& device) noexcept {
  return walkContinuations(device, 24u * 30000u);
}

std::uint32_t walkRounds(const vk::Device& device, double steps) noexcept {
  const std::uint32_t full = fullWalkRounds(device);
  if (full == 0) return 0;
  const double iterations = 4.0 * steps;
  if (!(iterations < 24.0 * 30000.0)) return full;  // also NaN
  return std::clamp<std::uint32_t>(
      walkContinuations(device, static_cast<std::uint64_t>(iterations)), 1u, full);
}

}  // namespace octovk
