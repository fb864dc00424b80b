// The map as an octomap::OcTree and OctoMap's .bt / .ot files.
#include "octovk/octomap_io.hpp"

#include <octomap/AbstractOcTree.h>
#include <unistd.h>

#include <cerrno>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <functional>
#include <iterator>
#include <vector>

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

// OctoMap's own header reader (protected in AbstractOcTree).
struct HeaderReader : octomap::AbstractOcTree {
  using octomap::AbstractOcTree::readHeader;
};

// OctoMap reads a tree's node records recursively, trusting every child flag, without checking
// the stream: past the end of a truncated file it tests a flag byte it never read (uninitialized;
// AddressSanitizer saw it recurse until the stack overflowed), and a corrupt file can nest deeper
// than a tree's 16 levels. So the header is read as OctoMap reads it, and the node records after
// it are walked here first, without recursion: true if they hold one whole tree OctoMap can read.
// .bt (binary): a record per inner node, 2 bytes of 2 bits per child (11: an inner child, whose
// record follows). .ot: a record per node, its float log-odds and a byte with a bit per child.
bool treeDataIsWhole(std::istream& in, bool binary) {
  std::string line, id;
  unsigned size = 0;
  double res = 0.0;
  std::getline(in, line);  // the file type, checked by the caller
  if (!HeaderReader::readHeader(in, id, size, res)) return false;
  if (!binary && id != "OcTree") return false;  // another node type, another record
  if (size == 0) return true;                   // OctoMap reads no record
  const std::string data{std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>()};
  struct Open {
    unsigned depth;
    unsigned children;  // a bit per child whose record is still to come
  };
  std::vector<Open> open;
  std::size_t at = 0;
  const auto byte = [&](std::size_t i) { return static_cast<unsigned char>(data[i]); };
  const auto record = [&](unsigned depth) {
    if (binary) {  // only inner nodes have one, and they lie above depth 16
      if (depth >= 16 || data.size() - at < 2) return false;
      unsigned inner = 0;
      for (unsigned i = 0; i < 8; ++i)
        if (((byte(at + i / 4) >> (2 * (i % 4))) & 3u) == 3u) inner |= 1u << i;
      open.push_back({depth, inner});
      at += 2;
    } else {
      const std::size_t bytes = sizeof(float) + 1;
      if (data.size() - at < bytes || (depth == 16 && byte(at + bytes - 1) != 0)) return false;
      open.push_back({depth, byte(at + bytes - 1)});
      at += bytes;
    }
    return true;
  };
  if (!record(0)) return false;
  while (!open.empty()) {
    if (open.back().children == 0) {
      open.pop_back();
      continue;
    }
    open.back().children &= open.back().children - 1;  // the lowest child's record is next
    if (!record(open.back().depth + 1)) return false;
  }
  return true;
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

}  // namespace

std::unique_ptr<octomap::OcTree> toOcTree(const OccupancyMap& map) {
  const HostTree host = map.download();
  auto tree = std::make_unique<TreeBuilder>(map.params().resolution);
  applyParams(*tree, map.params());
  if (!host.root_exists) return tree;
  std::function<void(std::uint32_t, octomap::OcTreeNode*, unsigned)> build =
      [&](std::uint32_t index, octomap::OcTreeNode* node, unsigned depth) {
        const HostTree::Node& n = host.nodes.at(index);
        node->setLogOdds(n.log_odds);
        if (depth >= 16) return;
        for (unsigned i = 0; i < 8; ++i) {
          if (!(n.mask & (1u << i))) continue;
          build(n.children * 8 + i, tree->createNodeChild(node, i), depth + 1);
        }
      };
  build(0, tree->makeRoot(), 0);
  return tree;
}

void fromOcTree(OccupancyMap& map, const octomap::OcTree& tree) {
  if (tree.getResolution() != map.params().resolution)
    throw Error(ErrorCode::kInvalidArgument,
                "fromOcTree: the tree's resolution " + std::to_string(tree.getResolution()) +
                    " differs from the map's " + std::to_string(map.params().resolution));
  HostTree host;
  const octomap::OcTreeNode* root = tree.getRoot();
  host.root_exists = root != nullptr;
  if (root) {
    host.nodes.resize(8);
    host.nodes[0] = {root->getLogOdds(), 0xFFFFFFFFu, 0};
    // Breadth first: each node with children gets the next block of 8 slots.
    std::vector<std::pair<const octomap::OcTreeNode*, std::uint32_t>> queue{{root, 0}};
    for (std::size_t head = 0; head < queue.size(); ++head) {
      const auto [node, index] = queue[head];
      if (!tree.nodeHasChildren(node)) continue;
      const std::uint32_t block = static_cast<std::uint32_t>(host.nodes.size() / 8);
      host.nodes.resize(host.nodes.size() + 8, HostTree::Node{0.0f, 0xFFFFFFFFu, 0});
      std::uint32_t mask = 0;
      for (unsigned i = 0; i < 8; ++i) {
        if (!tree.nodeChildExists(node, i)) continue;
        const octomap::OcTreeNode* child = tree.getNodeChild(node, i);
        host.nodes[block * 8 + i] = {child->getLogOdds(), 0xFFFFFFFFu, 0};
        queue.emplace_back(child, block * 8 + i);
        mask |= 1u << i;
      }
      host.nodes[index].children = block;
      host.nodes[index].mask = mask;
    }
  }
  map.upload(host);
}

