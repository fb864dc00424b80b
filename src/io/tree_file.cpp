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

// A .ot node record holds the node's data (the node's writeData: its float log-odds, then for a
// ColorOcTree the colour's r, g, b bytes; an OcTreeStamped writes no stamp), then a byte with a
// bit per child whose record follows. The data's size by payload, and what is wrong with it (""
// when nothing: a finite log-odds; every colour is one).
constexpr std::size_t kRecordDataBytes[] = {sizeof(float), sizeof(float) + 3, sizeof(float)};
std::size_t recordDataBytes(Payload payload) {
  return kRecordDataBytes[static_cast<std::size_t>(payload)];
}
std::string recordDataFault(std::string_view data) {
  float log_odds;
  std::memcpy(&log_odds, data.data(), sizeof(float));
  if (std::isfinite(log_odds)) return {};
  return " has log-odds " + std::to_string(log_odds) + ", not a finite number";
}

// What a refusal of a tree type says: the types octovk reads.
std::string unknownTreeType(std::string_view id);

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

std::string unknownTreeType(std::string_view id) {
  return "it holds a tree of type '" + shown(id) +
         "'; octovk reads OcTree, ColorOcTree and OcTreeStamped maps";
}

}  // namespace

bool payloadOfTreeType(std::string_view id, Payload& payload) {
  for (const Payload p : {Payload::kNone, Payload::kColor, Payload::kStamp}) {
    if (id != treeTypeName(p)) continue;
    payload = p;
    return true;
  }
  return false;
}

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
  if (Payload payload; !payloadOfTreeType(h.id, payload)) throw bad(unknownTreeType(h.id));
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

// OctoMap's reader of a tree type on a data section the walk found whole (`nodes` nodes).
template <class Tree>
std::unique_ptr<Tree> readWithOctoMap(std::string_view data, bool binary, double resolution,
                                      std::uint64_t nodes, const Fault& bad) {
  auto tree = std::make_unique<Tree>(resolution);
  if (data.empty()) return tree;
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

// The node records of a tree (a file's data section, or a message body) of type `payload` walked
// without recursion as `source` gives them, then read by OctoMap. `offset`: where the records
// start in `source` (offsets in messages count from the start of what the caller names);
// `announced`: the node count a file's header gives (a message has none).
AnyTree readTreeData(ByteSource& source, std::uint64_t offset, bool binary, Payload payload,
                     double resolution, std::optional<std::uint64_t> announced, const Fault& bad) {
  const std::size_t data_bytes = recordDataBytes(payload);
  const std::uint64_t apparent = source.size() > offset ? source.size() - offset : 0;
  std::uint64_t at = offset;
  std::uint64_t nodes = 0;
  if (!source.has(offset + 1)) {
    // What OctoMap writes for an empty tree: no record (its header says size 0).
    if (announced && *announced != 0)
      throw bad("its header announces " + std::to_string(*announced) +
                " nodes, but the data section is empty (truncated?)");
  } else {
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
    nodes = binary ? 1 : 0;  // .bt: records list children; the root has none
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
        if (!source.has(at + data_bytes + 1))
          throw bad(where(depth) + " runs past the end of the file");
        const std::string fault = recordDataFault(source.view(at, at + data_bytes));
        if (!fault.empty()) throw bad(where(depth) + fault);
        const unsigned mask = source.at(at + data_bytes);
        if (mask != 0 && depth >= kTreeDepth)
          throw bad(where(depth) + " has children, deeper than a tree's 16 levels");
        ++nodes;
        open[top++] = {depth, mask};
        at += data_bytes + 1;
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
  }

  // A whole tree OctoMap can read (or none): now OctoMap reads it, as the type it is.
  const std::string_view data = at > offset ? source.view(offset, at) : std::string_view();
  switch (payload) {
    case Payload::kColor:
      return readWithOctoMap<octomap::ColorOcTree>(data, binary, resolution, nodes, bad);
    case Payload::kStamp:
      return readWithOctoMap<octomap::OcTreeStamped>(data, binary, resolution, nodes, bad);
    case Payload::kNone:
      break;
  }
  return readWithOctoMap<octomap::OcTree>(data, binary, resolution, nodes, bad);
}

}  // namespace

AnyTree parseTreeFile(std::string_view bytes, bool binary, const std::string& name) {
  ByteSource source(bytes);
  return parseTreeFile(source, binary, name);
}

AnyTree parseTreeFile(ByteSource& source, bool binary, const std::string& name) {
  const Fault bad(name, binary);
  const TreeHeader h = readHeader(source, binary, bad);
  Payload payload = Payload::kNone;
  payloadOfTreeType(h.id, payload);  // readHeader refused any other
  source.release(h.data_at);  // the header's bytes: OctoMap's reader sees the data section only
  return readTreeData(source, h.data_at, binary, payload, h.resolution, h.size, bad);
}

AnyTree parseTreeBody(std::string_view body, bool binary, const std::string& id, double resolution,
                      const std::string& name) {
  const Fault bad(name, binary, /*message=*/true);
  Payload payload = Payload::kNone;
  if (!payloadOfTreeType(id, payload)) throw bad(unknownTreeType(id));
  MapParams params;
  params.resolution = resolution;
  if (!std::isfinite(resolution) || resolution <= 0.0)
    throw bad("its resolution " + std::to_string(resolution) +
              " is not a positive number of metres");
  if (const std::string why = params.validate(); !why.empty()) throw bad("its " + why);
  ByteSource source(body);
  return readTreeData(source, 0, binary, payload, resolution, std::nullopt, bad);
}

// ---- a stamped map's sidecar ----

