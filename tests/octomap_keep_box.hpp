// OctoMap keeping only a box, for the keepBox oracle tests and the bench. OctoMap's own
// deleteNode cannot do it: in Debian's build it aborts (`Assertion 'children == NULL'`) as soon
// as a deletion empties a parent, because deleteNodeChild frees an inner node with plain
// `delete`. So the cut tree is written from the leaf iterator: the leaves begin_leafs_bbx visits
// for the box, set at their depths in a fresh OcTree with the same parameters and changed keys
// (deleteNode leaves those alone), then updateInnerOccupancy (no pruning). OctoMap only.
#pragma once

#include <octomap/OcTree.h>

#include <memory>

namespace octovk::test {

/// An OcTree built leaf by leaf at any depth.
class LeafBuiltTree : public octomap::OcTree {
 public:
  /// Empty, with `like`'s resolution, sensor model, clamping, threshold and changed keys.
  explicit LeafBuiltTree(const octomap::OcTree& like) : octomap::OcTree(like.getResolution()) {
    clamping_thres_min = like.getClampingThresMinLog();
    clamping_thres_max = like.getClampingThresMaxLog();
    prob_hit_log = like.getProbHitLog();
    prob_miss_log = like.getProbMissLog();
    occ_prob_thres_log = like.getOccupancyThresLog();
    enableChangeDetection(like.isChangeDetectionEnabled());
    for (auto it = like.changedKeysBegin(); it != like.changedKeysEnd(); ++it)
      changed_keys.insert(*it);
  }

  /// The node at `depth` on `key`'s path, created with the nodes above it, gets `log_odds`.
  void setLeaf(const octomap::OcTreeKey& key, unsigned depth, float log_odds) {
    if (!root) {
      root = new octomap::OcTreeNode();
      ++tree_size;
    }
    octomap::OcTreeNode* n = root;
    for (unsigned d = 0; d < depth; ++d) {
      const unsigned i = octomap::computeChildIdx(key, static_cast<int>(tree_depth - 1 - d));
      n = nodeChildExists(n, i) ? getNodeChild(n, i) : createNodeChild(n, i);
    }
    n->setLogOdds(log_odds);
  }
};

/// `tree` with only the box [min, max] kept (see the top of the file). A corner outside the key
/// range keeps nothing: the iterator's constructor means to be the end iterator then ("coordinates
/// invalid, set to end iterator"), but 1.9.7 leaves the root on its stack, so it compares unequal
/// to end_leafs_bbx() and yields the root once, inner node or not; that root is not kept.
inline std::unique_ptr<octomap::OcTree> octomapKeepBox(const octomap::OcTree& tree,
                                                       const octomap::point3d& min,
                                                       const octomap::point3d& max) {
  auto kept = std::make_unique<LeafBuiltTree>(tree);
  octomap::OcTreeKey unused;
  if (!tree.coordToKeyChecked(min, unused) || !tree.coordToKeyChecked(max, unused)) return kept;
  for (auto it = tree.begin_leafs_bbx(min, max), end = tree.end_leafs_bbx(); it != end; ++it)
    kept->setLeaf(it.getKey(), it.getDepth(), it->getLogOdds());
  kept->updateInnerOccupancy();
  return kept;
}

}  // namespace octovk::test
