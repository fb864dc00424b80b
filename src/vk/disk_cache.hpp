// Records octovk keeps between runs in a per-user folder (the Vulkan pipeline cache, the device
// probe's verdict): each file names what it was written for, and one that is missing, truncated,
// corrupt or written for another device, driver or build reads as nothing. Nothing here fails
// a caller: a record is only ever a shortcut to what octovk would compute anyway.
#pragma once

#include <cstddef>
#include <cstdint>
#include <filesystem>
#include <optional>
#include <span>
#include <string>
#include <string_view>
#include <vector>

namespace octovk::vk::disk {

/// The folder the records live in: $OCTOVK_CACHE_DIR, else $XDG_CACHE_HOME/octovk, else
/// $HOME/.cache/octovk (relative XDG_CACHE_HOME ignored, as the XDG spec says); empty when none
/// is set, and then nothing is kept.
std::filesystem::path folder();

/// FNV-1a, 64 bits: the records' checksum and the short names of their files.
std::uint64_t hash64(std::span<const std::byte> bytes,
                     std::uint64_t seed = 0xcbf29ce484222325ull) noexcept;
std::uint64_t hash64(std::string_view text, std::uint64_t seed = 0xcbf29ce484222325ull) noexcept;

/// The payload of the record at `path` when the file is whole (its checksum holds) and was
/// written as `kind` for exactly `key`; nullopt otherwise.
std::optional<std::vector<std::byte>> readRecord(const std::filesystem::path& path,
                                                 std::string_view kind, std::string_view key);

/// Writes the record whole or not at all: to a temporary file in the same folder (created,
/// owner-only, when missing), then renamed over `path`, so a reader in another process sees the
/// old record or the new one. Returns false on any failure (no folder, read-only, disk full),
/// which callers ignore.
bool writeRecord(const std::filesystem::path& path, std::string_view kind, std::string_view key,
                 std::span<const std::byte> payload);

/// Removes the record at `path` if there is one (a verdict that no longer holds).
void removeRecord(const std::filesystem::path& path) noexcept;

}  // namespace octovk::vk::disk
