// TUM RGB-D sequences: depth.txt and groundtruth.txt matched by timestamp, and 16-bit PNG depth
// images read with libpng. Numbers are parsed with std::from_chars (locale-independent, correctly
// rounded): timestamps as double, poses as float, so that a pose is exactly the float values
// OctoMap's Pose6D would hold.
#include <png.h>

#include <algorithm>
#include <bit>
#include <cerrno>
#include <charconv>
#include <cmath>
#include <csetjmp>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <sstream>
#include <system_error>

#include "octovk/tum_sequence.hpp"

namespace octovk {

namespace {

namespace fs = std::filesystem;

// ---- text files ----

struct Line {
  std::size_t number = 0;
  std::vector<std::string> fields;
  std::string text;
};

// The data lines of a TUM text file: '#' comment lines and blank lines dropped, fields split on
// spaces and tabs, a trailing '\r' (a file from Windows) ignored.
std::vector<Line> readDataLines(const fs::path& path) {
  std::error_code ec;
  if (!fs::exists(path, ec))
    throw Error(ErrorCode::kIo, "'" + path.string() +
                                    "' does not exist; a TUM RGB-D folder holds depth.txt, "
                                    "groundtruth.txt and the depth images");
  if (!fs::is_regular_file(path, ec))
    throw Error(ErrorCode::kIo, "'" + path.string() + "' is not a regular file");
  std::ifstream in(path);
  if (!in.is_open())
    throw Error(ErrorCode::kIo, "cannot read '" + path.string() + "': " + std::strerror(errno) +
                                    "; check its permissions");
  std::vector<Line> lines;
  std::string text;
  for (std::size_t number = 1; std::getline(in, text); ++number) {
    if (!text.empty() && text.back() == '\r') text.pop_back();
    const std::size_t first = text.find_first_not_of(" \t");
    if (first == std::string::npos || text[first] == '#') continue;
    Line line;
    line.number = number;
    line.text = text;
    for (std::size_t at = first; at < text.size();) {
      const std::size_t end = std::min(text.find_first_of(" \t", at), text.size());
      line.fields.push_back(text.substr(at, end - at));
      at = text.find_first_not_of(" \t", end);
      if (at == std::string::npos) break;
    }
    lines.push_back(std::move(line));
  }
  if (in.bad()) throw Error(ErrorCode::kIo, "cannot read '" + path.string() + "': read failed");
  return lines;
}

Error badLine(const fs::path& path, const Line& line, const std::string& why) {
  std::string shown = line.text.size() > 80 ? line.text.substr(0, 77) + "..." : line.text;
  return Error(ErrorCode::kFormat, "'" + path.string() + "' line " + std::to_string(line.number) +
                                       ": " + why + " (the line is '" + shown + "')");
}

template <class T>
T parseField(const fs::path& path, const Line& line, std::size_t i, const char* what) {
  const std::string& text = line.fields[i];
  T value{};
  const auto [end, ec] = std::from_chars(text.data(), text.data() + text.size(), value);
  if (ec != std::errc() || end != text.data() + text.size() || !std::isfinite(value))
    throw badLine(path, line, std::string(what) + " '" + text + "' is not a finite number");
  return value;
}

struct GroundTruthPose {
  double timestamp;
  Pose pose;
};

std::vector<GroundTruthPose> readGroundTruth(const fs::path& path) {
  std::vector<GroundTruthPose> poses;
  for (const Line& line : readDataLines(path)) {
    if (line.fields.size() != 8)
      throw badLine(path, line,
                    "expected 8 values 'timestamp tx ty tz qx qy qz qw', found " +
                        std::to_string(line.fields.size()));
    GroundTruthPose p;
    p.timestamp = parseField<double>(path, line, 0, "the timestamp");
    float v[7];
    static const char* const kNames[7] = {"tx", "ty", "tz", "qx", "qy", "qz", "qw"};
    for (std::size_t i = 0; i < 7; ++i) v[i] = parseField<float>(path, line, i + 1, kNames[i]);
    // A rotation far from unit length scales the points: a broken or misordered file.
    const double norm = std::sqrt(double{v[3]} * v[3] + double{v[4]} * v[4] +
                                  double{v[5]} * v[5] + double{v[6]} * v[6]);
    if (std::abs(norm - 1.0) > 0.01) {
      std::ostringstream why;
      why << "the rotation (qx qy qz qw) has norm " << norm
          << ", not 1; the columns must be 'timestamp tx ty tz qx qy qz qw' with a unit quaternion";
      throw badLine(path, line, why.str());
    }
    // octomath::Pose6D(Vector3(tx, ty, tz), Quaternion(qw, qx, qy, qz)), unnormalised as there.
    p.pose.translation = {v[0], v[1], v[2]};
    p.pose.rotation = Eigen::Quaternionf(v[6], v[3], v[4], v[5]);
    poses.push_back(p);
  }
  if (poses.empty())
    throw Error(ErrorCode::kFormat, "'" + path.string() +
                                        "' lists no poses (only comments or blank lines); it "
                                        "needs lines 'timestamp tx ty tz qx qy qz qw'");
  return poses;
}

std::string seconds(double t) {
  std::ostringstream s;
  s.precision(6);
  s << std::fixed << t;
  return s.str();
}

// ---- PNG (libpng's full API: png_set_swap is not in the simplified one) ----

// libpng reports errors by longjmp. The functions that call setjmp hold no object with a
// destructor, and nothing with one lives between them and libpng, so the jump skips no cleanup.
struct PngReader {
  png_structp png = nullptr;
  png_infop info = nullptr;
  std::FILE* file = nullptr;
  char message[256] = {};

