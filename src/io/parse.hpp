// The checked readers behind readMapFile and readScanGraph: bytes in, a tree or scans out, or an
// Error (kFormat) that names the file and what is wrong in it. No Vulkan, no file system: the unit
// tests and the fuzz targets (tests/fuzz/) call them on bytes directly.
#pragma once

#include <octomap/OcTree.h>

#include <cstdint>
#include <memory>
#include <string>
#include <string_view>
#include <vector>

#include "io/byte_source.hpp"
#include "octovk/octomap_io.hpp"

namespace octovk::io {

/// What octovk reads from the text header of a .bt / .ot file.
struct TreeHeader {
  std::string id;           ///< the tree type ("OcTree")
  std::uint64_t size = 0;   ///< the node count the header announces
  double resolution = 0.0;  ///< metres
  std::size_t data_at = 0;  ///< the offset of the first byte after the "data" line
};

/// Reads and checks the header of a .bt (`binary`) or .ot file: the first line OctoMap writes,
/// then only comment lines (first word starting with '#'), blank lines and exactly one each of
/// "id OcTree", "size N", "res R" (R finite, positive and a resolution a map can have), ending
/// with a "data" line. Throws Error(kFormat) naming `name` otherwise.
TreeHeader parseTreeHeader(std::string_view bytes, bool binary, const std::string& name);

/// Checks a whole .bt (`binary`) or .ot file and reads its node records with OctoMap's reader.
/// Before OctoMap sees them, the records are walked without recursion: at most 16 levels below
/// the root, every record within the bytes, .ot log-odds finite, no inner node without children,
/// the node count equal to the header's size, no byte after the last record. Time and memory are
/// proportional to the file's size. Throws Error(kFormat) naming `name` and the fault.
std::unique_ptr<octomap::OcTree> parseTreeFile(std::string_view bytes, bool binary,
                                               const std::string& name);

/// parseTreeFile on bytes read from `source` as the checks go: the header line by line (a line
/// over 64 KiB is refused), the records one by one, so a file fails at its first fault having
/// read little more than the bytes before it. The data section is held for OctoMap's reader.
std::unique_ptr<octomap::OcTree> parseTreeFile(ByteSource& source, bool binary,
                                               const std::string& name);

/// Checks a message body (OctoMap's writeBinaryData (`binary`) or writeData output, the `data` of
/// an octomap_msgs/Octomap) with the same record walk as parseTreeFile, without a header: `id`
/// must be "OcTree" and `resolution` one a map can have; no node count is announced. Throws
/// Error(kFormat) naming `name` and the fault.
std::unique_ptr<octomap::OcTree> parseTreeBody(std::string_view body, bool binary,
                                               const std::string& id, double resolution,
                                               const std::string& name);

/// Reads an OctoMap ScanGraph binary file's bytes (see readScanGraph). Every count is checked
/// against the bytes left before anything is allocated for it; poses must be finite (points may
/// be NaN: the mapper skips those, as OctoMap does). Throws Error(kFormat) naming `name`.
std::vector<GraphScan> parseScanGraph(std::string_view bytes, const std::string& name);

/// parseScanGraph on bytes read from `source` as the parse goes (its size() the file's size,
/// which counts are checked against); memory follows the scans read, never the counts.
std::vector<GraphScan> parseScanGraph(ByteSource& source, const std::string& name);

}  // namespace octovk::io
