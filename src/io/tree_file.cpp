// .bt / .ot files checked before OctoMap reads them. OctoMap's readers trust their input: they read
// node records recursively, following every child flag, without looking at the stream (past the
// end of a truncated file they test flags they never read; a damaged file nests until the stack
// overflows or memory runs out), and they ignore a header's size of 0, a missing size, a tree type
// they can read as another, or a second value on the res line. So octovk parses the header itself
// and walks the records without recursion first; OctoMap's data reader only sees a data section
// that holds exactly one whole tree of at most 16 levels with the announced node count.
#include <octomap/OcTree.h>

#include <array>
#include <charconv>
#include <cmath>
#include <cstring>
#include <istream>
#include <optional>
#include <streambuf>
#include <string>
#include <string_view>
#include <vector>

#include "io/parse.hpp"

namespace octovk::io {

namespace {

constexpr unsigned kTreeDepth = 16;  // OctoMap's keys: leaves lie 16 levels below the root
constexpr std::string_view kFullHeader = "# Octomap OcTree file";
constexpr std::string_view kBinaryHeader = "# Octomap OcTree binary file";

// A .ot node record holds the node's data (OcTreeNode::writeData: its float log-odds; a payload
// such as a ColorOcTree's colour would follow it), then a byte with a bit per child whose record
// follows. The data's size, and what is wrong with it ("" when nothing: a finite log-odds).
constexpr std::size_t kRecordDataBytes = sizeof(float);
std::string recordDataFault(std::string_view data) {
  float log_odds;
  std::memcpy(&log_odds, data.data(), sizeof(float));
  if (std::isfinite(log_odds)) return {};
  return " has log-odds " + std::to_string(log_odds) + ", not a finite number";
}

// A file's text for a message: at most 40 characters, anything unprintable as '?'.
std::string shown(std::string_view text) {
  std::string out;
  for (char c : text.substr(0, 40)) out += (c >= 0x20 && c < 0x7f) ? c : '?';
  if (text.size() > 40) out += "...";
  return out;
}

// Refusals of a tree's bytes: a file (.bt / .ot) or a message body (OctoMap's writeBinaryData /
// writeData output, as octomap_msgs carries it).
class Fault {
 public:
  Fault(const std::string& name, bool binary, bool message = false)
      : name_(name), binary_(binary), message_(message) {}
  Error operator()(const std::string& why) const {
    if (message_)
      return Error(ErrorCode::kFormat,
                   "'" + name_ + "' is not a valid OctoMap " + (binary_ ? "binary" : "full") +
                       " map message body: " + why +
                       "; the message is corrupt or truncated, or its binary flag is wrong "
                       "(binary bodies come from writeBinaryData, full ones from writeData)");
    return Error(ErrorCode::kFormat, "'" + name_ + "' is not a valid OctoMap " +
                                         (binary_ ? ".bt" : ".ot") + " file: " + why +
                                         "; the file is corrupt, truncated or of another kind "
                                         "(write it again with OctoMap or octovk)");
  }

