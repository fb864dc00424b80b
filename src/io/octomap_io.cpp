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
#include <sstream>
#include <vector>

#include "io/parse.hpp"
#include "map/host_memory.hpp"
#include "map/host_tree.hpp"
#include "map/reference.hpp"

namespace octovk {

namespace {

// OcTree with access to the protected root, to build a tree node by node.
class TreeBuilder : public octomap::OcTree {
 public:
  explicit TreeBuilder(double resolution) : octomap::OcTree(resolution) {}
  octomap::OcTreeNode* makeRoot() {
    root = new octomap::OcTreeNode();
    tree_size = 1;
    size_changed = true;
    return root;
  }
};

// A node's data between the host tree and OctoMap's node: the twins of host_tree.hpp's
// accessors, where a payload joins too.
void copyNodeData(const HostTree::Node& from, octomap::OcTreeNode& to) {
  to.setLogOdds(from.log_odds);
}
HostTree::Node hostNodeOf(const octomap::OcTreeNode& from) {
  HostTree::Node n = emptyHostNode();
  n.log_odds = from.getLogOdds();
  return n;
}

std::string extensionOf(const std::string& path) {
  return std::filesystem::path(path).extension().string();
}

void applyParams(octomap::OcTree& tree, const MapParams& p) {
  tree.setProbHit(p.prob_hit);
  tree.setProbMiss(p.prob_miss);
  tree.setClampingThresMin(p.clamping_min);
  tree.setClampingThresMax(p.clamping_max);
  tree.setOccupancyThres(p.occupancy_threshold);
}

std::unique_ptr<octomap::OcTree> buildOcTree(OccupancyMap& map);
HostTree hostTreeOf(const OccupancyMap& map, const octomap::OcTree& tree);

}  // namespace

std::unique_ptr<octomap::OcTree> toOcTree(OccupancyMap& map) {
  return hostMemoryGuard("toOcTree", [&] { return buildOcTree(map); });
}

void fromOcTree(OccupancyMap& map, const octomap::OcTree& tree) {
  hostMemoryGuard("fromOcTree", [&] { map.upload(hostTreeOf(map, tree)); });
}

namespace {

std::unique_ptr<octomap::OcTree> buildOcTree(OccupancyMap& map) {
  const HostTree host = map.download();
  auto tree = std::make_unique<TreeBuilder>(map.params().resolution);
  applyParams(*tree, map.params());
  if (!host.root_exists) return tree;
  std::function<void(std::uint32_t, octomap::OcTreeNode*, unsigned)> build =
      [&](std::uint32_t index, octomap::OcTreeNode* node, unsigned depth) {
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

// The tree in the pool's layout, for OccupancyMap::upload.
HostTree hostTreeOf(const OccupancyMap& map, const octomap::OcTree& tree) {
  if (tree.getResolution() != map.params().resolution)
    throw Error(ErrorCode::kInvalidArgument,
                "fromOcTree: the tree's resolution " + std::to_string(tree.getResolution()) +
                    " differs from the map's " + std::to_string(map.params().resolution));
  HostTree host;
  const octomap::OcTreeNode* root = tree.getRoot();
  host.root_exists = root != nullptr;
  if (root) {
    host.nodes.resize(8);
    host.nodes[0] = hostNodeOf(*root);
    // Breadth first: each node with children gets the next block of 8 slots.
    std::vector<std::pair<const octomap::OcTreeNode*, std::uint32_t>> queue{{root, 0}};
    for (std::size_t head = 0; head < queue.size(); ++head) {
      const auto [node, index] = queue[head];
      if (!tree.nodeHasChildren(node)) continue;
      const std::uint32_t block = static_cast<std::uint32_t>(host.nodes.size() / 8);
      host.nodes.resize(host.nodes.size() + 8, emptyHostNode());
      std::uint32_t mask = 0;
      for (unsigned i = 0; i < 8; ++i) {
        if (!tree.nodeChildExists(node, i)) continue;
        const octomap::OcTreeNode* child = tree.getNodeChild(node, i);
        host.nodes[block * 8 + i] = hostNodeOf(*child);
        queue.emplace_back(child, block * 8 + i);
        mask |= 1u << i;
      }
      host.nodes[index].children = block;
      host.nodes[index].mask = mask;
    }
  }
  return host;
}

}  // namespace

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
  std::unique_ptr<octomap::OcTree> tree = buildOcTree(map);
  // Removed on any way out but the rename, from before it is created: opening the stream can
  // create the file, then fail allocating its buffer.
  TemporaryFile tmp(path + ".tmp-" + std::to_string(::getpid()));
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
  if (std::rename(tmp.path().c_str(), path.c_str()) != 0)
    throw Error(ErrorCode::kIo, "cannot write '" + path + "': " + std::strerror(errno));
  tmp.keep();
}

OccupancyMap readTreeFile(Context& context, const std::string& path, std::size_t max_device_bytes) {
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
  std::unique_ptr<octomap::OcTree> tree;
  {
    io::ByteSource source(in, size, path);
    tree = io::parseTreeFile(source, ext == ".bt", path);
  }
  MapParams params;
  params.resolution = tree->getResolution();
  params.max_device_bytes = max_device_bytes;
  OccupancyMap map(context, params);
  map.upload(hostTreeOf(map, *tree));
  return map;
}

}  // namespace

void writeMapFile(OccupancyMap& map, const std::string& path) {
  hostMemoryGuard("writeMapFile", [&] { writeTreeFile(map, path); });
}

OccupancyMap readMapFile(Context& context, const std::string& path, std::size_t max_device_bytes) {
  return hostMemoryGuard("readMapFile",
                         [&] { return readTreeFile(context, path, max_device_bytes); });
}

namespace {

MapMessage messageOf(OccupancyMap& map, bool binary) {
  return hostMemoryGuard(binary ? "binaryMapToMessage" : "fullMapToMessage", [&] {
    const std::unique_ptr<octomap::OcTree> tree = buildOcTree(map);
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

std::unique_ptr<octomap::OcTree> treeOf(const MapMessage& message, const std::string& name) {
  return hostMemoryGuard("messageToMap", [&] {
    const std::string_view body(reinterpret_cast<const char*>(message.data.data()),
                                message.data.size());
    return io::parseTreeBody(body, message.binary, message.id, message.resolution, name);
  });
}

}  // namespace

MapMessage binaryMapToMessage(OccupancyMap& map) { return messageOf(map, true); }

MapMessage fullMapToMessage(OccupancyMap& map) { return messageOf(map, false); }

OccupancyMap messageToMap(Context& context, const MapMessage& message,
                          std::size_t max_device_bytes, const std::string& name) {
  const std::unique_ptr<octomap::OcTree> tree = treeOf(message, name);
  MapParams params;
  params.resolution = tree->getResolution();
  params.max_device_bytes = max_device_bytes;
  OccupancyMap map(context, params);
  fromOcTree(map, *tree);
  return map;
}

void messageToMap(OccupancyMap& map, const MapMessage& message, const std::string& name) {
  const std::unique_ptr<octomap::OcTree> tree = treeOf(message, name);
  if (tree->getResolution() != map.params().resolution)
    throw Error(ErrorCode::kInvalidArgument,
                "messageToMap: '" + name + "' has resolution " +
                    std::to_string(tree->getResolution()) + " m, the map " +
                    std::to_string(map.params().resolution) +
                    " m; read it into a new map (messageToMap(context, message)) instead");
  fromOcTree(map, *tree);
}

}  // namespace octovk
