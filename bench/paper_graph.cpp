// Writes the paper workload's six 320x240 views of the synthetic building (bench/building.hpp) as
// an OctoMap scan graph, so that the building can be mapped by the program and by graph2tree
// (bench/capped_pairs.sh): each view's points in its sensor frame, the node's pose the sensor's
// position (no rotation).
#include <octomap/octomap.h>

#include <cstdio>
#include <exception>

#include "building.hpp"

int main(int argc, char** argv) {
  if (argc != 2) {
    std::fprintf(stderr, "usage: octovk_paper_graph OUT.graph\n");
    return 2;
  }
  try {
    const octovk::bench::Building building;
    octomap::ScanGraph graph;
    for (const octovk::bench::SensorPose& view : octovk::bench::paperViews()) {
      const auto points = octovk::bench::rangeImage(building, view, 320, 240);
      const Eigen::Vector3f at = view.position.cast<float>();
      auto* cloud = new octomap::Pointcloud();
      cloud->reserve(points.size());
      for (const Eigen::Vector3f& p : points)
        cloud->push_back(p.x() - at.x(), p.y() - at.y(), p.z() - at.z());
      graph.addNode(cloud, octomap::pose6d(at.x(), at.y(), at.z(), 0.0, 0.0, 0.0));
    }
    if (!graph.writeBinary(argv[1])) {
      std::fprintf(stderr, "octovk_paper_graph: cannot write %s\n", argv[1]);
      return 1;
    }
  } catch (const std::exception& e) {
    std::fprintf(stderr, "octovk_paper_graph: %s\n", e.what());
    return 1;
  }
  return 0;
}
