// The map as an octomap::OcTree and OctoMap's .bt / .ot files.
#include "octovk/octomap_io.hpp"

#include <unistd.h>

#include <cerrno>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <functional>
#include <iterator>
#include <optional>
#include <sstream>
#include <variant>
#include <vector>

#include "io/parse.hpp"
#include "map/host_memory.hpp"
#include "map/host_tree.hpp"
#include "map/reference.hpp"

namespace octovk {

namespace {

// An OctoMap tree with access to the protected root, to build a tree node by node.
template <class Tree>
class TreeBuilder : public Tree {
 public:
  using Node = typename Tree::NodeType;
  explicit TreeBuilder(double resolution) : Tree(resolution) {}
  Node* makeRoot() {
    this->root = new Node();
    this->tree_size = 1;
    this->size_changed = true;
    return this->root;
  }
};

// A node's data between the host tree and OctoMap's node, per tree type: the twins of
// host_tree.hpp's accessors. An OcTree node has no payload; a map with one gives it a new node's.
void copyNodeData(const HostTree::Node& from, octomap::OcTreeNode& to) {
  to.setLogOdds(from.log_odds);
}
void copyNodeData(const HostTree::Node& from, octomap::ColorOcTreeNode& to) {
  to.setLogOdds(from.log_odds);
  const Rgb c = unpackRgb(from.payload);
  to.setColor(c.r, c.g, c.b);
}
void copyNodeData(const HostTree::Node& from, octomap::OcTreeNodeStamped& to) {
  to.setLogOdds(from.log_odds);
  to.setTimestamp(from.payload);
}
HostTree::Node hostNodeOf(const octomap::OcTreeNode& from, Payload payload) {
  HostTree::Node n = emptyHostNode();
  n.log_odds = from.getLogOdds();
  n.payload = newNodePayload(payload);
  return n;
}
HostTree::Node hostNodeOf(const octomap::ColorOcTreeNode& from, Payload) {
  HostTree::Node n = emptyHostNode();
  n.log_odds = from.getLogOdds();
  const octomap::ColorOcTreeNode::Color c = from.getColor();
  n.payload = packRgb(Rgb{c.r, c.g, c.b});
  return n;
}
HostTree::Node hostNodeOf(const octomap::OcTreeNodeStamped& from, Payload) {
  HostTree::Node n = emptyHostNode();
  n.log_odds = from.getLogOdds();
  n.payload = from.getTimestamp();
  return n;
}

// The payload a tree type holds (kNone: an OcTree's nodes take the map's new-node payload).
constexpr Payload payloadOf(const octomap::OcTree*) { return Payload::kNone; }
constexpr Payload payloadOf(const octomap::ColorOcTree*) { return Payload::kColor; }
constexpr Payload payloadOf(const octomap::OcTreeStamped*) { return Payload::kStamp; }

// "an OcTree", "a ColorOcTree", "an OcTreeStamped".
std::string typeWithArticle(Payload payload) {
  const std::string name = treeTypeName(payload);
  return (name.front() == 'O' ? "an " : "a ") + name;
}

std::string extensionOf(const std::string& path) {
  return std::filesystem::path(path).extension().string();
}

void applyParams(octomap::AbstractOccupancyOcTree& tree, const MapParams& p) {
  tree.setProbHit(p.prob_hit);
  tree.setProbMiss(p.prob_miss);
  tree.setClampingThresMin(p.clamping_min);
  tree.setClampingThresMax(p.clamping_max);
  tree.setOccupancyThres(p.occupancy_threshold);
}

// `host` as an OctoMap tree of type Tree, with `params`' sensor model.
template <class Tree>
std::unique_ptr<Tree> buildTree(const HostTree& host, const MapParams& params) {
  auto tree = std::make_unique<TreeBuilder<Tree>>(params.resolution);
  applyParams(*tree, params);
  if (!host.root_exists) return tree;
  using Node = typename Tree::NodeType;
  std::function<void(std::uint32_t, Node*, unsigned)> build = [&](std::uint32_t index, Node* node,
                                                                  unsigned depth) {
    const HostTree::Node& n = host.nodes.at(index);
    copyNodeData(n, *node);
    if (depth >= 16) return;
    for (unsigned i = 0; i < 8; ++i) {
      if (!(n.mask & (1u << i))) continue;
      build(n.children * 8 + i, tree->createNodeChild(node, i), depth + 1);
    }
  };
  build(0, tree->makeRoot(), 0);
  return tree;
}

// The map's tree as OctoMap's tree of type Tree; a map of another payload is kInvalidArgument.
template <class Tree>
std::unique_ptr<Tree> mapAs(OccupancyMap& map, const char* call) {
  const Payload want = payloadOf(static_cast<const Tree*>(nullptr));
  if (map.params().payload != want)
    throw Error(ErrorCode::kInvalidArgument, std::string(call) + ": the map is " +
                                                 typeWithArticle(map.params().payload) + ", not " +
                                                 typeWithArticle(want));
  return buildTree<Tree>(map.download(), map.params());
}

// `tree` in the pool's layout for a map with `payload`, for OccupancyMap::upload.
template <class Tree>
HostTree hostTreeOf(const Tree& tree, Payload payload) {
  HostTree host;
  host.payload = payload;
  const auto* root = tree.getRoot();
  host.root_exists = root != nullptr;
  if (root) {
    host.nodes.resize(8);
    host.nodes[0] = hostNodeOf(*root, payload);
    // Breadth first: each node with children gets the next block of 8 slots.
    std::vector<std::pair<decltype(root), std::uint32_t>> queue{{root, 0}};
    for (std::size_t head = 0; head < queue.size(); ++head) {
      const auto [node, index] = queue[head];
      if (!tree.nodeHasChildren(node)) continue;
      const std::uint32_t block = static_cast<std::uint32_t>(host.nodes.size() / 8);
      host.nodes.resize(host.nodes.size() + 8, emptyHostNode());
      std::uint32_t mask = 0;
      for (unsigned i = 0; i < 8; ++i) {
        if (!tree.nodeChildExists(node, i)) continue;
        const auto* child = tree.getNodeChild(node, i);
        host.nodes[block * 8 + i] = hostNodeOf(*child, payload);
        queue.emplace_back(child, block * 8 + i);
        mask |= 1u << i;
      }
      host.nodes[index].children = block;
      host.nodes[index].mask = mask;
    }
  }
  return host;
}

void checkResolution(const OccupancyMap& map, double resolution, const char* call) {
  if (resolution != map.params().resolution)
    throw Error(ErrorCode::kInvalidArgument,
                std::string(call) + ": the tree's resolution " + std::to_string(resolution) +
                    " differs from the map's " + std::to_string(map.params().resolution));
}

// Uploads `tree` into `map` (resolution checked; nodes take the map's payload kind).
template <class Tree>
void uploadTree(OccupancyMap& map, const Tree& tree, const char* call) {
  checkResolution(map, tree.getResolution(), call);
  map.upload(hostTreeOf(tree, map.params().payload));
}

double resolutionOf(const io::AnyTree& any) {
  return std::visit([](const auto& tree) { return tree->getResolution(); }, any);
}

}  // namespace

HostTree io::hostTreeOf(const AnyTree& any) {
  return std::visit(
      [](const auto& tree) {
        return octovk::hostTreeOf(*tree, payloadOf(static_cast<decltype(tree.get())>(nullptr)));
      },
      any);
}

std::unique_ptr<octomap::AbstractOccupancyOcTree> io::octomapTreeOf(const HostTree& host,
                                                                    const MapParams& params) {
  switch (host.payload) {
    case Payload::kColor:
      return buildTree<octomap::ColorOcTree>(host, params);
    case Payload::kStamp:
      return buildTree<octomap::OcTreeStamped>(host, params);
    case Payload::kNone:
      break;
  }
  return buildTree<octomap::OcTree>(host, params);
}

std::unique_ptr<octomap::OcTree> toOcTree(OccupancyMap& map) {
  return hostMemoryGuard("toOcTree",
                         [&] { return buildTree<octomap::OcTree>(map.download(), map.params()); });
}

void fromOcTree(OccupancyMap& map, const octomap::OcTree& tree) {
  hostMemoryGuard("fromOcTree", [&] { uploadTree(map, tree, "fromOcTree"); });
}

std::unique_ptr<octomap::ColorOcTree> toColorOcTree(ColorMap& map) {
  return hostMemoryGuard("toColorOcTree",
                         [&] { return mapAs<octomap::ColorOcTree>(map, "toColorOcTree"); });
}

void fromColorOcTree(ColorMap& map, const octomap::ColorOcTree& tree) {
  hostMemoryGuard("fromColorOcTree", [&] { uploadTree(map, tree, "fromColorOcTree"); });
}

std::unique_ptr<octomap::OcTreeStamped> toOcTreeStamped(StampedMap& map) {
  return hostMemoryGuard("toOcTreeStamped",
                         [&] { return mapAs<octomap::OcTreeStamped>(map, "toOcTreeStamped"); });
}

void fromOcTreeStamped(StampedMap& map, const octomap::OcTreeStamped& tree) {
  hostMemoryGuard("fromOcTreeStamped", [&] { uploadTree(map, tree, "fromOcTreeStamped"); });
}

namespace {

// The file `path` removed unless kept: a failed write (an error, a std::bad_alloc) leaves none.
class TemporaryFile {
 public:
  explicit TemporaryFile(std::string path) : path_(std::move(path)) {}
  ~TemporaryFile() {
    if (!kept_) std::remove(path_.c_str());
  }
  TemporaryFile(const TemporaryFile&) = delete;
  TemporaryFile& operator=(const TemporaryFile&) = delete;
  const std::string& path() const { return path_; }
  void keep() { kept_ = true; }

