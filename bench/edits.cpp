// The edits workload: map surgery on the paper map at 0.05 m against OctoMap's loops on the same
// tree. Clearing a box: OctoMap's leaf_bbx_iterator setting every leaf to the lower clamping bound,
// then updateInnerOccupancy (octomap_server's clear_bbx), against OccupancyMap::clearBox. Keeping
// a box: OctoMap has no working in-place cut (deleteNode aborts in Debian's build when a deletion
// empties a parent, see tests/octomap_keep_box.hpp), so its side is the rebuild the oracle tests
// use: the leaves leaf_bbx_iterator visits set at their depths in a fresh OcTree, then
// updateInnerOccupancy, and the old tree deleted; against OccupancyMap::keepBox. Every result is
// compared node for node with OctoMap's (operator==); the bench reports, it never asserts on time.
#include <octomap/OcTree.h>

#include <algorithm>
#include <chrono>
#include <cstdio>
#include <memory>
#include <string>
#include <vector>

#include "building.hpp"
#include "measure.hpp"
#include "octomap_keep_box.hpp"
#include "octovk/octomap_io.hpp"
#include "workload_common.hpp"
#include "workloads.hpp"

namespace octovk::bench {

namespace {

constexpr double kResolution = 0.05;

double msSince(Clock::time_point start) {
  return std::chrono::duration<double, std::milli>(Clock::now() - start).count();
}

struct EditBox {
  std::string name;
  Eigen::Vector3f lo, hi;
};

octomap::point3d toPoint(const Eigen::Vector3f& v) { return octomap::point3d(v.x(), v.y(), v.z()); }

}  // namespace

void runEdits(Context& context, const BenchOptions& o, JsonWriter& json) {
  const Building building;
  const std::vector<SensorPose> views = paperViews();
  octomap::OcTree tree(kResolution);
  MapParams params;
  params.resolution = kResolution;
  {
    OccupancyMap map(context, params);
    for (std::size_t i = 0; i < views.size(); ++i) {
      progress("edits: view %zu/%zu\n", i + 1, views.size());
      const std::vector<Eigen::Vector3f> cloud =
          rangeImage(building, views[i], kPaperWidth, kPaperHeight);
      measureWorldScan(tree, map, cloud, views[i].position.cast<float>(), -1.0, false);
    }
  }
  const Box bounds = building.bounds();
  const Eigen::Vector3f lo = bounds.lo.cast<float>(), hi = bounds.hi.cast<float>();
  const Eigen::Vector3f at = views.front().position.cast<float>();
  const Eigen::Vector3f mid = 0.5f * (lo + hi);
  const std::vector<EditBox> boxes = {
      {"2 m cube at view 1", at - Eigen::Vector3f(1, 1, 1), at + Eigen::Vector3f(1, 1, 1)},
      {"10 x 10 x 4 m window at view 1", at - Eigen::Vector3f(5, 5, 2),
       at + Eigen::Vector3f(5, 5, 2)},
      {"half the building (x below the middle)", lo, Eigen::Vector3f(mid.x(), hi.y(), hi.z())},
      {"the building's bounds", lo, hi}};

  std::printf("\n## edits: clearBox and keepBox on the paper map at %g m\n", kResolution);
  std::printf(
      "\nThe paper map (six views) in both systems: %zu nodes, %zu leaves. Each edit starts from "
      "that map (OctoMap: a copy of the tree; octovk: a map uploaded from it, neither timed), "
      "median of %d. Clear: OctoMap's leaf_bbx_iterator loop setting getClampingThresMinLog(), "
      "then updateInnerOccupancy(); octovk's clearBox(). Keep: OctoMap rebuilt from "
      "leaf_bbx_iterator's leaves at their depths, updateInnerOccupancy(), the old tree deleted "
      "(no in-place cut of OctoMap works, see tests/octomap_keep_box.hpp); octovk's keepBox(). "
      "Wall times of the calls (octovk's include recording, submission and the wait); every "
      "result equal to OctoMap's node for node.\n\n",
      tree.size(), tree.getNumLeafNodes(), o.repeat);
  std::printf(
      "| box | leaves in it | OctoMap clear ms | octovk clear ms | speed-up | OctoMap keep ms | "
      "octovk keep ms | speed-up | nodes kept |\n|---|---|---|---|---|---|---|---|---|\n");
  json.key("edits").beginObject();
  json.field("nodes", tree.size()).field("leaves", tree.getNumLeafNodes());
  json.key("boxes").beginArray();
  OccupancyMap map(context, params);
  for (const EditBox& b : boxes) {
    progress("edits: %s\n", b.name.c_str());
    std::vector<double> om_clear, vk_clear, om_keep, vk_keep;
    std::size_t leaves = 0, kept_nodes = 0;
    bool equal = true;
    for (auto it = tree.begin_leafs_bbx(toPoint(b.lo), toPoint(b.hi)); it != tree.end_leafs_bbx();
         ++it)
      ++leaves;
    for (int rep = 0; rep < std::max(1, o.repeat); ++rep) {
      {
        octomap::OcTree copy(tree);
        auto t0 = Clock::now();
        for (auto it = copy.begin_leafs_bbx(toPoint(b.lo), toPoint(b.hi)),
                  end = copy.end_leafs_bbx();
             it != end; ++it)
          it->setLogOdds(copy.getClampingThresMinLog());
        copy.updateInnerOccupancy();
        om_clear.push_back(msSince(t0));
        fromOcTree(map, tree);
        t0 = Clock::now();
        map.clearBox(b.lo, b.hi);
        vk_clear.push_back(msSince(t0));
        equal = equal && copy == *toOcTree(map);
      }
      {
        auto copy = std::make_unique<octomap::OcTree>(tree);
        auto t0 = Clock::now();
        std::unique_ptr<octomap::OcTree> kept =
            test::octomapKeepBox(*copy, toPoint(b.lo), toPoint(b.hi));
        copy.reset();
        om_keep.push_back(msSince(t0));
        fromOcTree(map, tree);
        t0 = Clock::now();
        map.keepBox(b.lo, b.hi);
        vk_keep.push_back(msSince(t0));
        equal = equal && *kept == *toOcTree(map) && map.nodeCount() == kept->size();
        kept_nodes = kept->size();
      }
    }
    const double oc = median(om_clear), vc = median(vk_clear), ok = median(om_keep),
                 vkk = median(vk_keep);
    std::printf("| %s | %zu | %.1f | %.1f | %.1fx | %.1f | %.1f | %.1fx | %zu |\n", b.name.c_str(),
                leaves, oc, vc, oc / vc, ok, vkk, ok / vkk, kept_nodes);
    json.beginObject();
    json.field("box", b.name).field("leaves", leaves).field("kept_nodes", kept_nodes);
    json.field("octomap_clear_ms", oc).field("octovk_clear_ms", vc);
    json.field("octomap_keep_ms", ok).field("octovk_keep_ms", vkk);
    json.field("equal", equal);
    json.endObject();
    if (!equal) std::printf("\n**%s: octovk's tree differs from OctoMap's.**\n", b.name.c_str());
  }
  json.endArray();
  json.endObject();
}

}  // namespace octovk::bench
