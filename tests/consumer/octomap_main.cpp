// Uses octovk::octomap (pkg-config octovk-octomap): a map written as .bt and read back, by octovk
// and by OctoMap itself.
#include <octomap/OcTree.h>
#include <octovk/octomap_io.hpp>

#include <cstdio>
#include <filesystem>
#include <string>
#include <unistd.h>

#include "consumer.hpp"

int main() {
  int exit_code = 0;
  auto context = consumer::context(exit_code);
  if (!context) return exit_code;
  octovk::OccupancyMap map(*context, octovk::MapParams{});
  if (std::string why = consumer::insertWall(map); !why.empty()) return consumer::fail(why);

  const std::string path = (std::filesystem::temp_directory_path() /
                            ("octovk-consumer-" + std::to_string(getpid()) + ".bt")).string();
  octovk::writeMapFile(map, path);
  octovk::OccupancyMap read = octovk::readMapFile(*context, path);
  octomap::OcTree tree(0.1);
  const bool octomap_read = tree.readBinary(path);
  std::filesystem::remove(path);

  const std::size_t nodes = octovk::toOcTree(map)->size();
  if (nodes == 0) return consumer::fail("toOcTree() gave an empty tree");
  if (read.nodeCount() != nodes)
    return consumer::fail("readMapFile() gave " + std::to_string(read.nodeCount()) +
                          " nodes, toOcTree() " + std::to_string(nodes));
  if (!octomap_read || tree.size() != nodes)
    return consumer::fail("OctoMap read the .bt as " + std::to_string(tree.size()) +
                          " nodes, expected " + std::to_string(nodes));
  std::printf("consumer (octomap): %zu nodes written to .bt and read back by octovk and OctoMap\n",
              nodes);
  return 0;
}
