// The checked readers behind readMapFile and readScanGraph: bytes in, a tree or scans out, or an
// Error (kFormat) that names the file and what is wrong in it. No Vulkan, no file system: the unit
// tests and the fuzz targets (tests/fuzz/) call them on bytes directly.
#pragma once

#include <octomap/ColorOcTree.h>
#include <octomap/OcTree.h>
#include <octomap/OcTreeStamped.h>

#include <cstdint>
#include <memory>
#include <string>
#include <string_view>
#include <variant>
#include <vector>

#include "io/byte_source.hpp"
#include "octovk/octomap_io.hpp"

namespace octovk::io {

/// A tree as OctoMap reads it: of the type its file or message names (OcTree, ColorOcTree,
/// OcTreeStamped), in the order of Payload's kinds.
using AnyTree =
    std::variant<std::unique_ptr<octomap::OcTree>, std::unique_ptr<octomap::ColorOcTree>,
                 std::unique_ptr<octomap::OcTreeStamped>>;

/// The payload of a tree type name (treeTypeName's inverse); false for a type octovk cannot read.
bool payloadOfTreeType(std::string_view id, Payload& payload);

/// What octovk reads from the text header of a .bt / .ot file.
struct TreeHeader {
  std::string id;           ///< the tree type ("OcTree", "ColorOcTree" or "OcTreeStamped")
  std::uint64_t size = 0;   ///< the node count the header announces
  double resolution = 0.0;  ///< metres
  std::size_t data_at = 0;  ///< the offset of the first byte after the "data" line
};

/// Reads and checks the header of a .bt (`binary`) or .ot file: the first line OctoMap writes,
/// then only comment lines (first word starting with '#'), blank lines and exactly one each of
/// "id TYPE" (OcTree, ColorOcTree or OcTreeStamped), "size N", "res R" (R finite, positive and a
/// resolution a map can have), ending with a "data" line. Throws Error(kFormat) naming `name`
/// otherwise.
TreeHeader parseTreeHeader(std::string_view bytes, bool binary, const std::string& name);

/// Checks a whole .bt (`binary`) or .ot file and reads its node records with OctoMap's reader.
/// Before OctoMap sees them, the records are walked without recursion: at most 16 levels below
/// the root, every record within the bytes (a .ot record: the node's data, 4 bytes of log-odds
/// and for ColorOcTree 3 of colour, then its child byte), .ot log-odds finite, no inner node
/// without children, the node count equal to the header's size, no byte after the last record.
/// The tree is of the header's type. Time and memory are proportional to the file's size.
/// Throws Error(kFormat) naming `name` and the fault.
AnyTree parseTreeFile(std::string_view bytes, bool binary, const std::string& name);

/// parseTreeFile on bytes read from `source` as the checks go: the header line by line (a line
/// over 64 KiB is refused), the records one by one, so a file fails at its first fault having
/// read little more than the bytes before it. The data section is held for OctoMap's reader.
AnyTree parseTreeFile(ByteSource& source, bool binary, const std::string& name);

/// Checks a message body (OctoMap's writeBinaryData (`binary`) or writeData output, the `data` of
/// an octomap_msgs/Octomap) with the same record walk as parseTreeFile, without a header: `id`
/// must be "OcTree", "ColorOcTree" or "OcTreeStamped" and `resolution` one a map can have; no
/// node count is announced. Throws Error(kFormat) naming `name` and the fault.
AnyTree parseTreeBody(std::string_view body, bool binary, const std::string& id, double resolution,
                      const std::string& name);

// ---- between OctoMap's trees and the host tree (octomap_io.cpp) ----

/// A tree of any type in the pool's layout, with the payload of its type.
HostTree hostTreeOf(const AnyTree& tree);

/// `host` as OctoMap's tree of its payload's type (OcTree, ColorOcTree, OcTreeStamped), with
/// `params`' resolution and sensor model: the tree writeMapFile and the messages write.
std::unique_ptr<octomap::AbstractOccupancyOcTree> octomapTreeOf(const HostTree& host,
                                                                const MapParams& params);

// ---- a stamped map's sidecar (PATH.ot.stamps): the stamps OctoMap's .ot does not hold ----
// Little-endian: bytes 0-7 "OVKSTAMP", 8-11 the version (1), 12-15 zero, 16-23 the node count,
// 24-31 the tree's digest (treeDigest), then one uint32 stamp per node in the .ot's node order.

/// The sidecar's header size, and its size for a tree of `nodes` nodes.
inline constexpr std::size_t kStampsHeaderBytes = 32;
constexpr std::uint64_t stampsFileSize(std::uint64_t nodes) {
  return kStampsHeaderBytes + 4 * nodes;
}

/// FNV-1a (64 bits) of the .ot data section a tree gives: for every node in the .ot's order
/// (depth first, children 0 to 7) its float log-odds' 4 bytes little-endian and its child byte.
/// A sidecar names the tree its stamps belong to by it.
std::uint64_t treeDigest(const HostTree& tree);

/// The sidecar of a tree whose payload is kStamp.
std::string stampsFile(const HostTree& tree);

/// Gives `tree`'s nodes (payload kStamp) the stamps of sidecar `bytes`. Throws Error(kFormat)
/// naming `name` and the fault when the bytes are not a sidecar, of a version this reader
/// knows, for a tree with this node count and digest; `tree` is then unchanged.
void applyStampsFile(std::string_view bytes, HostTree& tree, const std::string& name);
/// The same on a file read as the checks go (its size checked before its stamps are read).
void applyStampsFile(ByteSource& source, HostTree& tree, const std::string& name);

/// Reads an OctoMap ScanGraph binary file's bytes (see readScanGraph). Every count is checked
/// against the bytes left before anything is allocated for it; poses must be finite (points may
/// be NaN: the mapper skips those, as OctoMap does). Throws Error(kFormat) naming `name`.
std::vector<GraphScan> parseScanGraph(std::string_view bytes, const std::string& name);

/// parseScanGraph on bytes read from `source` as the parse goes (its size() the file's size,
/// which counts are checked against); memory follows the scans read, never the counts.
std::vector<GraphScan> parseScanGraph(ByteSource& source, const std::string& name);

}  // namespace octovk::io
