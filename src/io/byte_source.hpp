// The bytes of a file as a parser reaches them (src/io/byte_source.cpp): the readers of
// parse.hpp and tum_parse.hpp read a file through it, and take a buffer through it alike.
#pragma once

#include <cstddef>
#include <cstdint>
#include <istream>
#include <string>
#include <string_view>

#include "octovk/errors.hpp"

namespace octovk::io {

/// Bytes as a parser asks for them: a buffer held whole, or a stream read in pieces of kPiece
/// bytes as the parse goes on. Memory follows the bytes a parse has reached, never a file's
/// apparent size: a sparse file of gigabytes fails at its first bad record after one piece.
/// Offsets are from the first byte; the bytes before release()'s offset may be let go.
class ByteSource {
 public:
  static constexpr std::size_t kPiece = 64 * 1024;

  /// All of `bytes`, held by the caller.
  explicit ByteSource(std::string_view bytes) : view_(bytes), size_(bytes.size()), done_(true) {}
  /// `in` read on demand; `size` is what the file's size says (for messages and for counts
  /// checked against it, never for an allocation); a read error is kIo naming `name`.
  ByteSource(std::istream& in, std::uint64_t size, const std::string& name)
      : in_(&in), name_(name), size_(size) {}

  /// Whether the bytes up to `end` (exclusive) exist; reads on, piece by piece, to find out.
  bool has(std::uint64_t end) { return end <= base_ + view_.size() || more(end); }
  /// The byte at `offset` (has(offset + 1), and not released).
  unsigned char at(std::uint64_t offset) const {
    return static_cast<unsigned char>(view_[offset - base_]);
  }
  /// The bytes [from, to) (has(to), and not released); valid until the next has() or release().
  std::string_view view(std::uint64_t from, std::uint64_t to) const {
    return view_.substr(from - base_, to - from);
  }
  /// The bytes' size as the caller gave it (the file's size): an upper bound for counts.
  std::uint64_t size() const { return size_; }
  /// The bytes before `offset` are not asked for again: a stream's buffer lets them go.
  void release(std::uint64_t offset);

 private:
  bool more(std::uint64_t end);

  std::istream* in_ = nullptr;
  std::string name_;
  std::string buffer_;     // a stream's bytes from base_ on
  std::string_view view_;  // the bytes held: buffer_, or the caller's
  std::uint64_t base_ = 0;
  std::uint64_t size_ = 0;
  bool done_ = false;  // the stream has ended (or there is none)
};

}  // namespace octovk::io
