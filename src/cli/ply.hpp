// ASCII PLY point clouds for the octovk commands (export's leaf cells, integrate's changed keys):
// the header, and numbers in their shortest exact form.
#pragma once

#include <cstddef>
#include <cstdint>
#include <functional>
#include <string>
#include <vector>

namespace octovk::cli {

/// Appends `value` in its shortest exact form (std::to_chars), then `separator`.
void appendNumber(std::string& out, float value, char separator);
void appendByte(std::string& out, std::uint8_t value, char separator);

/// Writes an ASCII PLY file at `path` (this file, not a temporary one): the header with
/// `comment`, `count` vertices and `properties` ("float x", "uchar red", ...), then for each
/// vertex the line `vertex(text, index)` appends (its values, ending in '\n'). Throws
/// octovk::Error (kIo) naming `path` when it cannot be written in full.
void writeAsciiPly(const std::string& path, const std::string& comment, std::size_t count,
                   const std::vector<std::string>& properties,
                   const std::function<void(std::string& text, std::size_t index)>& vertex);

}  // namespace octovk::cli
