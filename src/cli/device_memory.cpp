// --max-device-memory: the program's name for MapParams::max_device_bytes, for every command that
// builds a map (integrate, info, render, export). On lavapipe device memory is host memory, so
// without a cap a hostile input (a sensor origin kilometres from its points) could grow the
// process to many gigabytes before the device refused it.
#include <cerrno>
#include <cstdio>
#include <cstdlib>
#include <limits>
#include <ostream>

#include "cli.hpp"

namespace octovk::cli {

namespace {

// `message` with every `from` replaced by `to`.
std::string replacedAll(std::string message, const std::string& from, const std::string& to) {
  for (std::size_t at = message.find(from); at != std::string::npos;
       at = message.find(from, at + to.size()))
    message.replace(at, from.size(), to);
  return message;
}

}  // namespace

std::string bytesText(std::size_t bytes) {
  char text[64];
  std::snprintf(text, sizeof(text), "%zu bytes (%.1f MiB)", bytes,
                static_cast<double>(bytes) / (1024.0 * 1024.0));
  return text;
}

std::size_t parseByteCount(const ParsedOption& option) {
  const std::string& text = option.value;
  const auto bad = [&] {
    return UsageError(option.name +
                      " expects a number of bytes, with K, M, G or T for KiB, MiB, "
                      "GiB or TiB, got '" +
                      text + "'; e.g. " + option.name + " 512M (0: no cap)");
  };
  if (text.empty() || text[0] < '0' || text[0] > '9') throw bad();
  errno = 0;
  char* end = nullptr;
  const unsigned long long number = std::strtoull(text.c_str(), &end, 10);
  if (errno == ERANGE) throw bad();
  std::string suffix(end);
  if (suffix.size() > 1 && (suffix.back() == 'B' || suffix.back() == 'b')) suffix.pop_back();
  if (suffix.size() == 2 && suffix.back() == 'i') suffix.pop_back();  // "MiB" as "M"
  unsigned shift = 0;
  if (suffix.size() == 1) {
    switch (suffix[0]) {
      case 'k':
      case 'K':
        shift = 10;
        break;
      case 'm':
      case 'M':
        shift = 20;
        break;
      case 'g':
      case 'G':
        shift = 30;
        break;
      case 't':
      case 'T':
        shift = 40;
        break;
      default:
        throw bad();
    }
  } else if (!suffix.empty()) {
    throw bad();
  }
  if (number > (std::numeric_limits<std::size_t>::max() >> shift)) throw bad();
  return static_cast<std::size_t>(number) << shift;
}

void checkDeviceMemoryCap(const MapParams& params) {
  if (params.max_device_bytes == 0 || params.max_device_bytes >= params.minDeviceBytes()) return;
  throw UsageError(std::string(kMaxDeviceMemoryOption) + " " + bytesText(params.max_device_bytes) +
                   " is less than an empty map holds on the device, " +
                   bytesText(params.minDeviceBytes()) + "; raise it, or give 0 for no cap");
}

Error withOptionNames(const Error& e) {
  std::string message = e.what();
  if (message.find("max_device_bytes") == std::string::npos) return e;
  message = replacedAll(message, "MapParams::max_device_bytes", kMaxDeviceMemoryOption);
  message = replacedAll(message, "max_device_bytes", kMaxDeviceMemoryOption);
  // A library caller's remedy; the program releases scratch on its own.
  message = replacedAll(message, ", or call OccupancyMap::trim() to release scratch", "");
  return Error(e.code(), message, e.scan());
}

void printMaxDeviceMemoryHelp(std::ostream& out, const char* what_fails) {
  out << "      --max-device-memory BYTES\n"
         "                         the map's device memory cap, with K, M, G, T suffixes (512M,\n"
         "                         2G); 0 = no cap (default: 0). On lavapipe that is host memory.\n"
         "                         "
      << what_fails << " needing more fails (exit 1), naming the cap.\n";
}

}  // namespace octovk::cli
