// OctoMap interop: the map as an octomap::OcTree, OctoMap's .bt / .ot files and .graph scan logs.
// OctoMap is used here only to read and write its formats, never in the mapping path.
#pragma once

#include <octomap/OcTree.h>

#include <cstddef>
#include <functional>
#include <memory>
#include <string>
#include <vector>

#include "octovk/octovk.hpp"

namespace octovk {

/// The map as an OctoMap tree with the same nodes and bit-identical log-odds (downloads the map).
std::unique_ptr<octomap::OcTree> toOcTree(const OccupancyMap& map);

/// Replaces the map's contents with `tree` (uploads it). The map's resolution must match.
void fromOcTree(OccupancyMap& map, const octomap::OcTree& tree);

/// Writes the map in the format its extension names: .bt (OctoMap's writeBinary: max-likelihood,
/// pruned) or .ot (full log-odds). Written to a temporary file and renamed, so a failed write
/// leaves no partial file behind.
void writeMapFile(const OccupancyMap& map, const std::string& path);

/// Reads a .bt or .ot file into a new map on `context`, with the file's resolution and, for .ot,
/// its sensor model. The file is checked before OctoMap's reader sees it (header fields, tree type
/// OcTree, at most 16 levels, node count, finite log-odds), so a damaged or hostile file is a
/// kFormat error naming the file and the fault, at a cost in time and memory linear in its size.
/// `max_device_bytes` caps the map as MapParams::max_device_bytes does (0: no cap): a file whose
/// tree does not fit under it is a kOutOfDeviceMemory error naming the cap.
OccupancyMap readMapFile(Context& context, const std::string& path,
                         std::size_t max_device_bytes = 0);

/// One scan of a scan graph: points in the sensor frame, and the sensor pose in the world.
struct GraphScan {
  std::vector<Eigen::Vector3f> points_sensor;
  Pose T_world_sensor;
};

/// Reads an OctoMap ScanGraph binary file (.graph); a corrupt or truncated file, a count beyond the
/// bytes the file holds, or a non-finite pose is a kFormat error naming the file. Points may be
/// NaN (the mapper skips them).
std::vector<GraphScan> readScanGraph(const std::string& path);

/// The sensor origin graph2tree uses for a scan (in the sensor frame), to pass with the pose:
/// pose.inverse().transform(pose.translation).
Eigen::Vector3f graph2treeSensorOrigin(const Pose& T_world_sensor);

/// Writes `count` scans as an OctoMap scan graph (.graph): ScanGraph::writeBinary's layout (scan
/// count, each scan through octomap::ScanNode::writeBinary with id i, no edges), one scan in
/// memory at a time; `scan(i)` gives scan i. Points and pose are stored as OctoMap's Pointcloud
/// and Pose6D hold them (floats), so readScanGraph and ScanGraph::readBinary read back exactly
/// these values. Writes `path` itself (wrap it for an atomic write); kIo if it cannot be written.
void writeScanGraph(const std::string& path, std::size_t count,
                    const std::function<GraphScan(std::size_t)>& scan);

}  // namespace octovk