 private:
  std::string path_;
  bool kept_ = false;
};

// Writes `bytes` into `file` (a temporary); false when the stream failed.
bool writeBytes(const std::string& file, const std::string& target, const std::string& bytes) {
  std::ofstream out(file, std::ios_base::binary);
  if (!out.is_open())
    throw Error(ErrorCode::kIo, "cannot write '" + target + "': " + std::strerror(errno));
  out.write(bytes.data(), static_cast<std::streamsize>(bytes.size()));
  out.close();
  return out.good();
}

// The map as OctoMap's tree of its type, downloaded; a stamped map's sidecar into `stamps`.
std::unique_ptr<octomap::AbstractOccupancyOcTree> treeToWrite(OccupancyMap& map,
                                                              std::string* stamps) {
  const HostTree host = map.download();
  if (stamps) *stamps = host.payload == Payload::kStamp ? io::stampsFile(host) : std::string();
  return io::octomapTreeOf(host, map.params());
}

std::string temporaryName(const std::string& path) {
  return path + ".tmp-" + std::to_string(::getpid());
}

void writeTreeFile(OccupancyMap& map, const std::string& path) {
  const std::string ext = extensionOf(path);
  if (ext != ".bt" && ext != ".ot")
    throw Error(ErrorCode::kInvalidArgument,
                "cannot write '" + path + "': unknown extension '" + ext +
                    "'; use .bt (binary, max-likelihood) or .ot (full log-odds)");
  const std::filesystem::path target(path);
  const std::filesystem::path dir =
      target.has_parent_path() ? target.parent_path() : std::filesystem::path(".");
  if (!std::filesystem::is_directory(dir))
    throw Error(ErrorCode::kIo,
                "cannot write '" + path + "': directory '" + dir.string() + "' does not exist");
  // A stamped map's .ot: its stamps beside it, since OctoMap's .ot holds none.
  const bool with_stamps = map.params().payload == Payload::kStamp && ext == ".ot";
  const std::string stamps_path = path + ".stamps";
  std::string stamps;
  const std::unique_ptr<octomap::AbstractOccupancyOcTree> tree =
      treeToWrite(map, with_stamps ? &stamps : nullptr);
  // Removed on any way out but the rename, from before it is created: opening the stream can
  // create the file, then fail allocating its buffer.
  TemporaryFile tmp(temporaryName(path));
  bool ok = false;
  {
    std::ofstream out(tmp.path(), std::ios_base::binary);
    if (!out.is_open())
      throw Error(ErrorCode::kIo, "cannot write '" + path + "': " + std::strerror(errno));
    if (ext == ".bt")
      ok = tree->writeBinary(out);  // prunes to max-likelihood first
    else
      ok = tree->write(out);
    out.close();
    ok = ok && out.good();
  }
  if (!ok) throw Error(ErrorCode::kIo, "failed writing '" + path + "' (disk full or I/O error)");
  std::optional<TemporaryFile> stamps_tmp;
  if (with_stamps) {
    stamps_tmp.emplace(temporaryName(stamps_path));
    if (!writeBytes(stamps_tmp->path(), stamps_path, stamps))
      throw Error(ErrorCode::kIo, "failed writing '" + stamps_path + "' (disk full or I/O error)");
  }
  if (std::rename(tmp.path().c_str(), path.c_str()) != 0)
    throw Error(ErrorCode::kIo, "cannot write '" + path + "': " + std::strerror(errno));
  tmp.keep();
  // After the map: a sidecar left from before then names another tree, which the reader refuses.
  if (stamps_tmp) {
    if (std::rename(stamps_tmp->path().c_str(), stamps_path.c_str()) != 0)
      throw Error(ErrorCode::kIo, "wrote '" + path + "' but not its stamps '" + stamps_path +
                                      "': " + std::strerror(errno) + "; write the map again");
    stamps_tmp->keep();
  }
}

// Gives a stamped tree read from `path` the stamps of `path`.stamps where that file exists.
void readStampsBeside(const std::string& path, HostTree& host) {
  const std::string stamps_path = path + ".stamps";
  std::error_code ec;
  const auto st = std::filesystem::status(stamps_path, ec);
  if (!std::filesystem::exists(st)) return;  // written by OctoMap: no stamps, all 0
  if (!std::filesystem::is_regular_file(st))
    throw Error(ErrorCode::kIo, "cannot read '" + stamps_path +
                                    "': it is not a regular file; remove it, or give a stamps "
                                    "file written by octovk");
  std::ifstream in(stamps_path, std::ios_base::binary);
  if (!in.is_open())
    throw Error(ErrorCode::kIo, "cannot read '" + stamps_path + "': " + std::strerror(errno));
  const std::uintmax_t size = std::filesystem::file_size(stamps_path, ec);
  if (ec) throw Error(ErrorCode::kIo, "cannot read '" + stamps_path + "': " + ec.message());
  io::ByteSource source(in, size, stamps_path);
  io::applyStampsFile(source, host, stamps_path);
}

MapFileContents readTreeFile(const std::string& path) {
  const std::string ext = extensionOf(path);
  if (ext != ".bt" && ext != ".ot")
    throw Error(ErrorCode::kInvalidArgument, "cannot read '" + path + "': unknown extension '" +
                                                 ext + "'; use a .bt or .ot file");
  // A directory, or a device or pipe (a link to /dev/zero would be read without end).
  std::error_code ec;
  if (const auto st = std::filesystem::status(path, ec);
      std::filesystem::exists(st) && !std::filesystem::is_regular_file(st))
    throw Error(ErrorCode::kIo,
                "cannot read '" + path + "': it is not a regular file; give a map file");
  std::ifstream in(path, std::ios_base::binary);
  if (!in.is_open())
    throw Error(ErrorCode::kIo, "cannot read '" + path + "': " + std::strerror(errno));
  const std::uintmax_t size = std::filesystem::file_size(path, ec);
  if (ec) throw Error(ErrorCode::kIo, "cannot read '" + path + "': " + ec.message());
  // Read as the checks go (see tree_file.cpp): memory follows the bytes that pass them, and a
  // damaged or sparse file fails at its first fault, whatever size it claims.
  MapFileContents file;
  MapParams& params = file.params;
  HostTree& host = file.tree;
  {
    io::ByteSource source(in, size, path);
    const io::AnyTree tree = io::parseTreeFile(source, ext == ".bt", path);
    params.resolution = resolutionOf(tree);
    host = io::hostTreeOf(tree);
  }
  if (host.payload == Payload::kStamp && ext == ".ot") readStampsBeside(path, host);
  params.payload = host.payload;
  return file;
}

}  // namespace

std::size_t writeMapStream(OccupancyMap& map, std::ostream& out, bool binary, std::string* stamps) {
  return hostMemoryGuard("writeMapStream", [&] {
    const std::unique_ptr<octomap::AbstractOccupancyOcTree> tree =
        treeToWrite(map, binary ? nullptr : stamps);
    if (binary && stamps) stamps->clear();
    if (binary)
      tree->writeBinary(out);  // prunes to max-likelihood first
    else
      tree->write(out);
    return tree->size();
  });
}

void writeMapFile(OccupancyMap& map, const std::string& path) {
  hostMemoryGuard("writeMapFile", [&] { writeTreeFile(map, path); });
}

MapFileContents readMapFileContents(const std::string& path) {
  return hostMemoryGuard("readMapFileContents", [&] { return readTreeFile(path); });
}

OccupancyMap readMapFile(Context& context, const std::string& path, std::size_t max_device_bytes) {
  return hostMemoryGuard("readMapFile", [&] {
    MapFileContents file = readTreeFile(path);
    file.params.max_device_bytes = max_device_bytes;
    OccupancyMap map(context, file.params);
    map.upload(file.tree);
    return map;
  });
}

namespace {

MapMessage messageOf(OccupancyMap& map, bool binary) {
  return hostMemoryGuard(binary ? "binaryMapToMessage" : "fullMapToMessage", [&] {
    const std::unique_ptr<octomap::AbstractOccupancyOcTree> tree =
        io::octomapTreeOf(map.download(), map.params());
    std::ostringstream out(std::ios_base::binary);
    if (binary)
      tree->writeBinaryData(out);
    else
      tree->writeData(out);
    if (!out) throw Error(ErrorCode::kInternal, "OctoMap could not write the message body");
    const std::string bytes = std::move(out).str();
    MapMessage message;
    message.id = tree->getTreeType();
    message.resolution = tree->getResolution();
    message.binary = binary;
    message.data.resize(bytes.size());
    if (!bytes.empty()) std::memcpy(message.data.data(), bytes.data(), bytes.size());
    return message;
  });
}

// A message body as a host tree of its type (checked), and its resolution.
HostTree treeOf(const MapMessage& message, const std::string& name, double& resolution) {
  return hostMemoryGuard("messageToMap", [&] {
    const std::string_view body(reinterpret_cast<const char*>(message.data.data()),
                                message.data.size());
    const io::AnyTree tree =
        io::parseTreeBody(body, message.binary, message.id, message.resolution, name);
    resolution = resolutionOf(tree);
    return io::hostTreeOf(tree);
  });
}

}  // namespace

MapMessage binaryMapToMessage(OccupancyMap& map) { return messageOf(map, true); }

MapMessage fullMapToMessage(OccupancyMap& map) { return messageOf(map, false); }

OccupancyMap messageToMap(Context& context, const MapMessage& message, std::size_t max_device_bytes,
                          const std::string& name) {
  MapParams params;
  const HostTree host = treeOf(message, name, params.resolution);
  params.payload = host.payload;
  params.max_device_bytes = max_device_bytes;
  OccupancyMap map(context, params);
  hostMemoryGuard("messageToMap", [&] { map.upload(host); });
  return map;
}

void messageToMap(OccupancyMap& map, const MapMessage& message, const std::string& name) {
  double resolution = 0.0;
  const HostTree host = treeOf(message, name, resolution);
  if (resolution != map.params().resolution)
    throw Error(ErrorCode::kInvalidArgument,
                "messageToMap: '" + name + "' has resolution " + std::to_string(resolution) +
                    " m, the map " + std::to_string(map.params().resolution) +
                    " m; read it into a new map (messageToMap(context, message)) instead");
  if (host.payload != map.params().payload)
    throw Error(ErrorCode::kInvalidArgument,
                "messageToMap: '" + name + "' holds " + typeWithArticle(host.payload) +
                    ", the map is " + typeWithArticle(map.params().payload) +
                    "; read it into a new map (messageToMap(context, message)) instead");
  hostMemoryGuard("messageToMap", [&] { map.upload(host); });
}

}  // namespace octovk
