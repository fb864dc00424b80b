// OctoMap interop: the map as an octomap::OcTree (ColorOcTree, OcTreeStamped), OctoMap's .bt / .ot
// files and .graph scan logs. OctoMap is used here only to read and write its formats, never in
// the mapping path.
#pragma once

#include <octomap/ColorOcTree.h>
#include <octomap/OcTree.h>
#include <octomap/OcTreeStamped.h>

#include <cstddef>
#include <cstdint>
#include <functional>
#include <memory>
#include <ostream>
#include <string>
#include <vector>

#include "octovk/octovk.hpp"

namespace octovk {

/// The map as an OctoMap tree with the same nodes and bit-identical log-odds (downloads the map).
/// A payload is left out (toColorOcTree, toOcTreeStamped keep it).
std::unique_ptr<octomap::OcTree> toOcTree(OccupancyMap& map);

/// Replaces the map's contents with `tree` (uploads it). The map's resolution must match. A map
/// with a payload gives every node a new node's (white, stamp 0).
void fromOcTree(OccupancyMap& map, const octomap::OcTree& tree);

/// The map as an OctoMap ColorOcTree: the same nodes, bit-identical log-odds and the colours
/// (inner nodes' as updateInnerOccupancy() gives them). Downloads the map.
std::unique_ptr<octomap::ColorOcTree> toColorOcTree(ColorMap& map);

/// Replaces the map's contents with `tree`'s nodes, log-odds and colours (uploads it). The map's
/// resolution must match.
void fromColorOcTree(ColorMap& map, const octomap::ColorOcTree& tree);

/// The map as an OctoMap OcTreeStamped: the same nodes, bit-identical log-odds, and every node's
/// stamp set with setTimestamp. Downloads the map.
std::unique_ptr<octomap::OcTreeStamped> toOcTreeStamped(StampedMap& map);

/// Replaces the map's contents with `tree`'s nodes, log-odds and stamps (uploads it). The map's
/// resolution must match.
void fromOcTreeStamped(StampedMap& map, const octomap::OcTreeStamped& tree);

/// Writes the map in the format its extension names: .bt (OctoMap's writeBinary: max-likelihood,
/// pruned) or .ot (full log-odds), as OctoMap's tree of the map's type (MapParams::payload)
/// writes it: an OcTree, a ColorOcTree (.ot: log-odds and colour per node) or an OcTreeStamped
/// (header "id OcTreeStamped"; OctoMap's files hold no stamps). A stamped map's .ot also gets
/// its stamps beside it in `PATH.stamps` (octovk's own format: "OVKSTAMP", version, node count,
/// a digest of the tree, a uint32 stamp per node in the .ot's order, little-endian), which
/// readMapFile reads back. Each file is written to a temporary file and renamed, so a failed
/// write (an I/O error, or the host out of memory: kOutOfHostMemory) leaves no partial file
/// behind and the file it was to replace as it was.
void writeMapFile(OccupancyMap& map, const std::string& path);

/// What writeMapFile writes, into `out` (`binary`: the .bt, else the .ot) for a caller that makes
/// its files atomic itself (the program's outputs); check `out` afterwards. For a stamped map's
/// .ot, `stamps` (when given) receives the bytes of its `PATH.stamps` (else it is left empty).
/// Returns the node count written (for .bt after writeBinary's pruning). Downloads the map.
std::size_t writeMapStream(OccupancyMap& map, std::ostream& out, bool binary,
                           std::string* stamps = nullptr);

/// Reads a .bt or .ot file into a new map on `context`, with the file's resolution and
/// MapParams' default sensor model (neither format stores one: OctoMap's readers also keep their
/// defaults), and the payload of the file's tree type: OcTree none, ColorOcTree kColor (the
/// colours of a .ot; a .bt holds none, so white), OcTreeStamped kStamp (the stamps of
/// `PATH.stamps` where that file exists, else 0). The file is checked before OctoMap's reader
/// sees it (header fields, tree type, at most 16 levels, node count, finite log-odds), so a
/// damaged or hostile file, or a `PATH.stamps` that is not this tree's, is a kFormat error
/// naming the file and the fault. The file is read as the checks go, so time and
/// memory follow the bytes before the first fault (a sparse or oversized file fails at once), not
/// its size; the host out of memory is kOutOfHostMemory. `max_device_bytes` caps the map as
/// MapParams::max_device_bytes does (0: no cap): a file whose tree does not fit under it is a
/// kOutOfDeviceMemory error naming the cap.
OccupancyMap readMapFile(Context& context, const std::string& path,
                         std::size_t max_device_bytes = 0);

/// A map file as readMapFile reads and checks it, in host memory only: the tree and the
/// parameters of the map readMapFile would make of it (resolution, payload, the default sensor
/// model; max_device_bytes 0). No device is touched, so a damaged file is reported before any
/// driver starts. Errors as readMapFile's. `OccupancyMap map(context, file.params);
/// map.upload(file.tree);` is readMapFile.
struct MapFileContents {
  MapParams params;
  HostTree tree;
};
MapFileContents readMapFileContents(const std::string& path);

/// The body of an octomap_msgs/Octomap message (everything but its ROS header), as OctoMap's
/// octomap_msgs conversions fill it: `id` the tree type ("OcTree", "ColorOcTree", "OcTreeStamped"),
/// `resolution` in metres, `binary` and `data`, the bytes of OctoMap's writeBinaryData() (binary:
/// one occupied or free state per leaf, the tree not pruned or converted first) or writeData()
/// (full: every node's float log-odds). Nothing of a file's text header is in `data`.
struct MapMessage {
  std::string id = "OcTree";
  double resolution = 0.0;
  bool binary = true;
  std::vector<std::int8_t> data;  ///< int8, as octomap_msgs declares it: `msg.data = m.data`
};

/// The map as a binary message body: byte-identical to octomap_msgs::binaryMapToMsg on the same
/// tree of the map's type (OctoMap's writeBinaryData). Downloads the map; no file is written.
MapMessage binaryMapToMessage(OccupancyMap& map);

/// The map as a full message body: byte-identical to octomap_msgs::fullMapToMsg on the same tree
/// of the map's type (OctoMap's writeData: every node's log-odds, and a ColorOcTree's colours).
/// Downloads the map; no file is written.
MapMessage fullMapToMessage(OccupancyMap& map);

/// A message body as a new map on `context` with the message's resolution, the default sensor
/// model and the payload of its tree type (stamps 0: no message holds them). The body is checked
/// as readMapFile checks a file (tree type OcTree, ColorOcTree or OcTreeStamped, at most 16
/// levels, every record within the bytes, finite log-odds, no byte after the last record): a
/// damaged or hostile body is a kFormat error naming `name` and the fault. `max_device_bytes`
/// as readMapFile.
OccupancyMap messageToMap(Context& context, const MapMessage& message,
                          std::size_t max_device_bytes = 0,
                          const std::string& name = "map message");

/// Replaces `map`'s contents with a message body (checked as above); the message's resolution
/// and tree type must be the map's (else kInvalidArgument). On any error the map is as before.
void messageToMap(OccupancyMap& map, const MapMessage& message,
                  const std::string& name = "map message");

/// One scan of a scan graph: points in the sensor frame, and the sensor pose in the world.
struct GraphScan {
  std::vector<Eigen::Vector3f> points_sensor;
  Pose T_world_sensor;
};

/// Reads an OctoMap ScanGraph binary file (.graph); a corrupt or truncated file, a count beyond the
/// bytes the file holds, or a non-finite pose is a kFormat error naming the file. Points may be
/// NaN (the mapper skips them). Read as it is parsed: memory follows the scans read, never a
/// count or the file's size; the host out of memory is kOutOfHostMemory.
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