 private:
  const std::string& name_;
  bool binary_;
  bool message_;
};

// The whitespace-separated words of a header line (as OctoMap's `>>` splits them); at most 3,
// which is one more than any header line may hold.
std::vector<std::string_view> words(std::string_view line) {
  std::vector<std::string_view> out;
  const auto space = [](char c) {
    return c == ' ' || c == '\t' || c == '\r' || c == '\v' || c == '\f';
  };
  std::size_t i = 0;
  while (i < line.size() && out.size() < 3) {
    while (i < line.size() && space(line[i])) ++i;
    const std::size_t start = i;
    while (i < line.size() && !space(line[i])) ++i;
    if (i > start) out.push_back(line.substr(start, i - start));
  }
  return out;
}

// The bytes of a data section as a stream for OctoMap's reader, without a copy.
class ViewBuffer : public std::streambuf {
 public:
  explicit ViewBuffer(std::string_view bytes) {
    char* begin = const_cast<char*>(bytes.data());  // only read
    setg(begin, begin, begin + bytes.size());
  }
  std::size_t consumed() const { return static_cast<std::size_t>(gptr() - eback()); }
};

}  // namespace

namespace {

// The longest header line read: OctoMap writes lines of a few dozen bytes, and a line without
// end (a sparse file's zeros after a comment's '#') must not be read whole.
constexpr std::size_t kMaxHeaderLine = 64 * 1024;

TreeHeader readHeader(ByteSource& source, bool binary, const Fault& bad) {
  const std::string_view magic = binary ? kBinaryHeader : kFullHeader;
  std::uint64_t at = 0;
  // The next line without its '\n' (at most kMaxHeaderLine + 1 bytes of it); `at` moves past
  // the '\n' (or to the end). Valid until the next call.
  const auto next_line = [&]() {
    std::uint64_t end = at;
    while (source.has(end + 1) && source.at(end) != '\n' && end - at <= kMaxHeaderLine) ++end;
    const std::string_view line = source.view(at, end);
    at = source.has(end + 1) ? end + 1 : end;
    return line;
  };
  const auto too_long = [&](std::string_view line, std::uint64_t line_at) {
    if (line.size() > kMaxHeaderLine)
      throw bad("the header line at byte " + std::to_string(line_at) + " ('" + shown(line) +
                "') is longer than " + std::to_string(kMaxHeaderLine) + " bytes");
  };
  if (!source.has(1)) throw bad("it is empty");
  const std::string_view first = next_line();
  if (first.substr(0, magic.size()) != magic) {
    if (binary && first.substr(0, kFullHeader.size()) == kFullHeader)
      throw bad("it holds a full tree (its first line is '" + std::string(kFullHeader) +
                "'); name it .ot");
    if (!binary && first.substr(0, kBinaryHeader.size()) == kBinaryHeader)
      throw bad("it holds a binary tree (its first line is '" + std::string(kBinaryHeader) +
                "'); name it .bt");
    throw bad("its first line is '" + shown(first) + "', not '" + std::string(magic) + "'");
  }
  too_long(first, 0);
  TreeHeader h;
  bool has_id = false, has_size = false, has_res = false, has_data = false;
  while (source.has(at + 1) && !has_data) {
    const std::uint64_t line_at = at;
    const std::string_view line = next_line();
    too_long(line, line_at);
    const std::vector<std::string_view> w = words(line);
    if (w.empty() || w[0].front() == '#') continue;  // blank or comment
    const std::string key(w[0]);
    const auto one_value = [&](bool& seen) {
      if (seen) throw bad("the header gives '" + key + "' twice");
      seen = true;
      if (w.size() != 2)
        throw bad("the header line '" + shown(line) + "' must be '" + key + "' and one value");
      return w[1];
    };
    if (key == "id") {
      h.id = std::string(one_value(has_id));
    } else if (key == "size") {
      const std::string_view v = one_value(has_size);
      const auto [end, ec] = std::from_chars(v.data(), v.data() + v.size(), h.size);
      if (ec != std::errc() || end != v.data() + v.size())
        throw bad("the header's size '" + shown(v) + "' is not a node count");
    } else if (key == "res") {
      const std::string_view v = one_value(has_res);
      const auto [end, ec] = std::from_chars(v.data(), v.data() + v.size(), h.resolution);
      if (ec != std::errc() || end != v.data() + v.size() || !std::isfinite(h.resolution) ||
          h.resolution <= 0.0)
        throw bad("the header's resolution '" + shown(v) + "' is not a positive number of metres");
      MapParams params;
      params.resolution = h.resolution;
      if (const std::string why = params.validate(); !why.empty()) throw bad("the header's " + why);
    } else if (key == "data") {
      if (w.size() != 1) throw bad("the header line '" + shown(line) + "' must be just 'data'");
      has_data = true;
    } else {
      throw bad("unknown header line '" + shown(line) + "' at byte " + std::to_string(line_at) +
                " (a header holds comments and id, size, res and data lines)");
    }
  }
  if (!has_data) throw bad("its header has no 'data' line (truncated?)");
  if (!has_id) throw bad("its header has no 'id' line");
  if (h.id != "OcTree")
    throw bad("it holds a tree of type '" + shown(h.id) +
              "', not a plain OcTree; octovk reads OcTree maps only");
  if (!has_size) throw bad("its header has no 'size' line, so its node data cannot be checked");
  if (!has_res) throw bad("its header has no 'res' line");
  h.data_at = static_cast<std::size_t>(at);
  return h;
}

}  // namespace

TreeHeader parseTreeHeader(std::string_view bytes, bool binary, const std::string& name) {
  ByteSource source(bytes);
  return readHeader(source, binary, Fault(name, binary));
}

namespace {

// The node records of a tree (a file's data section, or a message body) walked without
// recursion as `source` gives them, then read by OctoMap. `offset`: where the records start in
// `source` (offsets in messages count from the start of what the caller names); `announced`:
// the node count a file's header gives (a message has none).
std::unique_ptr<octomap::OcTree> readTreeData(ByteSource& source, std::uint64_t offset, bool binary,
                                              double resolution,
                                              std::optional<std::uint64_t> announced,
                                              const Fault& bad) {
  auto tree = std::make_unique<octomap::OcTree>(resolution);
  const std::uint64_t apparent = source.size() > offset ? source.size() - offset : 0;
  if (!source.has(offset + 1)) {
    // What OctoMap writes for an empty tree: no record (its header says size 0).
    if (announced && *announced != 0)
      throw bad("its header announces " + std::to_string(*announced) +
                " nodes, but the data section is empty (truncated?)");
    return tree;
  }
  if (announced && *announced == 0)
    throw bad("its header announces 0 nodes, but " + std::to_string(apparent) +
              " bytes of node data follow");

  // The walk: a stack of the nodes whose child records are still to come (at most 17).
  struct Open {
    unsigned depth;
    unsigned children;  // a bit per child whose record is still to come
  };
  std::array<Open, kTreeDepth + 1> open{};
  std::size_t top = 0;
  std::uint64_t at = offset;
  std::uint64_t nodes = binary ? 1 : 0;  // .bt: records list children; the root has none
  const auto where = [&](unsigned depth) {
    return "the node record at byte " + std::to_string(at) + " (depth " + std::to_string(depth) +
           ")";
  };
  const auto record = [&](unsigned depth) {
    if (binary) {  // 2 bits per child: 00 none, 01 occupied leaf, 10 free leaf, 11 inner node
      if (!source.has(at + 2)) throw bad(where(depth) + " runs past the end of the file");
      unsigned inner = 0, children = 0;
      for (unsigned i = 0; i < 8; ++i) {
        const unsigned pair = (source.at(at + i / 4) >> (2 * (i % 4))) & 3u;
        if (pair != 0) ++children;
        if (pair == 3) inner |= 1u << i;
      }
      if (depth > 0 && children == 0)
        throw bad(where(depth) + " is an inner node without children");
      if (inner != 0 && depth + 1 >= kTreeDepth)
        throw bad(where(depth) + " has inner children, deeper than a tree's 16 levels");
      nodes += children;
      open[top++] = {depth, inner};
      at += 2;
    } else {  // the node's data, then a byte with a bit per child whose record follows
      if (!source.has(at + kRecordDataBytes + 1))
        throw bad(where(depth) + " runs past the end of the file");
      const std::string fault = recordDataFault(source.view(at, at + kRecordDataBytes));
      if (!fault.empty()) throw bad(where(depth) + fault);
      const unsigned mask = source.at(at + kRecordDataBytes);
      if (mask != 0 && depth >= kTreeDepth)
        throw bad(where(depth) + " has children, deeper than a tree's 16 levels");
      ++nodes;
      open[top++] = {depth, mask};
      at += kRecordDataBytes + 1;
    }
    // More nodes than announced: refused now rather than after the rest of the file.
    if (announced && nodes > *announced)
      throw bad("its header announces " + std::to_string(*announced) +
                " nodes, the data holds more (" + std::to_string(nodes) + " by byte " +
                std::to_string(at) + ")");
  };
  record(0);
  while (top > 0) {
    Open& last = open[top - 1];
    if (last.children == 0) {
      --top;
      continue;
    }
    last.children &= last.children - 1;  // the lowest child's record is next
    record(last.depth + 1);
  }
  if (source.has(at + 1))
    throw bad(std::to_string(source.size() > at ? source.size() - at : 1) +
              " bytes follow the tree's last node record (at byte " + std::to_string(at) + ")");
  if (announced && nodes != *announced)
    throw bad("its header announces " + std::to_string(*announced) + " nodes, the data holds " +
              std::to_string(nodes));

  // A whole tree OctoMap can read: now OctoMap reads it.
  const std::string_view data = source.view(offset, at);
  ViewBuffer buffer(data);
  std::istream in(&buffer);
  if (binary)
    tree->readBinaryData(in);
  else
    tree->readData(in);
  if (in.fail() || buffer.consumed() != data.size() || tree->size() != nodes)
    throw bad("OctoMap read " + std::to_string(tree->size()) + " nodes from " +
              std::to_string(buffer.consumed()) + " bytes, where the check found " +
              std::to_string(nodes) + " in " + std::to_string(data.size()));
  return tree;
}

}  // namespace

std::unique_ptr<octomap::OcTree> parseTreeFile(std::string_view bytes, bool binary,
                                               const std::string& name) {
  ByteSource source(bytes);
  return parseTreeFile(source, binary, name);
}

std::unique_ptr<octomap::OcTree> parseTreeFile(ByteSource& source, bool binary,
                                               const std::string& name) {
  const Fault bad(name, binary);
  const TreeHeader h = readHeader(source, binary, bad);
  source.release(h.data_at);  // the header's bytes: OctoMap's reader sees the data section only
  return readTreeData(source, h.data_at, binary, h.resolution, h.size, bad);
}

std::unique_ptr<octomap::OcTree> parseTreeBody(std::string_view body, bool binary,
                                               const std::string& id, double resolution,
                                               const std::string& name) {
  const Fault bad(name, binary, /*message=*/true);
  if (id != "OcTree")
    throw bad("it holds a tree of type '" + shown(id) +
              "', not a plain OcTree; octovk reads OcTree maps only");
  MapParams params;
  params.resolution = resolution;
  if (!std::isfinite(resolution) || resolution <= 0.0)
    throw bad("its resolution " + std::to_string(resolution) +
              " is not a positive number of metres");
  if (const std::string why = params.validate(); !why.empty()) throw bad("its " + why);
  ByteSource source(body);
  return readTreeData(source, 0, binary, resolution, std::nullopt, bad);
}

}  // namespace octovk::io
