// OctoMap scan graphs (.graph). The structure is checked first, so that a corrupt or truncated
// file is reported instead of being half read (ScanGraph::readBinary reads what it can silently).
#include <octomap/ScanGraph.h>

#include <cerrno>
#include <cstring>
#include <fstream>

#include "octovk/octomap_io.hpp"

namespace octovk {

namespace {

// Sizes of ScanGraph's binary records: a Vector3 is an int and 3 doubles, a quaternion an int
// and 4 doubles, a node is  points | pose | id, an edge  id | id | pose | weight.
constexpr std::uint64_t kVectorBytes = 4 + 3 * 8;
constexpr std::uint64_t kPoseBytes = kVectorBytes + 4 + 4 * 8;
constexpr std::uint64_t kEdgeBytes = 4 + 4 + kPoseBytes + 8;

void checkStructure(const std::string& path) {
  std::ifstream in(path, std::ios_base::binary | std::ios_base::ate);
  if (!in.is_open())
    throw Error(ErrorCode::kIo, "cannot read scan graph '" + path + "': " + std::strerror(errno));
  const std::uint64_t size = static_cast<std::uint64_t>(in.tellg());
  in.seekg(0);
  auto readU32 = [&](const char* what) {
    std::uint32_t v = 0;
    if (!in.read(reinterpret_cast<char*>(&v), 4))
      throw Error(ErrorCode::kFormat,
                  "'" + path + "' is not a valid scan graph: truncated at the " + what);
    return v;
  };
  auto bad = [&](const std::string& why) {
    return Error(ErrorCode::kFormat, "'" + path + "' is not a valid scan graph (.graph): " + why);
  };
  if (size < 8) throw bad("file is shorter than a graph header");
  const std::uint32_t nodes = readU32("node count");
  std::uint64_t at = 4;
  for (std::uint32_t i = 0; i < nodes; ++i) {
    const std::uint32_t points = readU32("point count");
    at += 4;
    const std::uint64_t body = std::uint64_t{points} * kVectorBytes + kPoseBytes + 4;
    if (at + body > size)
      throw bad("scan " + std::to_string(i) + " claims " + std::to_string(points) +
                " points, more than the file holds");
    // Spot-check the Vector3 size markers (always 3) of the first point and the pose.
    if (points > 0) {
      if (readU32("first point") != 3)
        throw bad("scan " + std::to_string(i) + " has a bad point record");
      in.seekg(static_cast<std::streamoff>(at + std::uint64_t{points} * kVectorBytes));
    }
    if (readU32("pose") != 3) throw bad("scan " + std::to_string(i) + " has a bad pose record");
    at += body;
    in.seekg(static_cast<std::streamoff>(at));
  }
  const std::uint32_t edges = readU32("edge count");
  at += 4;
  if (at + std::uint64_t{edges} * kEdgeBytes != size)
    throw bad("its length does not match its " + std::to_string(nodes) + " scans and " +
              std::to_string(edges) + " edges");
}

}  // namespace

std::vector<GraphScan> readScanGraph(const std::string& path) {
  checkStructure(path);
  octomap::ScanGraph graph;
  if (!graph.readBinary(path)) throw Error(ErrorCode::kIo, "cannot read scan graph '" + path + "'");
  std::vector<GraphScan> scans;
  scans.reserve(graph.size());
  for (const octomap::ScanNode* node : graph) {
    GraphScan scan;
    const octomath::Vector3& t = node->pose.trans();
    const octomath::Quaternion& q = node->pose.rot();
    scan.T_world_sensor.translation = {t.x(), t.y(), t.z()};
    scan.T_world_sensor.rotation = Eigen::Quaternionf(q.u(), q.x(), q.y(), q.z());
    scan.points_sensor.reserve(node->scan->size());
    for (const octomap::point3d& p : *node->scan)
      scan.points_sensor.emplace_back(p.x(), p.y(), p.z());
    scans.push_back(std::move(scan));
  }
  return scans;
}

Eigen::Vector3f graph2treeSensorOrigin(const Pose& T_world_sensor) {
  return T_world_sensor.inverse().transform(T_world_sensor.translation);
}

}  // namespace octovk
