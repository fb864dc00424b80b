// ASCII PLY files (ply.hpp), written in blocks of about a megabyte.
#include "ply.hpp"

#include <cerrno>
#include <charconv>
#include <cstring>
#include <fstream>

#include "octovk/octovk.hpp"

namespace octovk::cli {

void appendNumber(std::string& out, float value, char separator) {
  char text[32];
  const auto [end, ec] = std::to_chars(text, text + sizeof(text), value);
  (void)ec;  // 32 characters hold every float
  out.append(text, end);
  out += separator;
}

void appendByte(std::string& out, std::uint8_t value, char separator) {
  char text[4];
  const auto [end, ec] = std::to_chars(text, text + sizeof(text), static_cast<unsigned>(value));
  (void)ec;
  out.append(text, end);
  out += separator;
}

void writeAsciiPly(const std::string& path, const std::string& comment, std::size_t count,
                   const std::vector<std::string>& properties,
                   const std::function<void(std::string& text, std::size_t index)>& vertex) {
  std::ofstream out(path, std::ios_base::binary | std::ios_base::trunc);
  if (!out.is_open())
    throw Error(ErrorCode::kIo, "cannot write '" + path + "': " + std::strerror(errno));
  std::string text = "ply\nformat ascii 1.0\ncomment " + comment + "\nelement vertex " +
                     std::to_string(count) + "\n";
  for (const std::string& property : properties) text += "property " + property + "\n";
  text += "end_header\n";
  for (std::size_t i = 0; i < count; ++i) {
    vertex(text, i);
    if (text.size() > (1u << 20)) {
      out.write(text.data(), static_cast<std::streamsize>(text.size()));
      text.clear();
    }
  }
  out.write(text.data(), static_cast<std::streamsize>(text.size()));
  out.close();
  if (!out.good())
    throw Error(ErrorCode::kIo, "failed writing '" + path + "' (disk full or I/O error)");
}

}  // namespace octovk::cli
