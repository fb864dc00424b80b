// OctoMap's own answers to the Python tests' queries, on a map the module wrote as .ot:
//   octovk_py_oracle search MAP.ot POINTS OUT      POINTS: float32 x y z per point
//       OUT per point: uint8 state (0 unknown, 1 free, 2 occupied), float32 log-odds, uint8 depth
//   octovk_py_oracle castray MAP.ot RAYS OUT       RAYS: float32 ox oy oz dx dy dz max_range
//       ignore_unknown (0/1) per ray; OUT per ray: uint8 hit, float32 end x y z
//   octovk_py_oracle leaves MAP.ot MINX MINY MINZ MAXX MAXY MAXZ OCCUPIED_ONLY OUT
//       OUT per leaf of leaf_bbx_iterator: float32 x y z size log-odds
// Records are packed (no padding). Exit status 1 with a message on stderr for a bad input.
#include <octomap/OcTree.h>

#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <fstream>
#include <iostream>
#include <iterator>
#include <memory>
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
const octomap::OcTreeNode* deepest(const octomap::OcTree& tree, const octomap::OcTreeKey& key,
                                   unsigned* depth) {
  const octomap::OcTreeNode* node = tree.getRoot();
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

}  // namespace

int main(int argc, char** argv) {
  if (argc < 5) {
    std::cerr << "usage: octovk_py_oracle search|castray|leaves MAP.ot ... OUT\n";
    return 1;
  }
  const std::string command = argv[1];
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
