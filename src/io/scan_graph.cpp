// OctoMap scan graphs (.graph, ScanGraph::writeBinary). Parsed here rather than with
// octomap::ScanGraph, which reads a corrupt or truncated file silently as far as it can and
// prints progress lines on stderr for every scan. Values are converted exactly as OctoMap's
// readers do: each coordinate is stored as a double and narrowed to float. Written through
// octomap::ScanNode::writeBinary, one scan at a time.
#include <octomap/ScanGraph.h>

#include <algorithm>
#include <cerrno>
#include <cmath>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <limits>
#include <memory>

#include "io/parse.hpp"
#include "map/host_memory.hpp"
#include "octovk/octomap_io.hpp"

namespace octovk {

namespace {

// Record sizes: a Vector3 is an int (3) and 3 doubles, a quaternion an int (4) and 4 doubles;
// a node is  points | pose | id,  an edge  id | id | pose | weight.
constexpr std::uint64_t kVectorBytes = 4 + 3 * 8;
constexpr std::uint64_t kPoseBytes = kVectorBytes + 4 + 4 * 8;
constexpr std::uint64_t kEdgeBytes = 4 + 4 + kPoseBytes + 8;

class GraphReader {
 public:
  GraphReader(const std::string& path, io::ByteSource& source) : path_(path), source_(source) {}

  std::uint32_t u32(const std::string& what) {
    need(4, what);
    std::uint32_t v;
    std::memcpy(&v, source_.view(at_, at_ + 4).data(), 4);
    at_ += 4;
    return v;
  }
  float narrowed(const std::string& what) {
    need(8, what);
    double v;
    std::memcpy(&v, source_.view(at_, at_ + 8).data(), 8);
    at_ += 8;
    return static_cast<float>(v);
  }
  void marker(std::uint32_t expected, const std::string& what) {
    if (u32(what) != expected) throw bad("bad " + what + " record");
  }
  void need(std::uint64_t n, const std::string& what) {
    if (!source_.has(at_ + n)) throw bad("truncated in the " + what);
  }
  // The bytes left by the file's size: counts are checked against it, never sized by it.
  std::uint64_t remaining() const { return source_.size() > at_ ? source_.size() - at_ : 0; }
  // The bytes read so far are not needed again.
  void done() { source_.release(at_); }
  bool atEnd() { return !source_.has(at_ + 1); }
  Error bad(const std::string& why) const {
    return Error(ErrorCode::kFormat, "'" + path_ + "' is not a valid scan graph (.graph): " + why);
  }

