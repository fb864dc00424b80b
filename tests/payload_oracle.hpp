// OctoMap's ColorOcTree and OcTreeStamped as the oracle of octovk's ColorMap and StampedMap: the
// oracle trees set up like a map, a node-by-node comparison of an OctoMap tree with a downloaded
// HostTree (log-odds bits, shape, colours of all nodes or stamps of leaves), and keepBox written
// leaf by leaf (as tests/octomap_keep_box.hpp does for OcTree, payload included).
#pragma once

#include <octomap/ColorOcTree.h>
#include <octomap/OcTreeStamped.h>

#include <cstdint>
#include <memory>
#include <sstream>
#include <string>
#include <vector>

#include "test_support.hpp"

namespace octovk::test {

/// `tree` with the map's sensor model, clamping and threshold.
template <class Tree>
void setSensorModel(Tree& tree, const MapParams& p) {
  tree.setProbHit(p.prob_hit);
  tree.setProbMiss(p.prob_miss);
  tree.setClampingThresMin(p.clamping_min);
  tree.setClampingThresMax(p.clamping_max);
  tree.setOccupancyThres(p.occupancy_threshold);
}

inline std::unique_ptr<octomap::ColorOcTree> makeColorOracle(const MapParams& p) {
  auto tree = std::make_unique<octomap::ColorOcTree>(p.resolution);
  setSensorModel(*tree, p);
  return tree;
}

/// OcTreeStamped whose updates stamp the scan's time (setScanTime) instead of time(NULL): the
/// virtual updateNodeLogOdds does the base update, then sets the stamp, as OcTreeStamped's own
/// does with time(NULL). Inner nodes still take time(NULL); no leaf depends on them.
class StampedOracle : public octomap::OcTreeStamped {
 public:
  explicit StampedOracle(const MapParams& p) : octomap::OcTreeStamped(p.resolution) {
    setSensorModel(*this, p);
  }
  explicit StampedOracle(double resolution) : octomap::OcTreeStamped(resolution) {}
  void setScanTime(unsigned int t) { time_ = t; }
  void updateNodeLogOdds(octomap::OcTreeNodeStamped* node, const float& update) const override {
    octomap::OccupancyOcTreeBase<octomap::OcTreeNodeStamped>::updateNodeLogOdds(node, update);
    node->setTimestamp(time_);
  }
  /// degradeOutdatedNodes with query time `now` instead of time(NULL), then updateInnerOccupancy()
  /// (octovk's degradeOutdated leaves the inner nodes consistent).
  void degradeOutdated(unsigned int now, unsigned int threshold) {
    for (auto it = begin_leafs(), end = end_leafs(); it != end; ++it)
      if (isNodeOccupied(*it) && (now - it->getTimestamp()) > threshold) integrateMissNoTime(&*it);
    updateInnerOccupancy();
  }