namespace {

constexpr std::string_view kStampsMagic = "OVKSTAMP";
constexpr std::uint32_t kStampsVersion = 1;

// Calls visit(index) for every node of `tree` in the .ot's order: depth first, children 0 to 7.
template <class Visit>
void forEachInFileOrder(const HostTree& tree, Visit&& visit) {
  if (!tree.root_exists || tree.nodes.empty()) return;
  std::vector<std::uint64_t> stack{0};
  while (!stack.empty()) {
    const std::uint64_t i = stack.back();
    stack.pop_back();
    if (i >= tree.nodes.size())
      throw Error(ErrorCode::kInternal, "a host tree's child link leaves its nodes");
    visit(static_cast<std::size_t>(i));
    const HostTree::Node& n = tree.nodes[i];
    for (int c = 7; c >= 0; --c)
      if (n.mask & (1u << c)) stack.push_back(std::uint64_t{n.children} * 8 + c);
  }
}

void putLittle(std::string& out, std::uint64_t value, unsigned bytes) {
  for (unsigned i = 0; i < bytes; ++i) out += static_cast<char>((value >> (8 * i)) & 0xFFu);
}

std::uint64_t getLittle(std::string_view in, std::size_t at, unsigned bytes) {
  std::uint64_t value = 0;
  for (unsigned i = 0; i < bytes; ++i)
    value |= std::uint64_t{static_cast<unsigned char>(in[at + i])} << (8 * i);
  return value;
}

}  // namespace

std::uint64_t treeDigest(const HostTree& tree) {
  std::uint64_t hash = 14695981039346656037ull;  // FNV-1a's offset basis
  const auto add = [&](std::uint64_t byte) {
    hash ^= byte;
    hash *= 1099511628211ull;  // FNV's 64-bit prime
  };
  forEachInFileOrder(tree, [&](std::size_t i) {
    std::uint32_t bits;
    std::memcpy(&bits, &tree.nodes[i].log_odds, sizeof(bits));
    for (unsigned b = 0; b < 4; ++b) add((bits >> (8 * b)) & 0xFFu);
    add(tree.nodes[i].mask & 0xFFu);
  });
  return hash;
}

std::string stampsFile(const HostTree& tree) {
  std::vector<std::uint32_t> stamps;
  forEachInFileOrder(tree, [&](std::size_t i) { stamps.push_back(tree.nodes[i].payload); });
  std::string out(kStampsMagic);
  out.reserve(stampsFileSize(stamps.size()));
  putLittle(out, kStampsVersion, 4);
  putLittle(out, 0, 4);
  putLittle(out, stamps.size(), 8);
  putLittle(out, treeDigest(tree), 8);
  for (const std::uint32_t stamp : stamps) putLittle(out, stamp, 4);
  return out;
}

void applyStampsFile(std::string_view bytes, HostTree& tree, const std::string& name) {
  ByteSource source(bytes);
  applyStampsFile(source, tree, name);
}

void applyStampsFile(ByteSource& source, HostTree& tree, const std::string& name) {
  const auto bad = [&](const std::string& why) {
    return Error(ErrorCode::kFormat,
                 "'" + name + "' does not hold this map's time stamps: " + why +
                     "; it is damaged, or the map beside it was written again without it "
                     "(delete it to read the map with every stamp 0)");
  };
  std::vector<std::size_t> order;
  forEachInFileOrder(tree, [&](std::size_t i) { order.push_back(i); });
  if (!source.has(kStampsHeaderBytes))
    throw bad("it is " + std::to_string(source.size()) + " bytes, shorter than the " +
              std::to_string(kStampsHeaderBytes) + "-byte header of an octovk stamps file");
  const std::string_view header = source.view(0, kStampsHeaderBytes);
  if (header.substr(0, kStampsMagic.size()) != kStampsMagic)
    throw bad("it does not start with '" + std::string(kStampsMagic) + "' but '" +
              shown(header.substr(0, kStampsMagic.size())) + "'");
  if (const std::uint64_t version = getLittle(header, 8, 4); version != kStampsVersion)
    throw bad("it is of version " + std::to_string(version) + "; this octovk reads version " +
              std::to_string(kStampsVersion));
  if (getLittle(header, 12, 4) != 0) throw bad("its reserved bytes 12-15 are not zero");
  const std::uint64_t count = getLittle(header, 16, 8);
  const std::uint64_t digest = getLittle(header, 24, 8);
  if (count != order.size())
    throw bad("it holds stamps for " + std::to_string(count) + " nodes, the map has " +
              std::to_string(order.size()));
  const std::uint64_t expected = stampsFileSize(count);
  const auto wrong_size = [&](std::uint64_t size) {
    return bad("it is " + std::to_string(size) + " bytes, not the " + std::to_string(expected) +
               " that " + std::to_string(count) + " stamps take");
  };
  if (source.size() != expected) throw wrong_size(source.size());
  if (digest != treeDigest(tree))
    throw bad(
        "its digest of the map's nodes differs from the map's (the same node count, "
        "other values or shape)");
  std::vector<std::uint32_t> stamps(order.size());
  for (std::size_t k = 0; k < order.size(); ++k) {
    const std::uint64_t at = kStampsHeaderBytes + 4 * std::uint64_t{k};
    if (!source.has(at + 4)) throw wrong_size(at);  // shrunk while read
    stamps[k] = static_cast<std::uint32_t>(getLittle(source.view(at, at + 4), 0, 4));
    source.release(at);
  }
  if (source.has(expected + 1)) throw wrong_size(expected + 1);  // grown while read
  for (std::size_t k = 0; k < order.size(); ++k) tree.nodes[order[k]].payload = stamps[k];
}

}  // namespace octovk::io
