// OctoMap's own answers to the Python tests' queries, on a map the module wrote as .ot:
//   octovk_py_oracle search MAP.ot POINTS OUT      POINTS: float32 x y z per point
//       OUT per point: uint8 state (0 unknown, 1 free, 2 occupied), float32 log-odds, uint8 depth
//   octovk_py_oracle castray MAP.ot RAYS OUT       RAYS: float32 ox oy oz dx dy dz max_range
//       ignore_unknown (0/1) per ray; OUT per ray: uint8 hit, float32 end x y z
//   octovk_py_oracle leaves MAP.ot MINX MINY MINZ MAXX MAXY MAXZ OCCUPIED_ONLY OUT
//       OUT per leaf of leaf_bbx_iterator: float32 x y z size log-odds
//   octovk_py_oracle colorscan RES average|integrate SCANS QUERIES OUT
//       a ColorOcTree of the scans in SCANS, each insertPointCloud(points, origin) then
//       averageNodeColor (or integrateNodeColor) per point in order, then updateInnerOccupancy;
//   octovk_py_oracle stampscan RES SCANS QUERIES [NOW THRESHOLD] OUT
//       an OcTreeStamped of the scans, every leaf a scan updates stamped with the scan's stamp,
//       then (with NOW) degradeOutdatedNodes(THRESHOLD) at time NOW.
//       SCANS per scan: uint32 n, float32 origin x y z, uint32 stamp, n x (float32 x y z),
//       n x (uint8 r g b); QUERIES: float32 x y z per point. OUT per query: as search's, then
//       uint32 payload (the colour r | g << 8 | b << 16, or the stamp; 0 where no node).
// Records are packed (no padding). Exit status 1 with a message on stderr for a bad input.
#include <octomap/ColorOcTree.h>
#include <octomap/OcTree.h>
#include <octomap/OcTreeStamped.h>

#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <fstream>
#include <iostream>
#include <iterator>
#include <memory>
#include <stdexcept>
#include <string>
#include <vector>

