// Uses octovk::store (pkg-config octovk-store): a map kept in an SQLite store, two scans
// committed through StoredMap, read back by readStoredMap and followed by StoreFollower.
#include <octovk/octomap_io.hpp>
#include <octovk/store.hpp>

#include <cstdio>
#include <filesystem>
#include <string>
#include <unistd.h>

#include "consumer.hpp"

int main() {
  int exit_code = 0;
  auto context = consumer::context(exit_code);
  if (!context) return exit_code;
  const std::filesystem::path dir = std::filesystem::temp_directory_path() /
                                    ("octovk-consumer-store-" + std::to_string(getpid()));
  std::filesystem::create_directories(dir);
  const std::string location = (dir / "map.sqlite").string();
  std::string why;
  try {
    octovk::MapParams params;
    params.resolution = 0.05;
    octovk::StoredMap stored = octovk::StoredMap::open(*context, location, "consumer", params);
    std::vector<Eigen::Vector3f> wall;
    for (int y = -5; y <= 5; ++y)
      for (int z = -5; z <= 5; ++z)
        wall.emplace_back(2.0f, 0.05f * static_cast<float>(y), 0.05f * static_cast<float>(z));
    stored.insertPointCloud(wall, Eigen::Vector3f::Zero(), "consumer", 0);
    stored.insertPointCloud(wall, Eigen::Vector3f(0.0f, 0.1f, 0.0f), "consumer", 1);
    const std::size_t nodes = stored.map().nodeCount();
    octovk::OccupancyMap read = octovk::readStoredMap(*context, location, "consumer");
    if (stored.lastSeq() != 2) why = "two scans committed as " + std::to_string(stored.lastSeq());
    else if (nodes == 0) why = "the stored map is empty";
    else if (read.nodeCount() != nodes)
      why = "readStoredMap() gave " + std::to_string(read.nodeCount()) + " nodes, the writer " +
            std::to_string(nodes);
    else
      std::printf("consumer (store): 2 scans committed to SQLite, %zu nodes read back\n", nodes);
  } catch (const octovk::Error& e) {
    why = e.what();
  }
  std::filesystem::remove_all(dir);
  return why.empty() ? 0 : consumer::fail(why);
}
