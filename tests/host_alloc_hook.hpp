// A test executable's replacement of the global operator new that fails the N-th host allocation
// of the test's own thread while armed (host_armed, host_count, host_fail_at). It defines the
// global allocation functions: include it in exactly one file of an executable (failure_test.cpp,
// io_failure_test.cpp).
#pragma once

#include <atomic>
#include <cstdint>
#include <cstdlib>
#include <new>

namespace {
// The host hook: armed only on the test's thread (the driver's own threads and the validation
// layer are not octovk's code and must not see a failure they cannot report).
thread_local bool host_armed = false;
std::atomic<std::uint64_t> host_count{0};
std::atomic<std::uint64_t> host_fail_at{0};
}  // namespace

// The replacements pair malloc with free throughout; gcc cannot see that across the pairs.
#pragma GCC diagnostic ignored "-Wmismatched-new-delete"
void* operator new(std::size_t bytes) {
  if (host_armed && host_count.fetch_add(1) + 1 == host_fail_at.load()) throw std::bad_alloc();
  if (void* p = std::malloc(bytes ? bytes : 1)) return p;
  throw std::bad_alloc();
}
void* operator new[](std::size_t bytes) { return operator new(bytes); }
void operator delete(void* p) noexcept { std::free(p); }
void operator delete[](void* p) noexcept { std::free(p); }
void operator delete(void* p, std::size_t) noexcept { std::free(p); }
void operator delete[](void* p, std::size_t) noexcept { std::free(p); }
