// How far a resumable walk (the scan's ray walk, castRay's) goes per dispatch, and how many
// continuation dispatches it needs, on a device whose driver ends shader loops early (the device
// probe measures the limit: vk::Device::loopLimit()). A map concern: the device only reports the
// limit it saw.
#pragma once

#include <cstdint>

#include "vk/device.hpp"

namespace octovk {

/// Loop iterations a resumable walk takes per dispatch: 30000 per 65535 of the measured limit
/// (room for the loops around the walk and the batch's other lanes), or all it needs (2^31 - 1)
/// where there is no limit.
std::uint32_t walkBudget(const vk::Device& device) noexcept;
/// Continuation dispatches a resumable walk of at most `worst_iterations` needs after its
/// first one: enough budgets to cover it where loops are limited, none elsewhere.
std::uint32_t walkContinuations(const vk::Device& device, std::uint64_t worst_iterations) noexcept;
/// The continuation rounds a scan's walk of at most `steps` DDA steps needs where the device
/// limits loops: at least 1 (the last one reports a walk still unfinished), at most
/// fullWalkRounds(); 0 where loops are not limited. Counts 4 loop iterations per step (the step
/// and the cell set's probes; a scan whose probes outrun that is run again with fullWalkRounds()).
std::uint32_t walkRounds(const vk::Device& device, double steps) noexcept;
/// The most points color_fold folds in one chunk: where loops are limited, the largest power of
/// two C whose worst fold (a node holding all C points: the list's merge sort, about
/// C * (2 log2 C + 3) iterations, then the fold) fits walkBudget(); elsewhere every point at once.
std::size_t colorFoldChunk(const vk::Device& device) noexcept;
/// Rounds that cover any ray (3 * 65536 steps with room for the probes).
std::uint32_t fullWalkRounds(const vk::Device& device) noexcept;

}  // namespace octovk
