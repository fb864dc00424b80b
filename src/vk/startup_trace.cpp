#include "vk/startup_trace.hpp"

#include <cstdio>
#include <cstdlib>
#include <cstring>

namespace octovk::vk {

namespace {
// The first call's time: the trace's origin, close to the process's first library call.
const std::chrono::steady_clock::time_point kOrigin = std::chrono::steady_clock::now();
}  // namespace

bool traceStartup() noexcept {
  static const bool on = [] {
    const char* env = std::getenv("OCTOVK_TRACE_STARTUP");
    return env && *env && std::strcmp(env, "0") != 0;
  }();
  return on;
}

void traceStep(std::string_view what, std::chrono::steady_clock::time_point since) noexcept {
  if (!traceStartup()) return;
  const auto now = std::chrono::steady_clock::now();
  const auto ms = [](auto d) { return std::chrono::duration<double, std::milli>(d).count(); };
  std::fprintf(stderr, "octovk start-up: %.*s: %.2f ms (at %.2f ms)\n",
               static_cast<int>(what.size()), what.data(), ms(now - since), ms(now - kOrigin));
}

}  // namespace octovk::vk
