#include "vk/fault_injection.hpp"

#include <atomic>

namespace octovk::vk::fault {

namespace {
std::atomic<std::uint64_t> fail_at{0};
std::atomic<std::uint64_t> allocations{0};
}  // namespace

void failDeviceAllocation(std::uint64_t n) noexcept {
  allocations.store(0);
  fail_at.store(n);
}
std::uint64_t deviceAllocations() noexcept { return allocations.load(); }
bool deviceAllocationFails() noexcept {
  const std::uint64_t n = allocations.fetch_add(1) + 1;
  return n == fail_at.load();
}

}  // namespace octovk::vk::fault
