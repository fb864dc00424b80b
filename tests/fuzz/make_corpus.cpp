// Writes the fuzz targets' seed corpus with OctoMap's own writers, from tiny maps, into
// DIR/{bt,ot,graph}/: usage: octovk_fuzz_corpus DIR (tests/fuzz/corpus holds its output).
#include <octomap/OcTree.h>
#include <octomap/ScanGraph.h>

#include <cmath>
#include <fstream>
#include <iostream>
#include <limits>
#include <string>

namespace {

// A few occupied and free voxels near the origin: a small tree with nodes on all 16 levels.
octomap::OcTree tinyTree(double resolution, int cells) {
  octomap::OcTree tree(resolution);
  for (int i = 0; i < cells; ++i) {
    const float x = static_cast<float>(resolution * (i % 3));
    const float y = static_cast<float>(resolution * (i / 3));
    tree.updateNode(octomap::point3d(x, y, 0.5f), true);
    tree.updateNode(octomap::point3d(x, y, 0.0f), false);
  }
  tree.updateNode(octomap::point3d(-1.0f, 2.0f, -0.5f), true);
  return tree;
}

bool write(const std::string& path, const auto& writer) {
  std::ofstream out(path, std::ios_base::binary);
  writer(out);
  out.close();
  if (!out) std::cerr << "octovk_fuzz_corpus: cannot write " << path << "\n";
  return static_cast<bool>(out);
}

}  // namespace

int main(int argc, char** argv) {
  if (argc != 2) {
    std::cerr << "usage: octovk_fuzz_corpus DIR (writes DIR/bt, DIR/ot, DIR/graph)\n";
    return 2;
  }
  const std::string dir = argv[1];
  bool ok = true;
  octomap::OcTree small = tinyTree(0.1, 6);
  octomap::OcTree empty(0.05);
  ok &= write(dir + "/ot/small.ot", [&](std::ostream& s) { small.write(s); });
  ok &= write(dir + "/ot/empty.ot", [&](std::ostream& s) { empty.write(s); });
  octomap::OcTree coarse = tinyTree(0.2, 2);
  ok &= write(dir + "/ot/coarse.ot", [&](std::ostream& s) { coarse.write(s); });
  ok &= write(dir + "/bt/small.bt", [&](std::ostream& s) { small.writeBinary(s); });
  ok &= write(dir + "/bt/empty.bt", [&](std::ostream& s) { empty.writeBinary(s); });
  ok &= write(dir + "/bt/coarse.bt", [&](std::ostream& s) { coarse.writeBinary(s); });

  // Two scans of four points (one NaN: legal, the mapper skips it) and an edge between them.
  octomap::ScanGraph graph;
  for (int n = 0; n < 2; ++n) {
    auto* cloud = new octomap::Pointcloud();
    for (int i = 0; i < 4; ++i)
      cloud->push_back(1.0f + 0.1f * static_cast<float>(i), 0.2f * static_cast<float>(n), 0.3f);
    if (n == 1) cloud->push_back(std::numeric_limits<float>::quiet_NaN(), 0.0f, 0.0f);
    graph.addNode(cloud, octomath::Pose6D(0.5f * static_cast<float>(n), 0.0f, 0.1f, 0.0f, 0.0f,
                                          0.3f * static_cast<float>(n)));
  }
  graph.addEdge(0, 1);
  ok &= write(dir + "/graph/two_scans.graph", [&](std::ostream& s) { graph.writeBinary(s); });
  octomap::ScanGraph none;
  ok &= write(dir + "/graph/empty.graph", [&](std::ostream& s) { none.writeBinary(s); });
  return ok ? 0 : 1;
}