  ~PngReader() {
    if (png) png_destroy_read_struct(&png, info ? &info : nullptr, nullptr);
    if (file) std::fclose(file);
  }
};

void pngError(png_structp png, png_const_charp message) {
  auto* reader = static_cast<PngReader*>(png_get_error_ptr(png));
  std::snprintf(reader->message, sizeof(reader->message), "%s", message);
  png_longjmp(png, 1);
}

void pngWarning(png_structp, png_const_charp) {}  // warnings change nothing read here

bool pngReadHeader(PngReader& r, png_uint_32* width, png_uint_32* height, int* bit_depth,
                   int* color_type) {
  if (setjmp(png_jmpbuf(r.png))) return false;
  png_init_io(r.png, r.file);
  png_set_sig_bytes(r.png, 8);
  png_read_info(r.png, r.info);
  int interlace = 0;
  png_get_IHDR(r.png, r.info, width, height, bit_depth, color_type, &interlace, nullptr, nullptr);
  return true;
}

bool pngReadRows(PngReader& r, png_bytepp rows) {
  if (setjmp(png_jmpbuf(r.png))) return false;
  // PNG stores 16-bit samples big-endian; swap them into host order.
  if constexpr (std::endian::native == std::endian::little) png_set_swap(r.png);
  png_read_image(r.png, rows);
  png_read_end(r.png, nullptr);
  return true;
}

const char* colorTypeName(int color_type) {
  switch (color_type) {
    case PNG_COLOR_TYPE_GRAY: return "grayscale";
    case PNG_COLOR_TYPE_GRAY_ALPHA: return "grayscale+alpha";
    case PNG_COLOR_TYPE_RGB: return "RGB colour";
    case PNG_COLOR_TYPE_RGB_ALPHA: return "RGBA colour";
    case PNG_COLOR_TYPE_PALETTE: return "palette colour";
    default: return "unknown colour type";
  }
}

}  // namespace

TumSequence readTumSequence(const std::string& dir, double max_time_difference_s) {
  const fs::path root(dir);
  std::error_code ec;
  if (!fs::is_directory(root, ec))
    throw Error(ErrorCode::kIo, "'" + dir + "' is not a directory; give a TUM RGB-D folder "
                                            "(with depth.txt and groundtruth.txt)");
  TumSequence sequence;
  sequence.dir = dir;

  const fs::path gt_path = root / "groundtruth.txt";
  std::vector<GroundTruthPose> poses = readGroundTruth(gt_path);
  sequence.poses = poses.size();
  std::stable_sort(poses.begin(), poses.end(), [](const auto& a, const auto& b) {
    return a.timestamp < b.timestamp;
  });

  const fs::path depth_path = root / "depth.txt";
  const std::vector<Line> lines = readDataLines(depth_path);
  for (const Line& line : lines) {
    if (line.fields.size() != 2)
      throw badLine(depth_path, line,
                    "expected 2 fields 'timestamp filename', found " +
                        std::to_string(line.fields.size()));
    const double t = parseField<double>(depth_path, line, 0, "the timestamp");
    ++sequence.images_listed;
    // The nearest pose: the first at or after t, or the one before it (the earlier on a tie).
    const auto after = std::lower_bound(
        poses.begin(), poses.end(), t,
        [](const GroundTruthPose& p, double time) { return p.timestamp < time; });
    auto nearest = after;
    if (after == poses.end() ||
        (after != poses.begin() && t - std::prev(after)->timestamp <= after->timestamp - t))
      nearest = std::prev(after);
    if (!(std::abs(nearest->timestamp - t) < max_time_difference_s)) {
      ++sequence.skipped_no_pose;
      continue;
    }
    TumFrame frame;
    frame.timestamp = t;
    frame.pose_timestamp = nearest->timestamp;
    frame.image_path = (root / line.fields[1]).string();
    frame.line = line.number;
    frame.T_world_camera = nearest->pose;
    if (!fs::is_regular_file(frame.image_path, ec))
      throw Error(ErrorCode::kIo,
                  "'" + depth_path.string() + "' line " + std::to_string(line.number) +
                      ": depth image '" + frame.image_path +
                      (fs::exists(frame.image_path, ec) ? "' is not a regular file"
                                                        : "' does not exist") +
                      "; check the folder is complete");
    sequence.frames.push_back(std::move(frame));
  }
  if (sequence.images_listed == 0)
    throw Error(ErrorCode::kFormat,
                "'" + depth_path.string() +
                    "' lists no images (only comments or blank lines); it needs lines "
                    "'timestamp filename'");
  if (sequence.frames.empty()) {
    double first = 0, last = 0;
    bool any = false;
    for (const Line& line : lines) {
      const double t = parseField<double>(depth_path, line, 0, "the timestamp");
      first = any ? std::min(first, t) : t;
      last = any ? std::max(last, t) : t;
      any = true;
    }
    throw Error(ErrorCode::kFormat,
                "no image of '" + depth_path.string() + "' has a ground-truth pose less than " +
                    seconds(max_time_difference_s) + " s away (images " + seconds(first) + " to " +
                    seconds(last) + " s, poses " + seconds(poses.front().timestamp) + " to " +
                    seconds(poses.back().timestamp) +
                    " s); check that groundtruth.txt belongs to this sequence");
  }
  return sequence;
}

DepthImage DepthPng::image(const CameraIntrinsics& camera) const {
  DepthImage out;
  out.width = width;
  out.height = height;
  out.encoding = DepthImage::Encoding::kUint16;
  out.pixels = depths.data();
  out.fx = camera.fx;
  out.fy = camera.fy;
  out.cx = camera.cx;
  out.cy = camera.cy;
  out.depth_scale = camera.depth_scale;
  return out;
}

namespace {

// Opens `path` in `r` and reads its header; throws unless it is a 16-bit grayscale PNG.
void openDepthPng(PngReader& r, const std::string& path, png_uint_32* width,
                  png_uint_32* height) {
  r.file = std::fopen(path.c_str(), "rb");
  if (!r.file)
    throw Error(ErrorCode::kIo, "cannot read depth image '" + path + "': " + std::strerror(errno));
  unsigned char signature[8];
  if (std::fread(signature, 1, 8, r.file) != 8 || png_sig_cmp(signature, 0, 8) != 0)
    throw Error(ErrorCode::kFormat, "depth image '" + path +
                                        "' is not a PNG file; depth images must be 16-bit "
                                        "grayscale PNGs");
  r.png = png_create_read_struct(PNG_LIBPNG_VER_STRING, &r, pngError, pngWarning);
  if (r.png) r.info = png_create_info_struct(r.png);
  if (!r.png || !r.info)
    throw Error(ErrorCode::kIo, "cannot read depth image '" + path + "': libpng is out of memory");

  int bit_depth = 0, color_type = 0;
  if (!pngReadHeader(r, width, height, &bit_depth, &color_type))
    throw Error(ErrorCode::kFormat, "depth image '" + path +
                                        "' is a corrupt or truncated PNG (libpng: " +
                                        std::string(r.message) + ")");
  if (bit_depth != 16 || color_type != PNG_COLOR_TYPE_GRAY)
    throw Error(ErrorCode::kFormat, "depth image '" + path + "' is a " +
                                        colorTypeName(color_type) + " PNG of bit depth " +
                                        std::to_string(bit_depth) +
                                        "; depth images must be 16-bit grayscale PNGs");
  if (*width > 65536 || *height > 65536)
    throw Error(ErrorCode::kFormat, "depth image '" + path + "' is " + std::to_string(*width) +
                                        " x " + std::to_string(*height) +
                                        " pixels; at most 65536 in each direction");
}

}  // namespace

void checkDepthPng(const std::string& path) {
  PngReader r;
  png_uint_32 width = 0, height = 0;
  openDepthPng(r, path, &width, &height);
}

DepthPng readDepthPng(const std::string& path) {
  PngReader r;
  png_uint_32 width = 0, height = 0;
  openDepthPng(r, path, &width, &height);
  DepthPng out;
  out.width = width;
  out.height = height;
  out.depths.resize(std::size_t{width} * height);
  std::vector<png_bytep> rows(height);
  for (png_uint_32 y = 0; y < height; ++y)
    rows[y] = reinterpret_cast<png_bytep>(out.depths.data() + std::size_t{y} * width);
  if (!pngReadRows(r, rows.data()))
    throw Error(ErrorCode::kFormat, "depth image '" + path +
                                        "' is a corrupt or truncated PNG (libpng: " +
                                        std::string(r.message) + ")");
  return out;
}

}  // namespace octovk