namespace {

std::vector<float> readFloats(const char* path) {
  std::ifstream in(path, std::ios::binary);
  const std::string bytes((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
  std::vector<float> out(bytes.size() / sizeof(float));
  std::memcpy(out.data(), bytes.data(), out.size() * sizeof(float));
  return out;
}

template <class T>
void put(std::string& out, T value) {
  out.append(reinterpret_cast<const char*>(&value), sizeof(value));
}

// OcTree::search(key) with the depth of the node found: the leaf on the key's path, or none where
// the path ends at an inner node without the child it needs.
template <class Tree>
const typename Tree::NodeType* deepest(const Tree& tree, const octomap::OcTreeKey& key,
                                       unsigned* depth) {
  const typename Tree::NodeType* node = tree.getRoot();
  *depth = 0;
  if (!node) return nullptr;
  for (int level = 15; level >= 0; --level) {
    const unsigned child = octomap::computeChildIdx(key, level);
    if (!tree.nodeChildExists(node, child)) return tree.nodeHasChildren(node) ? nullptr : node;
    node = tree.getNodeChild(node, child);
    ++*depth;
  }
  return node;
}

struct Scan {
  octomap::Pointcloud points;
  std::vector<std::uint8_t> colors;  // r, g, b per point
  octomap::point3d origin;
  unsigned stamp = 0;
};

std::vector<Scan> readScans(const char* path) {
  std::ifstream in(path, std::ios::binary);
  const std::string bytes((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
  std::vector<Scan> scans;
  std::size_t at = 0;
  auto take = [&](void* to, std::size_t n) {
    if (at + n > bytes.size()) throw std::runtime_error("SCANS ends inside a scan");
    std::memcpy(to, bytes.data() + at, n);
    at += n;
  };
  while (at < bytes.size()) {
    Scan scan;
    std::uint32_t n = 0;
    float o[3];
    take(&n, sizeof n);
    take(o, sizeof o);
    take(&scan.stamp, sizeof scan.stamp);
    scan.origin = octomap::point3d(o[0], o[1], o[2]);
    std::vector<float> p(3 * std::size_t{n});
    take(p.data(), p.size() * sizeof(float));
    for (std::size_t i = 0; i < n; ++i) scan.points.push_back(p[3 * i], p[3 * i + 1], p[3 * i + 2]);
    scan.colors.resize(3 * std::size_t{n});
    take(scan.colors.data(), scan.colors.size());
    scans.push_back(std::move(scan));
  }
  return scans;
}

// OcTreeStamped at a chosen time: every node updateNodeLogOdds updates takes `now` instead of
// time(NULL), as octovk's scans take their stamp.
class StampedAt : public octomap::OcTreeStamped {
 public:
  explicit StampedAt(double resolution) : OcTreeStamped(resolution) {}
  void updateNodeLogOdds(octomap::OcTreeNodeStamped* node, const float& update) const override {
    OccupancyOcTreeBase<octomap::OcTreeNodeStamped>::updateNodeLogOdds(node, update);
    node->setTimestamp(now);
  }
  unsigned now = 0;
};

// search() for each query, with the found node's payload.
template <class Tree, class Payload>
std::string searchWithPayload(const Tree& tree, const std::vector<float>& p, Payload payload) {
  std::string out;
  for (std::size_t i = 0; i + 3 <= p.size(); i += 3) {
    octomap::OcTreeKey key;
    unsigned depth = 0;
    const bool inside = tree.coordToKeyChecked(octomap::point3d(p[i], p[i + 1], p[i + 2]), key);
    const auto* node = inside ? deepest(tree, key, &depth) : nullptr;
    put<std::uint8_t>(out, !node ? 0 : tree.isNodeOccupied(node) ? 2 : 1);
    put<float>(out, node ? node->getLogOdds() : 0.0f);
    put<std::uint8_t>(out, static_cast<std::uint8_t>(node ? depth : 0));
    put<std::uint32_t>(out, node ? payload(*node) : 0u);
  }
  return out;
}

bool writeOut(const char* path, const std::string& out) {
  std::ofstream file(path, std::ios::binary | std::ios::trunc);
  file.write(out.data(), static_cast<std::streamsize>(out.size()));
  return static_cast<bool>(file);
}

// The colorscan and stampscan commands (argv as main's).
int payloadScan(int argc, char** argv) {
  const std::string command = argv[1];
  const double resolution = std::strtod(argv[2], nullptr);
  if (command == "colorscan" && argc == 7) {
    const bool integrate = std::string(argv[3]) == "integrate";
    octomap::ColorOcTree tree(resolution);
    for (const Scan& scan : readScans(argv[4])) {
      tree.insertPointCloud(scan.points, scan.origin, -1.0, false, false);
      for (std::size_t i = 0; i < scan.points.size(); ++i) {
        const octomap::point3d& q = scan.points[i];
        const std::uint8_t* c = &scan.colors[3 * i];
        if (integrate)
          tree.integrateNodeColor(q.x(), q.y(), q.z(), c[0], c[1], c[2]);
        else
          tree.averageNodeColor(q.x(), q.y(), q.z(), c[0], c[1], c[2]);
      }
    }
    tree.updateInnerOccupancy();
    const auto packed = [](const octomap::ColorOcTreeNode& n) {
      const octomap::ColorOcTreeNode::Color c = n.getColor();
      return std::uint32_t{c.r} | (std::uint32_t{c.g} << 8) | (std::uint32_t{c.b} << 16);
    };
    return writeOut(argv[6], searchWithPayload(tree, readFloats(argv[5]), packed)) ? 0 : 1;
  }
  if (command == "stampscan" && (argc == 6 || argc == 8)) {
    StampedAt tree(resolution);
    for (const Scan& scan : readScans(argv[3])) {
      tree.now = scan.stamp;
      tree.insertPointCloud(scan.points, scan.origin, -1.0, false, false);
    }
    if (argc == 8) {
      // degradeOutdatedNodes with time(NULL) replaced by NOW.
      const auto now = static_cast<unsigned>(std::strtoul(argv[5], nullptr, 10));
      const auto threshold = static_cast<unsigned>(std::strtoul(argv[6], nullptr, 10));
      for (auto it = tree.begin_leafs(), end = tree.end_leafs(); it != end; ++it)
        if (tree.isNodeOccupied(*it) && (now - it->getTimestamp()) > threshold)
          tree.integrateMissNoTime(&*it);
      tree.updateInnerOccupancy();
    }
    const auto stamp = [](const octomap::OcTreeNodeStamped& n) {
      return std::uint32_t{n.getTimestamp()};
    };
    return writeOut(argv[argc - 1], searchWithPayload(tree, readFloats(argv[4]), stamp)) ? 0 : 1;
  }
  std::cerr << "octovk_py_oracle: wrong arguments for " << command << "\n";
  return 1;
}

}  // namespace

int main(int argc, char** argv) {
  if (argc < 5) {
    std::cerr << "usage: octovk_py_oracle search|castray|leaves MAP.ot ... OUT, or "
                 "colorscan|stampscan RES ... OUT\n";
    return 1;
  }
  const std::string command = argv[1];
  if (command == "colorscan" || command == "stampscan") {
    try {
      return payloadScan(argc, argv);
    } catch (const std::exception& e) {
      std::cerr << "octovk_py_oracle: " << e.what() << "\n";
      return 1;
    }
  }
  std::unique_ptr<octomap::AbstractOcTree> read(octomap::AbstractOcTree::read(argv[2]));
  auto* tree = dynamic_cast<octomap::OcTree*>(read.get());
  if (!tree) {
    std::cerr << "octovk_py_oracle: cannot read " << argv[2] << " as an OcTree (.ot)\n";
    return 1;
  }
  std::string out;
  if (command == "search") {
    const std::vector<float> p = readFloats(argv[3]);
    for (std::size_t i = 0; i + 3 <= p.size(); i += 3) {
      octomap::OcTreeKey key;
      unsigned depth = 0;
      const bool inside = tree->coordToKeyChecked(octomap::point3d(p[i], p[i + 1], p[i + 2]), key);
      const octomap::OcTreeNode* node = inside ? deepest(*tree, key, &depth) : nullptr;
      if (inside && node != tree->search(key)) {
        std::cerr << "octovk_py_oracle: own descent differs from OcTree::search\n";
        return 1;
      }
      put<std::uint8_t>(out, !node ? 0 : tree->isNodeOccupied(node) ? 2 : 1);
      put<float>(out, node ? node->getLogOdds() : 0.0f);
      put<std::uint8_t>(out, static_cast<std::uint8_t>(node ? depth : 0));
    }
  } else if (command == "castray") {
    const std::vector<float> r = readFloats(argv[3]);
    for (std::size_t i = 0; i + 8 <= r.size(); i += 8) {
      const octomap::point3d origin(r[i], r[i + 1], r[i + 2]);
      octomap::point3d end = origin;  // where OctoMap leaves `end` untouched: the origin
      const bool hit = tree->castRay(origin, octomap::point3d(r[i + 3], r[i + 4], r[i + 5]), end,
                                     r[i + 7] != 0.0f, r[i + 6]);
      put<std::uint8_t>(out, hit ? 1 : 0);
      for (int k = 0; k < 3; ++k) put<float>(out, end(k));
    }
  } else if (command == "leaves" && argc == 11) {
    const octomap::point3d lo(std::strtof(argv[3], nullptr), std::strtof(argv[4], nullptr),
                              std::strtof(argv[5], nullptr));
    const octomap::point3d hi(std::strtof(argv[6], nullptr), std::strtof(argv[7], nullptr),
                              std::strtof(argv[8], nullptr));
    const bool occupied_only = std::string(argv[9]) == "1";
    for (auto it = tree->begin_leafs_bbx(lo, hi), end = tree->end_leafs_bbx(); it != end; ++it) {
      if (occupied_only && !tree->isNodeOccupied(*it)) continue;
      const octomap::point3d c = it.getCoordinate();
      for (float v : {c.x(), c.y(), c.z(), static_cast<float>(it.getSize()), it->getLogOdds()})
        put<float>(out, v);
    }
  } else {
    std::cerr << "octovk_py_oracle: unknown command or wrong arguments: " << command << "\n";
    return 1;
  }
  std::ofstream file(argv[argc - 1], std::ios::binary | std::ios::trunc);
  file.write(out.data(), static_cast<std::streamsize>(out.size()));
  return file ? 0 : 1;
}
