// octovk convert: a depth-image sequence in the TUM RGB-D layout as an OctoMap scan graph, and the
// TUM folder handling integrate shares (options, checks, help).
#include <sys/resource.h>
#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <cfloat>
#include <cmath>
#include <cstdint>
#include <cstring>
#include <filesystem>
#include <iostream>
#include <limits>
#include <new>
#include <sstream>

#include "command.hpp"
#include "octovk/octomap_io.hpp"
#include "octovk/tum_sequence.hpp"
#include "report.hpp"

namespace octovk::cli {

namespace fs = std::filesystem;

// ---- shared with integrate ----

std::vector<std::pair<std::string, std::string>> cameraMultiValueOptions() {
  return {{"--intrinsics", "FX FY CX CY"}};
}

std::vector<std::string> cameraValueOptions() { return {"--depth-scale"}; }

namespace {

// A float from a double option value, refusing what float cannot hold.
float toFloat(const ParsedOption& option, double value, const std::string& example) {
  if (std::abs(value) > double{FLT_MAX})
    throw UsageError(option.name + " value " + std::to_string(value) +
                     " is too large for a float; e.g. " + option.name + " " + example);
  return static_cast<float>(value);
}

}  // namespace

bool parseCameraOption(const ParsedOption& option, CameraIntrinsics& camera) {
  if (option.name == "--intrinsics") {
    const std::string example = "525 525 319.5 239.5";
    const std::vector<double> v = parseNumbers(option, example);
    camera.fx = toFloat(option, v[0], example);
    camera.fy = toFloat(option, v[1], example);
    camera.cx = toFloat(option, v[2], example);
    camera.cy = toFloat(option, v[3], example);
    if (camera.fx == 0.0f || camera.fy == 0.0f)
      throw UsageError("--intrinsics: the focal lengths FX and FY must not be zero (got " +
                       option.values[0] + ", " + option.values[1] + "); e.g. --intrinsics " +
                       example);
    return true;
  }
  if (option.name == "--depth-scale") {
    camera.depth_scale = toFloat(option, parseNumber(option, "5000"), "5000");
    if (!(camera.depth_scale > 0.0f))
      throw UsageError("--depth-scale must be a positive number of depth units per metre (got " +
                       option.value + "); TUM RGB-D: --depth-scale 5000");
    return true;
  }
  return false;
}

void checkTumFolder(const std::string& dir, const std::string& usage) {
  if (dir.empty()) throw UsageError("no input folder given; usage: " + usage);
  std::error_code ec;
  const fs::file_status st = fs::status(dir, ec);
  if (!fs::exists(st)) throw UsageError("input '" + dir + "' does not exist; check the path");
  if (!fs::is_directory(st))
    throw UsageError("input '" + dir + "' is not a folder; give a TUM RGB-D folder (with " +
                     "depth.txt and groundtruth.txt)");
  for (const char* name : {"depth.txt", "groundtruth.txt"}) {
    const fs::path file = fs::path(dir) / name;
    if (!fs::exists(file, ec))
      throw UsageError("folder '" + dir + "' has no " + name +
                       ", so it is not a TUM RGB-D sequence; it needs depth.txt ('timestamp "
                       "filename' lines), groundtruth.txt ('timestamp tx ty tz qx qy qz qw' "
                       "lines) and the depth images");
    if (::access(file.c_str(), R_OK) != 0)
      throw UsageError("cannot read '" + file.string() + "': " + std::strerror(errno) +
                       "; check its permissions");
  }
}

void printTumFolderHelp(std::ostream& out) {
  out << "DIR is a TUM RGB-D folder: DIR/depth.txt ('timestamp filename', files inside DIR only:\n"
         "an absolute name, a '..' or a symbolic link out of DIR is refused), DIR/groundtruth.txt\n"
         "(one pose a line: 'timestamp tx ty tz qx qy qz qw') and 16-bit grayscale PNG depth\n"
         "images. Each image takes the nearest pose; one with none within 0.02 s is skipped.\n";
}

void printCameraOptionsHelp(std::ostream& out) {
  out << "      --intrinsics FX FY CX CY  DIR's camera in pixels (default: 525 525 319.5 239.5)\n"
         "      --depth-scale S    depth units per metre in DIR's images (default: 5000)\n";
}

std::string tumImagesText(const TumSequence& sequence) {
  return format(
      "%zu used of %zu in depth.txt (%zu skipped: no ground-truth pose less than %g s "
      "away)",
      sequence.frames.size(), sequence.images_listed, sequence.skipped_no_pose,
      kTumMaxTimeDifference);
}

// ---- octovk convert ----

namespace {

constexpr const char* kConvertUsage = "octovk convert DIR -o SCANS.graph";

}  // namespace

void printConvertHelp(std::ostream& out) {
  out << kConvertUsage
      << " [--intrinsics FX FY CX CY] [--depth-scale S]\n"
         "\n"
         "Writes a TUM RGB-D depth-image sequence as an OctoMap scan graph (.graph): one node per\n"
         "image with a pose, its points in the camera frame. graph2tree on it builds the map that\n"
         "'octovk integrate DIR' builds, byte for byte. No Vulkan device is needed.\n"
         "\n";
  printTumFolderHelp(out);
  out << "\n"
         "Options:\n"
         "  -o, --output FILE      the scan graph to write (.graph). Required.\n";
  printCameraOptionsHelp(out);
  out << "  -h, --help             show this help\n"
         "Values: '--name VALUE' or '--name=VALUE' ('--intrinsics=FX,FY,CX,CY').\n";
}

namespace {

class Convert final : public Command {
 public:
  bool option(const ParsedOption& opt) override { return parseCameraOption(opt, camera_); }
  void check(Invocation& in) override {
    checkTumFolder(in.input(), kConvertUsage);
    in.checkOutputs();
  }
  int run(Invocation& in) override;