void writeMapFile(const OccupancyMap& map, const std::string& path) {
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
  std::unique_ptr<octomap::OcTree> tree = toOcTree(map);
  const std::string tmp = path + ".tmp-" + std::to_string(::getpid());
  bool ok = false;
  {
    std::ofstream out(tmp, std::ios_base::binary);
    if (!out.is_open())
      throw Error(ErrorCode::kIo, "cannot write '" + path + "': " + std::strerror(errno));
    if (ext == ".bt")
      ok = tree->writeBinary(out);  // prunes to max-likelihood first
    else
      ok = tree->write(out);
    out.close();
    ok = ok && out.good();
  }
  if (!ok) {
    std::remove(tmp.c_str());
    throw Error(ErrorCode::kIo, "failed writing '" + path + "' (disk full or I/O error)");
  }
  if (std::rename(tmp.c_str(), path.c_str()) != 0) {
    const std::string why = std::strerror(errno);
    std::remove(tmp.c_str());
    throw Error(ErrorCode::kIo, "cannot write '" + path + "': " + why);
  }
}

OccupancyMap readMapFile(Context& context, const std::string& path) {
  const std::string ext = extensionOf(path);
  if (ext != ".bt" && ext != ".ot")
    throw Error(ErrorCode::kInvalidArgument, "cannot read '" + path + "': unknown extension '" +
                                                 ext + "'; use a .bt or .ot file");
  std::ifstream in(path, std::ios_base::binary);
  if (!in.is_open())
    throw Error(ErrorCode::kIo, "cannot read '" + path + "': " + std::strerror(errno));
  std::string first_line;
  std::getline(in, first_line);
  in.seekg(0);
  std::unique_ptr<octomap::OcTree> tree;
  if (ext == ".bt") {
    if (first_line.rfind("# Octomap OcTree binary file", 0) != 0)
      throw Error(ErrorCode::kFormat,
                  "'" + path + "' is not an OctoMap binary tree (.bt): bad header");
    if (!treeDataIsWhole(in, true))
      throw Error(ErrorCode::kFormat, "'" + path + "' is a corrupt or truncated .bt file");
    in.clear();
    in.seekg(0);
    tree = std::make_unique<octomap::OcTree>(0.1);
    if (!tree->readBinary(in) || tree->getResolution() <= 0.0)
      throw Error(ErrorCode::kFormat, "'" + path + "' is a corrupt or truncated .bt file");
  } else {
    if (first_line.rfind("# Octomap OcTree file", 0) != 0)
      throw Error(ErrorCode::kFormat, "'" + path + "' is not an OctoMap tree (.ot): bad header");
    // The header's node count: OctoMap's reader does not compare it with what it read.
    std::size_t header_size = 0;
    bool has_size = false;
    for (std::string line; std::getline(in, line) && line.rfind("data", 0) != 0;) {
      if (line.rfind("size ", 0) == 0) {
        header_size = std::strtoull(line.c_str() + 5, nullptr, 10);
        has_size = true;
      }
    }
    in.clear();
    in.seekg(0);
    if (!treeDataIsWhole(in, false))
      throw Error(ErrorCode::kFormat, "'" + path +
                                          "' is a truncated or corrupt .ot file, or holds another "
                                          "tree type than OcTree");
    in.clear();
    in.seekg(0);
    std::unique_ptr<octomap::AbstractOcTree> abstract(octomap::AbstractOcTree::read(in));
    auto* as_tree = dynamic_cast<octomap::OcTree*>(abstract.get());
    if (!as_tree)
      throw Error(ErrorCode::kFormat,
                  "'" + path + "' is a corrupt .ot file or holds another tree type than OcTree");
    abstract.release();
    tree.reset(as_tree);
    if (in.fail() || !has_size || tree->size() != header_size)
      throw Error(ErrorCode::kFormat, "'" + path +
                                          "' is a truncated or corrupt .ot file: its header "
                                          "announces " +
                                          std::to_string(header_size) + " nodes, the data holds " +
                                          std::to_string(tree->size()));
  }
  if (in.bad())
    throw Error(ErrorCode::kFormat, "'" + path + "' is a corrupt or truncated OctoMap file");
  MapParams params;
  params.resolution = tree->getResolution();
  OccupancyMap map(context, params);
  fromOcTree(map, *tree);
  return map;
}

}  // namespace octovk
