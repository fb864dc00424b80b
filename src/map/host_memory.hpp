// std::bad_alloc at the library's edge: every public call turns it into the one exception type.
#pragma once

#include <new>
#include <string>
#include <utility>

#include "octovk/octovk.hpp"

namespace octovk {

/// f(), with a std::bad_alloc from inside it thrown as Error(kOutOfHostMemory) naming `call`.
/// Only the edge of a call may use it: where the call's own rollback has already run.
template <class F>
decltype(auto) hostMemoryGuard(const char* call, F&& f) {
  try {
    return std::forward<F>(f)();
  } catch (const std::bad_alloc&) {
    throw Error(ErrorCode::kOutOfHostMemory,
                std::string(call) + ": the host ran out of memory; free some, or split the work");
  }
}

}  // namespace octovk
