// OCTOVK_TRACE_STARTUP=1: what a process pays before its first result, step by step, on stderr
// (creating the instance and the device, the device probe or its kept verdict, loading the
// pipeline cache, building each pipeline, saving the cache). For measuring start-up.
#pragma once

#include <chrono>
#include <string_view>

namespace octovk::vk {

/// Whether OCTOVK_TRACE_STARTUP is set and not "0" (read once).
bool traceStartup() noexcept;

/// Writes "octovk start-up: <what>: <ms since `since`> ms (at <ms since the first step> ms)" to
/// stderr when traceStartup().
void traceStep(std::string_view what, std::chrono::steady_clock::time_point since) noexcept;

}  // namespace octovk::vk
