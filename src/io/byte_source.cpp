// io::ByteSource: a file read piece by piece as a parser reaches its bytes (see byte_source.hpp).
#include "io/byte_source.hpp"

#include <algorithm>

namespace octovk::io {

bool ByteSource::more(std::uint64_t end) {
  if (!in_) return false;  // a caller's buffer: all there is
  while (!done_ && base_ + buffer_.size() < end) {
    // One piece at a time, whatever `end` asks: a count read from the file never sizes a read.
    const std::size_t held = buffer_.size();
    buffer_.resize(held + kPiece);
    in_->read(buffer_.data() + held, static_cast<std::streamsize>(kPiece));
    const auto got = static_cast<std::size_t>(std::max<std::streamsize>(in_->gcount(), 0));
    buffer_.resize(held + got);
    if (in_->bad()) throw Error(ErrorCode::kIo, "cannot read '" + name_ + "': read error");
    if (got < kPiece) done_ = true;
  }
  view_ = buffer_;
  return end <= base_ + buffer_.size();
}

void ByteSource::release(std::uint64_t offset) {
  if (!in_ || offset <= base_) return;
  // Only once a piece is done with, so that a parse moving a few bytes at a time copies little.
  const std::uint64_t drop = std::min<std::uint64_t>(offset - base_, buffer_.size());
  if (drop < kPiece) return;
  buffer_.erase(0, static_cast<std::size_t>(drop));
  base_ += drop;
  view_ = buffer_;
}

}  // namespace octovk::io