 private:
  CameraIntrinsics camera_;
};

// Host bytes converting an image of `pixels` pixels takes at its peak: the decoded image (2 a
// pixel), its points (12) and OctoMap's copy of them that writes the scan (12).
constexpr std::uint64_t kConvertBytesPerPixel = 2 + 12 + 12;

// The most host memory this process can have: the machine's, or less under `ulimit -v`.
std::uint64_t hostMemoryLimit() {
  const long pages = ::sysconf(_SC_PHYS_PAGES), page = ::sysconf(_SC_PAGESIZE);
  std::uint64_t limit = pages > 0 && page > 0 ? std::uint64_t(pages) * std::uint64_t(page)
                                              : std::numeric_limits<std::uint64_t>::max();
  rlimit as{};
  if (::getrlimit(RLIMIT_AS, &as) == 0 && as.rlim_cur != RLIM_INFINITY)
    limit = std::min<std::uint64_t>(limit, as.rlim_cur);
  return limit;
}

std::string mib(std::uint64_t bytes) { return std::to_string(bytes >> 20) + " MiB"; }

int Convert::run(Invocation& in) {
  const TumSequence sequence = readTumSequence(in.input());
  // Every image's header before any work: one that cannot be converted in the host's memory is
  // refused by its size, not after its pixels were decoded.
  const std::uint64_t limit = hostMemoryLimit();
  for (const TumFrame& frame : sequence.frames) {
    const DepthPngSize size = checkDepthPng(frame.image_path);
    const std::uint64_t needed = std::uint64_t{size.width} * size.height * kConvertBytesPerPixel;
    if (needed > limit)
      throw Error(ErrorCode::kOutOfHostMemory,
                  "depth image '" + frame.image_path + "' is " + std::to_string(size.width) +
                      " x " + std::to_string(size.height) + " pixels: converting it takes " +
                      mib(needed) + " of host memory, more than the " + mib(limit) +
                      " this process may have (the machine's memory or ulimit -v); scale the "
                      "image down or crop it");
  }
  std::size_t points = 0, no_depth = 0;
  in.files().write(0, [&](const std::string& tmp) {
    StderrSilencer silenced;  // OctoMap's Pointcloud::writeBinary reports every scan there
    writeScanGraph(tmp, sequence.frames.size(), [&](std::size_t i) {
      const TumFrame& frame = sequence.frames[i];
      GraphScan scan;
      std::size_t skipped = 0;
      try {
        const DepthPng png = readDepthPng(frame.image_path);
        scan.points_sensor = unprojectDepthImage(png.image(camera_), &skipped);
      } catch (const std::bad_alloc&) {
        throw Error(ErrorCode::kOutOfHostMemory,
                    "depth image '" + frame.image_path +
                        "': the host ran out of memory converting it; free some, or scale the "
                        "image down");
      }
      scan.T_world_sensor = frame.T_world_camera;
      points += scan.points_sensor.size();
      no_depth += skipped;
      return scan;
    });
  });
  in.files().commit();

  return Report(15)
      .line("images", tumImagesText(sequence))
      .line("points",
            format("%zu (camera frame; %zu pixels without depth skipped)", points, no_depth))
      .wrote(in.output())
      .print();
}

}  // namespace

std::unique_ptr<Command> makeConvert() { return std::make_unique<Convert>(); }

}  // namespace octovk::cli
