// Writes the fuzz targets' seed corpus into DIR/{bt,ot,message,graph,tum_lists,depth_png}/: tiny
// maps (OcTree, ColorOcTree, OcTreeStamped), map message bodies and graphs with OctoMap's own
// writers, tiny TUM RGB-D lists (groundtruth.txt, a NUL byte, depth.txt) and tiny 16-bit PNGs with
// libpng. Usage: octovk_fuzz_corpus DIR (tests/fuzz/corpus holds its output).
#include <octomap/ColorOcTree.h>
#include <octomap/OcTree.h>
#include <octomap/OcTreeStamped.h>
#include <octomap/ScanGraph.h>
#include <png.h>
#include <zlib.h>

#include <cmath>
#include <csetjmp>
#include <cstdint>
#include <cstdio>
#include <fstream>
#include <iostream>
#include <limits>
#include <string>
#include <vector>

#include "png_writer.hpp"

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

// tinyTree's cells as a ColorOcTree, some coloured, inner colours as updateInnerOccupancy gives.
octomap::ColorOcTree tinyColorTree() {
  octomap::ColorOcTree tree(0.1);
  for (int i = 0; i < 6; ++i) {
    const octomap::point3d p(0.1f * static_cast<float>(i % 3), 0.1f * static_cast<float>(i / 3),
                             0.5f);
    tree.updateNode(p, true);
    if (i % 2 == 0)
      tree.setNodeColor(p.x(), p.y(), p.z(), static_cast<std::uint8_t>(40 * i), 7, 200);
  }
  tree.updateInnerOccupancy();
  return tree;
}

bool write(const std::string& path, const auto& writer) {
  std::ofstream out(path, std::ios_base::binary);
  writer(out);
  out.close();
  if (!out) std::cerr << "octovk_fuzz_corpus: cannot write " << path << "\n";
  return static_cast<bool>(out);
}


// A grayscale depth image of `width` x `height` pixels, 16-bit unless `bit_depth` is 8.
bool writeDepthPng(const std::string& path, png_uint_32 width, png_uint_32 height, int interlace,
                   int bit_depth = 16) {
  const std::size_t bytes_per_sample = bit_depth == 16 ? 2 : 1;
  std::vector<unsigned char> data(std::size_t{width} * height * bytes_per_sample);
  for (std::size_t i = 0; i < data.size(); ++i)
    data[i] = static_cast<unsigned char>(i % 2 == 0 ? 0x13 + i : 0x88);  // 0x1388 = 5000: 1 m
  std::vector<png_bytep> rows(height);
  for (png_uint_32 y = 0; y < height; ++y)
    rows[y] = data.data() + std::size_t{y} * width * bytes_per_sample;
  const bool ok =
      octovk::test::writePngRows(path.c_str(), width, height, bit_depth, PNG_COLOR_TYPE_GRAY,
                                 interlace, rows.data());
  if (!ok) std::cerr << "octovk_fuzz_corpus: cannot write " << path << "\n";
  return ok;
}

}  // namespace

int main(int argc, char** argv) {
  if (argc != 2) {
    std::cerr << "usage: octovk_fuzz_corpus DIR (writes DIR/bt, DIR/ot, DIR/message, DIR/graph, ...)\n";
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
  // The other tree types: a ColorOcTree (.ot records of 7 data bytes) and an OcTreeStamped.
  octomap::ColorOcTree color = tinyColorTree();
  octomap::OcTreeStamped stamped(0.1);
  stamped.updateNode(octomap::point3d(0.1f, 0.2f, 0.3f), true);
  stamped.updateNode(octomap::point3d(0.5f, 0.2f, 0.3f), false);
  ok &= write(dir + "/ot/color.ot", [&](std::ostream& s) { color.write(s); });
  ok &= write(dir + "/ot/stamped.ot", [&](std::ostream& s) { stamped.write(s); });
  ok &= write(dir + "/bt/color.bt", [&](std::ostream& s) { color.writeBinary(s); });
  ok &= write(dir + "/bt/stamped.bt", [&](std::ostream& s) { stamped.writeBinary(s); });
  // Message bodies: a flag byte (bit 0: 1 binary, 0 full; bits 1-2: the tree type, 0 OcTree,
  // 1 ColorOcTree, 2 OcTreeStamped; see fuzz_message.cpp), then the body.
  ok &= write(dir + "/message/full_color.msg", [&](std::ostream& s) {
    s.put(2);
    color.writeData(s);
  });
  for (const bool binary : {true, false}) {
    const std::string kind = binary ? "binary" : "full";
    for (const auto& [name, tree] : {std::pair<const char*, octomap::OcTree*>{"small", &small},
                                     std::pair<const char*, octomap::OcTree*>{"coarse", &coarse}})
      ok &= write(dir + "/message/" + kind + "_" + name + ".msg", [&](std::ostream& s) {
        s.put(binary ? 1 : 0);
        if (binary)
          tree->writeBinaryData(s);
        else
          tree->writeData(s);
      });
  }

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

  // TUM RGB-D lists: groundtruth.txt, a NUL byte, depth.txt (see fuzz_tum_lists.cpp).
  const std::string groundtruth =
      "# ground truth trajectory\n# timestamp tx ty tz qx qy qz qw\n"
      "1305031102.1758 1.3405 0.6266 1.6575 0.6574 0.6126 -0.2949 -0.3248\n"
      "1305031102.1858 1.3303 0.6256 1.6464 0.6579 0.6161 -0.2932 -0.3189\n"
      "1305031102.2758 1.3160 0.6254 1.6302 0.6609 0.6199 -0.2893 -0.3086\n";
  const std::string depth =
      "# depth maps\n# timestamp filename\n1305031102.160407 depth/1305031102.160407.png\n"
      "\n1305031102.194330 depth/1305031102.194330.png\n"
      "1305031102.226738 depth/1305031102.226738.png\n";
  ok &= write(dir + "/tum_lists/three_images.txt",
              [&](std::ostream& s) { s << groundtruth << '\0' << depth; });
  ok &= write(dir + "/tum_lists/crlf_one_image.txt", [&](std::ostream& s) {
    s << "1.0\t0 0 0 0 0 0 1\r\n2.0 1 2 3 0 0 0.7071 0.7071\r\n"
      << '\0' << "1.01 a.png\r\n5 b.png\r\n";
  });

  // Depth images: 16-bit grayscale (plain and interlaced) and an 8-bit one, which is refused.
  ok &= writeDepthPng(dir + "/depth_png/gray16_3x2.png", 3, 2, PNG_INTERLACE_NONE);
  ok &= writeDepthPng(dir + "/depth_png/gray16_adam7_5x4.png", 5, 4, PNG_INTERLACE_ADAM7);
  ok &= writeDepthPng(dir + "/depth_png/gray8_2x2.png", 2, 2, PNG_INTERLACE_NONE, 8);
  ok &= write(dir + "/depth_png/text_chunk_2gib.png",
              [](std::ostream& s) { s << octovk::test::hugeTextChunkPng(); });
  return ok ? 0 : 1;
}