 private:
  unsigned int time_ = 0;
};

/// A node's payload as octovk packs it (HostTree::Node::payload, Lookup::payload).
inline std::uint32_t payloadOf(const octomap::ColorOcTreeNode& n) {
  const auto c = n.getColor();
  return packRgb(Rgb{c.r, c.g, c.b});
}
inline std::uint32_t payloadOf(const octomap::OcTreeNodeStamped& n) { return n.getTimestamp(); }
inline std::uint32_t payloadOf(const octomap::OcTreeNode&) { return 0; }

inline std::string payloadText(Payload kind, std::uint32_t v) {
  std::ostringstream s;
  if (kind == Payload::kColor) {
    const Rgb c = unpackRgb(v);
    s << "rgb(" << int{c.r} << ", " << int{c.g} << ", " << int{c.b} << ")";
  } else {
    s << v;
  }
  return s.str();
}

/// Compares `expected` (an OctoMap tree) with `actual` (a download()) node by node in OctoMap's
/// child order: presence, leaf or inner, log-odds bits, and the payload (a colour on every node,
/// a stamp on leaves only: inner stamps are time(NULL) in OctoMap). Names the first difference:
/// depth, key, centre, field, OctoMap's value and octovk's.
template <class Tree>
::testing::AssertionResult samePayloadTree(const Tree& expected, const HostTree& actual,
                                           Payload kind) {
  using Node = typename Tree::NodeType;
  if (actual.payload != kind)
    return ::testing::AssertionFailure()
           << "downloaded tree's payload kind is " << treeTypeName(actual.payload) << ", expected "
           << treeTypeName(kind);
  std::ostringstream out;
  std::size_t compared = 0;
  struct Walk {
    const Tree& a;
    const HostTree& b;
    Payload kind;
    std::ostringstream& out;
    std::size_t& compared;
    bool operator()(const Node* x, const HostTree::Node* y, unsigned depth, unsigned kx,
                    unsigned ky, unsigned kz) {
      auto where = [&] {
        out << "node at depth " << depth << " key (" << kx << ", " << ky << ", " << kz
            << ") centre ("
            << a.keyToCoord(octomap::OcTreeKey(static_cast<octomap::key_type>(kx),
                                               static_cast<octomap::key_type>(ky),
                                               static_cast<octomap::key_type>(kz)),
                            depth)
            << ") size " << a.getNodeSize(depth) << ": ";
      };
      if (!x || !y) {
        if (x || y) {
          where();
          out << (x ? "missing in octovk" : "missing in OctoMap");
          return false;
        }
        return true;
      }
      ++compared;
      if (floatBits(x->getLogOdds()) != floatBits(y->log_odds)) {
        where();
        out.precision(9);
        out << "log-odds OctoMap " << x->getLogOdds() << ", octovk " << y->log_odds;
        return false;
      }
      const bool cx = a.nodeHasChildren(x), cy = (y->mask & 0xFFu) != 0;
      if (cx != cy) {
        where();
        out << (cx ? "inner in OctoMap, leaf in octovk" : "leaf in OctoMap, inner in octovk");
        return false;
      }
      // Children first: a wrong inner colour is the average of wrong children, so the deepest
      // difference is the one to name.
      if (depth < 16 && cx && !children(x, y, depth, kx, ky, kz)) return false;
      const bool check_payload = kind == Payload::kColor || (kind == Payload::kStamp && !cx);
      if (check_payload && payloadOf(*x) != y->payload) {
        where();
        out << (kind == Payload::kColor ? "colour" : "stamp") << " OctoMap "
            << payloadText(kind, payloadOf(*x)) << ", octovk " << payloadText(kind, y->payload)
            << " (" << (cx ? "inner" : "leaf") << ", log-odds " << x->getLogOdds() << ")";
        return false;
      }
      return true;
    }
    bool children(const Node* x, const HostTree::Node* y, unsigned depth, unsigned kx, unsigned ky,
                  unsigned kz) {
      auto where = [&] {
        out << "children of the node at depth " << depth << " key (" << kx << ", " << ky << ", "
            << kz << "): ";
      };
      const unsigned bit = 15 - depth;
      for (unsigned i = 0; i < 8; ++i) {
        const Node* xc = a.nodeChildExists(x, i) ? a.getNodeChild(x, i) : nullptr;
        const HostTree::Node* yc = nullptr;
        if (y->mask & (1u << i)) {
          const std::size_t idx = std::size_t{y->children} * 8 + i;
          if (idx >= b.nodes.size()) {
            where();
            out << "child " << i << " index " << idx << " beyond the " << b.nodes.size()
                << " downloaded nodes";
            return false;
          }
          yc = &b.nodes[idx];
        }
        if (!(*this)(xc, yc, depth + 1, kx | ((i & 1u) << bit), ky | (((i >> 1) & 1u) << bit),
                     kz | (((i >> 2) & 1u) << bit)))
          return false;
      }
      return true;
    }
  };
  const HostTree::Node* root =
      actual.root_exists && !actual.nodes.empty() ? &actual.nodes[0] : nullptr;
  Walk walk{expected, actual, kind, out, compared};
  if (!walk(expected.getRoot(), root, 0, 0, 0, 0))
    return ::testing::AssertionFailure() << out.str();
  if (compared != expected.size())
    return ::testing::AssertionFailure()
           << "compared " << compared << " nodes but OctoMap has " << expected.size();
  return ::testing::AssertionSuccess();
}

/// A tree of OctoMap type Tree built leaf by leaf at any depth (payload included).
template <class Tree>
class LeafBuilt : public Tree {
 public:
  using Node = typename Tree::NodeType;
  explicit LeafBuilt(const Tree& like) : Tree(like.getResolution()) {
    this->clamping_thres_min = like.getClampingThresMinLog();
    this->clamping_thres_max = like.getClampingThresMaxLog();
    this->prob_hit_log = like.getProbHitLog();
    this->prob_miss_log = like.getProbMissLog();
    this->occ_prob_thres_log = like.getOccupancyThresLog();
  }
  /// The node at `depth` on `key`'s path, created with the nodes above it, copies `from`'s data.
  void setLeaf(const octomap::OcTreeKey& key, unsigned depth, const Node& from) {
    if (!this->root) {
      this->root = new Node();
      ++this->tree_size;
    }
    Node* n = this->root;
    for (unsigned d = 0; d < depth; ++d) {
      const unsigned i = octomap::computeChildIdx(key, static_cast<int>(this->tree_depth - 1 - d));
      n = this->nodeChildExists(n, i) ? this->getNodeChild(n, i) : this->createNodeChild(n, i);
    }
    n->copyData(from);
  }
};

/// `tree` with only the leaves leaf_bbx_iterator(min, max) visits, payload kept, then
/// updateInnerOccupancy() (see tests/octomap_keep_box.hpp for why not deleteNode).
template <class Tree>
std::unique_ptr<LeafBuilt<Tree>> keepBoxOracle(const Tree& tree, const Eigen::Vector3f& min,
                                               const Eigen::Vector3f& max) {
  auto kept = std::make_unique<LeafBuilt<Tree>>(tree);
  octomap::OcTreeKey unused;
  const octomap::point3d lo(min.x(), min.y(), min.z()), hi(max.x(), max.y(), max.z());
  if (!tree.coordToKeyChecked(lo, unused) || !tree.coordToKeyChecked(hi, unused)) return kept;
  for (auto it = tree.begin_leafs_bbx(lo, hi), end = tree.end_leafs_bbx(); it != end; ++it)
    kept->setLeaf(it.getKey(), it.getDepth(), *it);
  kept->updateInnerOccupancy();
  return kept;
}

/// A deterministic colour of point i of scan s, now and then white (OctoMap's "no colour").
inline Rgb colorOf(std::size_t s, std::size_t i) {
  if ((i * 7 + s) % 23 == 5) return Rgb{};
  return Rgb{static_cast<std::uint8_t>((i * 37 + s * 11) & 0xFF),
             static_cast<std::uint8_t>((i * 101 + s * 53 + 7) & 0xFF),
             static_cast<std::uint8_t>((i * 13 + s * 29 + 200) & 0xFF)};
}

inline std::vector<Rgb> colorsOf(std::size_t s, std::size_t n) {
  std::vector<Rgb> out(n);
  for (std::size_t i = 0; i < n; ++i) out[i] = colorOf(s, i);
  return out;
}

}  // namespace octovk::test
