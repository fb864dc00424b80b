// octovk: Errors: the one exception type, its codes, and Result for setup steps.
#pragma once

#include <cstdint>
#include <cstdlib>
#include <memory>
#include <optional>
#include <stdexcept>
#include <string>
#include <utility>

namespace octovk {

/// What went wrong, coarsely, so callers can react without parsing messages.
enum class ErrorCode {
  kNoDevice,           ///< no Vulkan device (install mesa-vulkan-drivers for the CPU device)
  kMissingFeature,     ///< the device lacks a feature octovk needs; the message names it
  kInvalidArgument,    ///< a parameter or input is out of its domain
  kOutOfDeviceMemory,  ///< the device could not hold the map; the map is as before the call
  /// An unexpected Vulkan failure; the message says it in words, Error::detail() names the
  /// call, its VkResult and the source place.
  kVulkan,
  kIo,      ///< a file could not be read or written
  kFormat,  ///< a file is not in the expected format
  /// The host could not allocate memory (std::bad_alloc inside octovk); the map is as before
  /// the call and keeps working.
  kOutOfHostMemory,
  /// octovk broke one of its own invariants: a bug, to be reported with the input.
  kInternal,
};

/// Whether the environment variable OCTOVK_DEBUG is set (not empty, not "0"): Error::what()
/// then ends with the developer detail (Error::detail()).
inline bool debugErrors() noexcept {
  const char* v = std::getenv("OCTOVK_DEBUG");
  return v != nullptr && v[0] != '\0' && !(v[0] == '0' && v[1] == '\0');
}

/// The one exception type of octovk. The library never exits the process.
///
/// what() is written for the person using octovk: the cause and the fix, in the words of the
/// API (or, in the program, of its options); it never names a Vulkan call or a source file.
/// What a developer needs beyond that (the driver call, its VkResult, the source place) is in
/// detail(), and appended to what() when OCTOVK_DEBUG is set.
class Error : public std::runtime_error {
 public:
  Error(ErrorCode code, const std::string& message, std::uint64_t scan = 0)
      : std::runtime_error(message), code_(code), scan_(scan) {}
  Error(ErrorCode code, const std::string& message, std::uint64_t scan, const std::string& detail)
      : std::runtime_error(detail.empty() || !debugErrors() ? message
                                                            : message + " [" + detail + "]"),
        code_(code),
        scan_(scan),
        detail_(detail.empty() ? nullptr
                               : std::make_shared<const Detail>(Detail{message, detail})) {}
  ErrorCode code() const noexcept { return code_; }
  /// For an error a synchronisation found in a scan submitted earlier (OccupancyMap::submit*,
  /// see there): that scan's ticket, so that a caller can say which of its inputs failed; 0 when
  /// the error is about the call that threw it.
  std::uint64_t scan() const noexcept { return scan_; }
  /// For developers: the Vulkan call that failed, its VkResult and where in octovk's source
  /// (empty for errors that are not the driver's). Not part of what() unless OCTOVK_DEBUG is set.
  const std::string& detail() const noexcept {
    static const std::string kNone;
    return detail_ ? detail_->detail : kNone;
  }
  /// what() without the detail OCTOVK_DEBUG appends: for callers that reword the message.
  std::string message() const { return detail_ ? detail_->message : std::string(what()); }

 private:
  struct Detail {
    std::string message, detail;
  };
  ErrorCode code_;
  std::uint64_t scan_;
  std::shared_ptr<const Detail> detail_;  // shared: copying an exception does not throw
};

/// A value or the reason there is none, for setup steps that fail for ordinary reasons.
template <class T>
class [[nodiscard]] Result {
 public:
  Result(T value) : value_(std::move(value)) {}      // NOLINT(google-explicit-constructor)
  Result(Error error) : error_(std::move(error)) {}  // NOLINT(google-explicit-constructor)
  explicit operator bool() const noexcept { return value_.has_value(); }
  T& value() {
    if (!value_) throw *error_;
    return *value_;
  }
  /// The reason there is no value; when there is one, an Error saying so (kInternal).
  const Error& error() const {
    static const Error kNoError(ErrorCode::kInternal, "Result::error() called on a value");
    return error_ ? *error_ : kNoError;
  }

 private:
  std::optional<T> value_;
  std::optional<Error> error_;
};

}  // namespace octovk
