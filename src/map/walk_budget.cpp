#include "map/walk_budget.hpp"

#include <algorithm>
#include <limits>

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

std::size_t colorFoldChunk(const vk::Device& device) noexcept {
  if (device.loopLimit() == 0) return std::numeric_limits<std::uint32_t>::max();
  const std::uint64_t budget = walkBudget(device);
  std::size_t chunk = 64;
  for (std::uint32_t log2 = 7; log2 < 31; ++log2) {
    const std::uint64_t c = std::uint64_t{1} << log2;
    if (c * (2 * log2 + 3) > budget) break;
    chunk = static_cast<std::size_t>(c);
  }
  return chunk;
}

}  // namespace octovk