 private:
  std::string path_;
  io::ByteSource& source_;
  std::uint64_t at_ = 0;
};

}  // namespace

namespace io {

std::vector<GraphScan> parseScanGraph(std::string_view bytes, const std::string& path) {
  ByteSource source(bytes);
  return parseScanGraph(source, path);
}

std::vector<GraphScan> parseScanGraph(ByteSource& source, const std::string& path) {
  GraphReader in(path, source);
  if (in.remaining() < 8 || !source.has(8)) throw in.bad("file is shorter than a graph header");
  const std::uint32_t count = in.u32("scan count");
  // Each scan takes at least its point count, pose and id; then the edge count follows.
  constexpr std::uint64_t kMinScanBytes = 4 + kPoseBytes + 4;
  if (std::uint64_t{count} * kMinScanBytes + 4 > in.remaining())
    throw in.bad("it claims " + std::to_string(count) + " scans, more than its " +
                 std::to_string(source.size()) + " bytes can hold");
  // Memory follows the scans read, not the counts: a sparse file's size lets a count pass the
  // check above, and its zeros fail at the first record.
  std::vector<GraphScan> scans;
  for (std::uint32_t i = 0; i < count; ++i) {
    const std::string scan = "scan " + std::to_string(i);
    const std::uint32_t points = in.u32(scan + " point count");
    if (std::uint64_t{points} * kVectorBytes + kPoseBytes + 4 > in.remaining())
      throw in.bad(scan + " claims " + std::to_string(points) +
                   " points, more than the file holds");
    GraphScan out;
    out.points_sensor.reserve(std::min<std::uint32_t>(points, 1u << 16));
    for (std::uint32_t p = 0; p < points; ++p) {
      in.marker(3, scan + " point");
      const float x = in.narrowed(scan + " point");
      const float y = in.narrowed(scan + " point");
      const float z = in.narrowed(scan + " point");
      out.points_sensor.emplace_back(x, y, z);  // NaN allowed: the mapper skips it, as OctoMap
      if (p % 4096 == 4095) in.done();
    }
    in.marker(3, scan + " pose translation");
    const float tx = in.narrowed(scan + " pose");
    const float ty = in.narrowed(scan + " pose");
    const float tz = in.narrowed(scan + " pose");
    in.marker(4, scan + " pose rotation");
    const float qu = in.narrowed(scan + " pose");
    const float qx = in.narrowed(scan + " pose");
    const float qy = in.narrowed(scan + " pose");
    const float qz = in.narrowed(scan + " pose");
    in.u32(scan + " id");
    in.done();
    // A scan is cast from its pose: a pose that is not a number has no origin to cast from.
    for (const float v : {tx, ty, tz, qu, qx, qy, qz})
      if (!std::isfinite(v))
        throw in.bad(scan + "'s pose is not finite (" + std::to_string(v) + ")");
    out.T_world_sensor.translation = {tx, ty, tz};
    out.T_world_sensor.rotation = Eigen::Quaternionf(qu, qx, qy, qz);
    scans.push_back(std::move(out));
  }
  const std::uint32_t edges = in.u32("edge count");
  if (in.remaining() != std::uint64_t{edges} * kEdgeBytes)
    throw in.bad("its length does not match its " + std::to_string(count) + " scans and " +
                 std::to_string(edges) + " edges");
  // octovk has no use for the edges, but their bytes must be there, and be edges: a sparse
  // file's zeros fail at the first marker, unread beyond it.
  for (std::uint32_t e = 0; e < edges; ++e) {
    const std::string edge = "edge " + std::to_string(e);
    in.u32(edge + " first id");
    in.u32(edge + " second id");
    in.marker(3, edge + " translation");
    for (int i = 0; i < 3; ++i) in.narrowed(edge + " translation");
    in.marker(4, edge + " rotation");
    for (int i = 0; i < 4; ++i) in.narrowed(edge + " rotation");
    in.narrowed(edge + " weight");
    in.done();
  }
  if (!in.atEnd())
    throw in.bad("it holds more bytes than its " + std::to_string(count) + " scans and " +
                 std::to_string(edges) + " edges (did it change while read?)");
  return scans;
}

}  // namespace io

std::vector<GraphScan> readScanGraph(const std::string& path) {
  return hostMemoryGuard("readScanGraph", [&] {
    std::error_code ec;  // not a directory, device or pipe (a link to /dev/zero never ends)
    if (const auto st = std::filesystem::status(path, ec);
        std::filesystem::exists(st) && !std::filesystem::is_regular_file(st))
      throw Error(ErrorCode::kIo,
                  "cannot read scan graph '" + path + "': it is not a regular file");
    std::ifstream in(path, std::ios_base::binary);
    if (!in.is_open())
      throw Error(ErrorCode::kIo, "cannot read scan graph '" + path + "': " + std::strerror(errno));
    const std::uintmax_t size = std::filesystem::file_size(path, ec);
    if (ec) throw Error(ErrorCode::kIo, "cannot read scan graph '" + path + "': " + ec.message());
    io::ByteSource source(in, size, path);
    return io::parseScanGraph(source, path);
  });
}

Eigen::Vector3f graph2treeSensorOrigin(const Pose& T_world_sensor) {
  return T_world_sensor.inverse().transform(T_world_sensor.translation);
}

namespace {

void writeGraph(const std::string& path, std::size_t count,
                const std::function<GraphScan(std::size_t)>& scan) {
  if (count > std::numeric_limits<std::uint32_t>::max())
    throw Error(ErrorCode::kInvalidArgument,
                "writeScanGraph: " + std::to_string(count) + " scans; a .graph holds at most 2^32-1");
  std::ofstream out(path, std::ios_base::binary | std::ios_base::trunc);
  if (!out.is_open())
    throw Error(ErrorCode::kIo, "cannot write scan graph '" + path + "': " + std::strerror(errno));
  const auto check = [&] {
    if (!out) throw Error(ErrorCode::kIo, "cannot write scan graph '" + path + "': write failed");
  };
  // ScanGraph::writeBinary: n | node_1 .. node_n | m | edge_1 .. edge_m, counts as uint32.
  const auto nodes = static_cast<std::uint32_t>(count);
  out.write(reinterpret_cast<const char*>(&nodes), sizeof(nodes));
  for (std::size_t i = 0; i < count; ++i) {
    const GraphScan s = scan(i);
    if (s.points_sensor.size() > std::numeric_limits<std::uint32_t>::max())
      throw Error(ErrorCode::kInvalidArgument,
                  "writeScanGraph: scan " + std::to_string(i) + " holds more than 2^32-1 points");
    auto cloud = std::make_unique<octomap::Pointcloud>();
    cloud->reserve(s.points_sensor.size());
    for (const Eigen::Vector3f& p : s.points_sensor) cloud->push_back(p.x(), p.y(), p.z());
    const Pose& pose = s.T_world_sensor;
    const octomath::Pose6D pose6d(
        octomath::Vector3(pose.translation.x(), pose.translation.y(), pose.translation.z()),
        octomath::Quaternion(pose.rotation.w(), pose.rotation.x(), pose.rotation.y(),
                             pose.rotation.z()));
    const octomap::ScanNode node(cloud.release(), pose6d, static_cast<unsigned int>(i));  // owns it
    node.writeBinary(out);
    check();
  }
  const std::uint32_t edges = 0;
  out.write(reinterpret_cast<const char*>(&edges), sizeof(edges));
  out.close();
  check();
}

}  // namespace

void writeScanGraph(const std::string& path, std::size_t count,
                    const std::function<GraphScan(std::size_t)>& scan) {
  hostMemoryGuard("writeScanGraph", [&] { writeGraph(path, count, scan); });
}

}  // namespace octovk
