#include "vk/disk_cache.hpp"

#include <fcntl.h>
#include <sys/stat.h>
#include <unistd.h>

#include <algorithm>
#include <atomic>
#include <cerrno>
#include <cstdlib>
#include <cstring>
#include <fstream>
#include <system_error>

namespace octovk::vk::disk {

namespace {

constexpr char kMagic[8] = {'o', 'c', 't', 'o', 'v', 'k', '1', '\n'};
// Far above any real record (a pipeline cache of every shader is a few MiB): a larger file is
// not read at all.
constexpr std::uint64_t kMaxRecordBytes = 256ull << 20;
constexpr std::uint64_t kMaxKeyBytes = 64u << 10;

// The file starts with this, then the key's bytes, then the payload's.
struct Header {
  char magic[8];
  char kind[8];  // zero-padded
  std::uint64_t key_bytes;
  std::uint64_t payload_bytes;
  std::uint64_t checksum;  // hash64 of this header (checksum 0), the key and the payload
};
static_assert(sizeof(Header) == 40);

Header makeHeader(std::string_view kind, std::uint64_t key_bytes, std::uint64_t payload_bytes) {
  Header h{};
  std::memcpy(h.magic, kMagic, sizeof kMagic);
  std::memcpy(h.kind, kind.data(), std::min(kind.size(), sizeof h.kind));
  h.key_bytes = key_bytes;
  h.payload_bytes = payload_bytes;
  return h;
}

std::uint64_t checksum(Header h, std::string_view key, std::span<const std::byte> payload) {
  h.checksum = 0;
  std::uint64_t sum = hash64(std::as_bytes(std::span(&h, 1)));
  sum = hash64(key, sum);
  return hash64(payload, sum);
}

std::filesystem::path absoluteEnv(const char* name) {
  const char* value = std::getenv(name);
  if (!value || !*value) return {};
  std::filesystem::path p(value);
  return p.is_absolute() ? p : std::filesystem::path();
}

}  // namespace

std::filesystem::path folder() {
  if (const char* dir = std::getenv("OCTOVK_CACHE_DIR"); dir && *dir)
    return std::filesystem::path(dir);
  if (std::filesystem::path xdg = absoluteEnv("XDG_CACHE_HOME"); !xdg.empty())
    return xdg / "octovk";
  if (std::filesystem::path home = absoluteEnv("HOME"); !home.empty())
    return home / ".cache" / "octovk";
  return {};
}

std::uint64_t hash64(std::span<const std::byte> bytes, std::uint64_t seed) noexcept {
  std::uint64_t h = seed;
  for (std::byte b : bytes) {
    h ^= static_cast<std::uint64_t>(b);
    h *= 0x100000001b3ull;
  }
  return h;
}

std::uint64_t hash64(std::string_view text, std::uint64_t seed) noexcept {
  return hash64(std::as_bytes(std::span(text.data(), text.size())), seed);
}

std::optional<std::vector<std::byte>> readRecord(const std::filesystem::path& path,
                                                 std::string_view kind, std::string_view key) {
  if (path.empty()) return std::nullopt;
  std::error_code ec;
  const std::uintmax_t size = std::filesystem::file_size(path, ec);
  if (ec || size < sizeof(Header) || size > kMaxRecordBytes) return std::nullopt;
  std::ifstream in(path, std::ios::binary);
  Header h;
  if (!in.read(reinterpret_cast<char*>(&h), sizeof h)) return std::nullopt;
  const Header want = makeHeader(kind, key.size(), 0);
  if (std::memcmp(h.magic, want.magic, sizeof h.magic) != 0 ||
      std::memcmp(h.kind, want.kind, sizeof h.kind) != 0 || h.key_bytes != key.size() ||
      h.key_bytes > kMaxKeyBytes || sizeof(Header) + h.key_bytes + h.payload_bytes != size)
    return std::nullopt;
  std::string stored_key(h.key_bytes, '\0');
  std::vector<std::byte> payload(h.payload_bytes);
  if (!in.read(stored_key.data(), static_cast<std::streamsize>(stored_key.size())) ||
      !in.read(reinterpret_cast<char*>(payload.data()),
               static_cast<std::streamsize>(payload.size())))
    return std::nullopt;
  if (stored_key != key || checksum(h, stored_key, payload) != h.checksum) return std::nullopt;
  return payload;
}

bool writeRecord(const std::filesystem::path& path, std::string_view kind, std::string_view key,
                 std::span<const std::byte> payload) {
  if (path.empty() || key.size() > kMaxKeyBytes ||
      sizeof(Header) + key.size() + payload.size() > kMaxRecordBytes)
    return false;
  const std::filesystem::path dir = path.parent_path();
  std::error_code ec;
  if (!std::filesystem::is_directory(dir, ec)) {
    std::filesystem::create_directories(dir.parent_path(), ec);
    if (::mkdir(dir.c_str(), 0700) != 0 && errno != EEXIST) return false;
  }
  Header h = makeHeader(kind, key.size(), payload.size());
  h.checksum = checksum(h, key, payload);

  // A name no other writer (thread or process) uses: the pid and a counter.
  static std::atomic<std::uint64_t> counter{0};
  std::filesystem::path tmp = path;
  tmp += ".tmp." + std::to_string(::getpid()) + "." + std::to_string(counter.fetch_add(1));
  const int fd = ::open(tmp.c_str(), O_WRONLY | O_CREAT | O_EXCL | O_CLOEXEC, 0600);
  if (fd < 0) return false;
  auto writeAll = [fd](const void* data, std::size_t bytes) {
    const auto* p = static_cast<const char*>(data);
    while (bytes > 0) {
      const ssize_t n = ::write(fd, p, bytes);
      if (n < 0 && errno == EINTR) continue;
      if (n <= 0) return false;
      p += n;
      bytes -= static_cast<std::size_t>(n);
    }
    return true;
  };
  bool ok = writeAll(&h, sizeof h) && writeAll(key.data(), key.size()) &&
            writeAll(payload.data(), payload.size());
  ok = (::close(fd) == 0) && ok;
  if (ok) ok = ::rename(tmp.c_str(), path.c_str()) == 0;
  if (!ok) ::unlink(tmp.c_str());
  return ok;
}

void removeRecord(const std::filesystem::path& path) noexcept {
  if (!path.empty()) ::unlink(path.c_str());
}

}  // namespace octovk::vk::disk
