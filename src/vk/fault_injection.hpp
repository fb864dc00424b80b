// For tests: makes the n-th device allocation fail as a driver out of memory would, to prove
// that every call which throws leaves the map as it was (tests/failure_test.cpp).
#pragma once

#include <cstdint>

namespace octovk::vk::fault {

/// Arms the hook: the n-th device allocation from now (1 = the next) fails with
/// VK_ERROR_OUT_OF_DEVICE_MEMORY; 0 disarms it. Resets the count.
void failDeviceAllocation(std::uint64_t n) noexcept;
/// Device allocations since the hook was last armed (or disarmed).
std::uint64_t deviceAllocations() noexcept;
/// Called before each device allocation: true when this one is to fail.
bool deviceAllocationFails() noexcept;

}  // namespace octovk::vk::fault
