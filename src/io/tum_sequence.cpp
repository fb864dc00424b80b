// TUM RGB-D sequences: depth.txt and groundtruth.txt (and rgb.txt, for colour) matched by
// timestamp, and 16-bit PNG depth images and 8-bit colour PNGs read with libpng. Numbers are parsed
// with std::from_chars (locale-independent, correctly rounded): timestamps as double, poses as
// float, so that a pose is exactly the float values OctoMap's Pose6D would hold.
#include "octovk/tum_sequence.hpp"

#include <png.h>

#include <algorithm>
#include <bit>
#include <cerrno>
#include <charconv>
#include <cmath>
#include <csetjmp>
#include <cstdint>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <sstream>
#include <string_view>
#include <system_error>

#include "io/byte_source.hpp"
#include "io/tum_parse.hpp"
#include "map/host_memory.hpp"

namespace octovk {

namespace {

namespace fs = std::filesystem;

// ---- text files ----

struct Line {
  std::size_t number = 0;
  std::vector<std::string> fields;
  std::string text;
};

// The longest line a list may have: TUM's lines hold a few dozen bytes, and a line without end
// (a sparse file's zeros) must not be read whole.
constexpr std::size_t kMaxLineBytes = 64 * 1024;

// The data lines of a TUM text file, one at a time as `source` gives them: '#' comment lines and
// blank lines dropped, fields split on spaces and tabs, a trailing '\r' (a file from Windows)
// ignored. Lines end at '\n' (the last may lack it), as std::getline reads them. Only the line
// at hand is held: memory follows the lines, never the file's size.
class DataLines {
 public:
  DataLines(io::ByteSource& source, const std::string& path) : source_(source), path_(path) {}

  // The next data line into `line`; false at the end.
  bool next(Line& line) {
    while (source_.has(at_ + 1)) {
      std::uint64_t end = at_;
      while (source_.has(end + 1) && source_.at(end) != '\n') {
        if (++end - at_ > kMaxLineBytes)
          throw Error(ErrorCode::kFormat,
                      "'" + path_ + "' line " + std::to_string(number_ + 1) + " is longer than " +
                          std::to_string(kMaxLineBytes) +
                          " bytes; a TUM list holds short lines 'timestamp ...' (is it a TUM "
                          "list?)");
      }
      std::string text(source_.view(at_, end));
      at_ = source_.has(end + 1) ? end + 1 : end;
      source_.release(at_);
      ++number_;
      if (!text.empty() && text.back() == '\r') text.pop_back();
      const std::size_t first = text.find_first_not_of(" \t");
      if (first == std::string::npos || text[first] == '#') continue;
      line.number = number_;
      line.fields.clear();
      for (std::size_t field = first; field < text.size();) {
        const std::size_t field_end = std::min(text.find_first_of(" \t", field), text.size());
        line.fields.push_back(text.substr(field, field_end - field));
        field = text.find_first_not_of(" \t", field_end);
        if (field == std::string::npos) break;
      }
      line.text = std::move(text);
      return true;
    }
    return false;
  }

 private:
  io::ByteSource& source_;
  const std::string& path_;
  std::uint64_t at_ = 0;
  std::size_t number_ = 0;
};

// A TUM list inside the folder `real_root` (canonical), opened; kIo errors name it. A list that
// is a symbolic link out of the folder is refused, as an image's name would be.
std::ifstream openList(const fs::path& path, const fs::path& real_root, std::uintmax_t* size) {
  std::error_code ec;
  if (!fs::exists(path, ec))
    throw Error(ErrorCode::kIo, "'" + path.string() +
                                    "' does not exist; a TUM RGB-D folder holds depth.txt, "
                                    "groundtruth.txt and the depth images (and rgb.txt and "
                                    "the colour images, for colour)");
  const fs::path real = fs::canonical(path, ec);
  if (ec) throw Error(ErrorCode::kIo, "cannot resolve '" + path.string() + "': " + ec.message());
  const fs::path inside = real.lexically_relative(real_root);
  if (inside.empty() || *inside.begin() == "..")
    throw Error(ErrorCode::kIo, "'" + path.string() + "' leads through a symbolic link to '" +
                                    real.string() + "', outside the folder '" + real_root.string() +
                                    "'; the lists are read from inside the folder only: copy "
                                    "the file into it");
  if (!fs::is_regular_file(real, ec))
    throw Error(ErrorCode::kIo, "'" + path.string() + "' is not a regular file");
  // The resolved name: the one checked above is the one read.
  std::ifstream in(real, std::ios_base::binary);
  if (!in.is_open())
    throw Error(ErrorCode::kIo, "cannot read '" + path.string() + "': " + std::strerror(errno) +
                                    "; check its permissions");
  *size = fs::file_size(real, ec);
  if (ec) throw Error(ErrorCode::kIo, "cannot read '" + path.string() + "': " + ec.message());
  return in;
}

Error badLine(const std::string& path, const Line& line, const std::string& why) {
  std::string shown = line.text.size() > 80 ? line.text.substr(0, 77) + "..." : line.text;
  return Error(ErrorCode::kFormat, "'" + path + "' line " + std::to_string(line.number) + ": " +
                                       why + " (the line is '" + shown + "')");
}

template <class T>
T parseField(const std::string& path, const Line& line, std::size_t i, const char* what) {
  const std::string& text = line.fields[i];
  T value{};
  const auto [end, ec] = std::from_chars(text.data(), text.data() + text.size(), value);
  if (ec != std::errc() || end != text.data() + text.size() || !std::isfinite(value))
    throw badLine(path, line, std::string(what) + " '" + text + "' is not a finite number");
  return value;
}

// Images are read from inside the folder only: joined with an absolute name the folder would be
// dropped, and '..' climbs out of it, either way to any file on the machine. (Symbolic links are
// resolved and checked where the files are: readTumSequence.) `list` names the list in words
// ("depth.txt"), `example` a name it could hold.
void checkImageName(const std::string& path, const Line& line, const char* list,
                    const char* example) {
  const fs::path name(line.fields[1]);
  if (name.is_absolute())
    throw badLine(path, line,
                  "the file name '" + line.fields[1] + "' is absolute; " + list +
                      " names images relative to the folder (e.g. '" + example + "')");
  if (std::any_of(name.begin(), name.end(), [](const fs::path& part) { return part == ".."; }))
    throw badLine(path, line,
                  "the file name '" + line.fields[1] + "' has a '..' component; " + list +
                      " names images inside the folder (e.g. '" + example +
                      "'): move the images into it");
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
// The bytes come from a file (readDepthPng, checkDepthPng) or from memory (io::decodeDepthPng).
struct PngReader {
  png_structp png = nullptr;
  png_infop info = nullptr;
  std::FILE* file = nullptr;
  std::string_view memory;  // when file is null: the bytes, read from `memory_at`
  std::size_t memory_at = 0;
  std::uint64_t source_size = 0;  // bytes in the file or in memory; 0 when unknown
  char message[256] = {};

  ~PngReader() {
    if (png) png_destroy_read_struct(&png, info ? &info : nullptr, nullptr);
    if (file) std::fclose(file);
  }

  // Up to `length` bytes into `out`; how many were read.
  std::size_t read(unsigned char* out, std::size_t length) {
    if (file) return std::fread(out, 1, length, file);
    const std::size_t n = std::min(length, memory.size() - memory_at);
    if (n > 0) std::memcpy(out, memory.data() + memory_at, n);  // memory.data() may be null
    memory_at += n;
    return n;
  }
};

void pngError(png_structp png, png_const_charp message) {
  auto* reader = static_cast<PngReader*>(png_get_error_ptr(png));
  std::snprintf(reader->message, sizeof(reader->message), "%s", message);
  png_longjmp(png, 1);
}

void pngWarning(png_structp, png_const_charp) {}  // warnings change nothing read here

// libpng's read callback; a short read is an error, as in libpng's own file reader.
void pngRead(png_structp png, png_bytep out, png_size_t length) {
  auto* reader = static_cast<PngReader*>(png_get_io_ptr(png));
  if (reader->read(out, length) != length) png_error(png, "Read Error");
}

// The most pixels a depth image may have in each direction (libpng's user limit and our check).
constexpr png_uint_32 kMaxPngSide = 65536;
// The longest chunk libpng will take (IDAT excepted: libpng streams it and bounds it by the
// image's size); libpng's own default, made explicit.
constexpr png_alloc_size_t kMaxPngChunkBytes = 8'000'000;
// The most ancillary chunks (text, sPLT, unknown) libpng keeps; none are kept here anyway.
constexpr png_uint_32 kMaxPngCachedChunks = 32;

// Bounds what libpng may allocate for a PNG beyond its rows and zlib's window. Debian's libpng
// 1.6.39 allocates a text chunk whole, as long as its length field says, before reading it, and
// png_set_chunk_malloc_max does not stop that: a 2.5 kB file declaring a 2 GiB tEXt chunk cost
// 2 GiB of RSS and seconds before its read failed. Depth images need no ancillary chunk (text,
// ICC profile, gamma, ...), so all but tRNS are skipped unread (libpng reads them through in
// 1 kB pieces, holding nothing): none is allocated, decompressed or stored.
void limitPngMemory(png_structp png) {
  png_set_user_limits(png, kMaxPngSide, kMaxPngSide);
  png_set_chunk_malloc_max(png, kMaxPngChunkBytes);
  png_set_chunk_cache_max(png, kMaxPngCachedChunks);
  png_set_keep_unknown_chunks(png, PNG_HANDLE_CHUNK_NEVER, nullptr, -1);  // -1: known ones too
}

bool pngReadHeader(PngReader& r, png_uint_32* width, png_uint_32* height, int* bit_depth,
                   int* color_type) {
  if (setjmp(png_jmpbuf(r.png))) return false;
  png_set_read_fn(r.png, &r, pngRead);
  png_set_sig_bytes(r.png, 8);
#ifdef FUZZING_BUILD_MODE_UNSAFE_FOR_PRODUCTION
  // Fuzz builds only (tests/fuzz/): damaged checksums pass, so mutated chunks reach the decoder.
  png_set_crc_action(r.png, PNG_CRC_QUIET_USE, PNG_CRC_QUIET_USE);
#endif
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
    case PNG_COLOR_TYPE_GRAY:
      return "grayscale";
    case PNG_COLOR_TYPE_GRAY_ALPHA:
      return "grayscale+alpha";
    case PNG_COLOR_TYPE_RGB:
      return "RGB colour";
    case PNG_COLOR_TYPE_RGB_ALPHA:
      return "RGBA colour";
    case PNG_COLOR_TYPE_PALETTE:
      return "palette colour";
    default:
      return "unknown colour type";
  }
}

}  // namespace

namespace io {

std::vector<GroundTruthPose> parseGroundTruth(std::string_view text, const std::string& path) {
  ByteSource source(text);
  return parseGroundTruth(source, path);
}

std::vector<GroundTruthPose> parseGroundTruth(ByteSource& source, const std::string& path) {
  std::vector<GroundTruthPose> poses;
  DataLines lines(source, path);
  for (Line line; lines.next(line);) {
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
    const double norm = std::sqrt(double{v[3]} * v[3] + double{v[4]} * v[4] + double{v[5]} * v[5] +
                                  double{v[6]} * v[6]);
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
    throw Error(ErrorCode::kFormat, "'" + path +
                                        "' lists no poses (only comments or blank lines); it "
                                        "needs lines 'timestamp tx ty tz qx qy qz qw'");
  return poses;
}

TumSequence associateDepthList(std::string_view text, std::vector<GroundTruthPose> poses,
                               const TumListNames& names, double max_time_difference_s,
                               const std::function<void(const TumFrame&)>& frame_taken) {
  ByteSource source(text);
  return associateDepthList(source, std::move(poses), names, max_time_difference_s, frame_taken);
}

TumSequence associateDepthList(ByteSource& source, std::vector<GroundTruthPose> poses,
                               const TumListNames& names, double max_time_difference_s,
                               const std::function<void(const TumFrame&)>& frame_taken) {
  const fs::path root(names.dir);
  const std::string& depth_path = names.depth;
  TumSequence sequence;
  sequence.dir = names.dir;
  sequence.poses = poses.size();
  if (poses.empty())
    throw Error(ErrorCode::kFormat, "'" + names.groundtruth +
                                        "' lists no poses (only comments or blank lines); it "
                                        "needs lines 'timestamp tx ty tz qx qy qz qw'");
  std::stable_sort(poses.begin(), poses.end(),
                   [](const auto& a, const auto& b) { return a.timestamp < b.timestamp; });

  double first = 0, last = 0;  // the images' times, for the message when none takes a pose
  DataLines lines(source, depth_path);
  for (Line line; lines.next(line);) {
    if (line.fields.size() != 2)
      throw badLine(
          depth_path, line,
          "expected 2 fields 'timestamp filename', found " + std::to_string(line.fields.size()));
    const double t = parseField<double>(depth_path, line, 0, "the timestamp");
    first = sequence.images_listed == 0 ? t : std::min(first, t);
    last = sequence.images_listed == 0 ? t : std::max(last, t);
    checkImageName(depth_path, line, "depth.txt", "depth/1305031102.160407.png");
    ++sequence.images_listed;
    // The nearest pose: the first at or after t, or the one before it (the earlier on a tie).
    const auto after =
        std::lower_bound(poses.begin(), poses.end(), t,
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
    if (frame_taken) frame_taken(frame);
    sequence.frames.push_back(std::move(frame));
  }
  if (sequence.images_listed == 0)
    throw Error(ErrorCode::kFormat,
                "'" + depth_path +
                    "' lists no images (only comments or blank lines); it needs lines "
                    "'timestamp filename'");
  if (sequence.frames.empty()) {
    throw Error(ErrorCode::kFormat,
                "no image of '" + depth_path + "' has a ground-truth pose less than " +
                    seconds(max_time_difference_s) + " s away (images " + seconds(first) + " to " +
                    seconds(last) + " s, poses " + seconds(poses.front().timestamp) + " to " +
                    seconds(poses.back().timestamp) +
                    " s); check that groundtruth.txt belongs to this sequence");
  }
  return sequence;
}

std::vector<ListedImage> parseImageList(std::string_view text, const std::string& name) {
  ByteSource source(text);
  return parseImageList(source, name);
}

std::vector<ListedImage> parseImageList(ByteSource& source, const std::string& path) {
  std::vector<ListedImage> images;
  DataLines lines(source, path);
  for (Line line; lines.next(line);) {
    if (line.fields.size() != 2)
      throw badLine(
          path, line,
          "expected 2 fields 'timestamp filename', found " + std::to_string(line.fields.size()));
    ListedImage image;
    image.timestamp = parseField<double>(path, line, 0, "the timestamp");
    checkImageName(path, line, "rgb.txt", "rgb/1305031102.175304.png");
    image.name = line.fields[1];
    image.line = line.number;
    images.push_back(std::move(image));
  }
  if (images.empty())
    throw Error(ErrorCode::kFormat, "'" + path +
                                        "' lists no images (only comments or blank lines); it "
                                        "needs lines 'timestamp filename'");
  return images;
}

void associateColorImages(TumSequence& sequence, std::vector<ListedImage> images,
                          const TumListNames& names, double max_time_difference_s) {
  if (images.empty())
    throw Error(ErrorCode::kFormat, "'" + names.rgb +
                                        "' lists no images (only comments or blank lines); it "
                                        "needs lines 'timestamp filename'");
  sequence.color_images = images.size();
  std::stable_sort(images.begin(), images.end(),
                   [](const auto& a, const auto& b) { return a.timestamp < b.timestamp; });
  const fs::path root(names.dir);
  for (TumFrame& frame : sequence.frames) {
    const double t = frame.timestamp;
    // The nearest image, as for poses: the first at or after t, or the one before it (the
    // earlier on a tie).
    const auto after = std::lower_bound(
        images.begin(), images.end(), t,
        [](const ListedImage& image, double time) { return image.timestamp < time; });
    auto nearest = after;
    if (after == images.end() ||
        (after != images.begin() && t - std::prev(after)->timestamp <= after->timestamp - t))
      nearest = std::prev(after);
    const double gap = std::abs(nearest->timestamp - t);
    if (!(gap < max_time_difference_s))
      throw Error(ErrorCode::kFormat,
                  "'" + names.depth + "' line " + std::to_string(frame.line) + ": depth image " +
                      seconds(t) + " ('" + frame.image_path + "') has no colour image in '" +
                      names.rgb + "' less than " + seconds(max_time_difference_s) +
                      " s away (the nearest, " + seconds(nearest->timestamp) + " on line " +
                      std::to_string(nearest->line) + ", is " + seconds(gap) +
                      " s away); a colour map needs a colour image for every depth image with "
                      "a pose: check that rgb.txt belongs to this sequence, or leave the image "
                      "out of depth.txt");
    frame.color_path = (root / nearest->name).string();
    frame.color_timestamp = nearest->timestamp;
    frame.color_line = nearest->line;
  }
}

}  // namespace io

namespace {

// Checks that the image `path`, which a list names, exists inside the folder `real_root`
// (canonical) and is a regular file; `where` begins the messages (list, line and image).
void checkImageFile(const std::string& path, const fs::path& real_root, const std::string& where) {
  std::error_code exists_ec;
  if (!fs::exists(path, exists_ec))
    throw Error(ErrorCode::kIo, where + " does not exist; check the folder is complete");
  // A symbolic link (of the image or of a folder on its way) that leads out of the folder reads
  // any file on the machine, as an absolute or '..' name would: refused alike.
  std::error_code real_ec;
  const fs::path real = fs::canonical(path, real_ec);
  if (real_ec) throw Error(ErrorCode::kIo, where + " cannot be resolved: " + real_ec.message());
  const fs::path inside = real.lexically_relative(real_root);
  if (inside.empty() || *inside.begin() == "..")
    throw Error(ErrorCode::kIo, where + " leads through a symbolic link to '" + real.string() +
                                    "', outside the folder '" + real_root.string() +
                                    "'; images are read from inside the folder only: copy the "
                                    "image into it");
  if (!fs::is_regular_file(real, exists_ec))
    throw Error(ErrorCode::kIo, where + " is not a regular file; check the folder is complete");
}

TumSequence readSequence(const std::string& dir, double max_time_difference_s, TumColor color) {
  const fs::path root(dir);
  std::error_code ec;
  if (!fs::is_directory(root, ec))
    throw Error(ErrorCode::kIo, "'" + dir +
                                    "' is not a directory; give a TUM RGB-D folder "
                                    "(with depth.txt and groundtruth.txt)");
  io::TumListNames names;
  names.dir = dir;
  names.groundtruth = (root / "groundtruth.txt").string();
  names.depth = (root / "depth.txt").string();
  names.rgb = (root / "rgb.txt").string();
  // The folder as the lists and images are resolved against it (it may itself be reached by a
  // link).
  const fs::path real_root = fs::canonical(root, ec);
  if (ec) throw Error(ErrorCode::kIo, "cannot resolve the folder '" + dir + "': " + ec.message());
  // The lists are read as they are parsed: memory follows their lines, not their size.
  std::uintmax_t size = 0;
  std::ifstream groundtruth = openList(names.groundtruth, real_root, &size);
  io::ByteSource groundtruth_bytes(groundtruth, size, names.groundtruth);
  std::vector<io::GroundTruthPose> poses =
      io::parseGroundTruth(groundtruth_bytes, names.groundtruth);
  std::ifstream depth = openList(names.depth, real_root, &size);
  io::ByteSource depth_bytes(depth, size, names.depth);
  TumSequence sequence = io::associateDepthList(
      depth_bytes, std::move(poses), names, max_time_difference_s, [&](const TumFrame& frame) {
        checkImageFile(frame.image_path, real_root,
                       "'" + names.depth + "' line " + std::to_string(frame.line) +
                           ": depth image '" + frame.image_path + "'");
      });
  if (color == TumColor::kRgbTxt) {
    std::ifstream rgb = openList(names.rgb, real_root, &size);
    io::ByteSource rgb_bytes(rgb, size, names.rgb);
    io::associateColorImages(sequence, io::parseImageList(rgb_bytes, names.rgb), names,
                             max_time_difference_s);
    for (const TumFrame& frame : sequence.frames)
      checkImageFile(frame.color_path, real_root,
                     "'" + names.rgb + "' line " + std::to_string(frame.color_line) +
                         ": colour image '" + frame.color_path + "'");
  }
  return sequence;
}

}  // namespace

TumSequence readTumSequence(const std::string& dir, double max_time_difference_s, TumColor color) {
  return hostMemoryGuard("readTumSequence",
                         [&] { return readSequence(dir, max_time_difference_s, color); });
}

DepthImage DepthPng::image(const CameraIntrinsics& camera) const {
  DepthImage out;
  out.width = width;
  out.height = height;
  out.encoding = DepthImage::Encoding::kUint16;
  out.depths = std::span<const std::uint16_t>(depths);
  out.fx = camera.fx;
  out.fy = camera.fy;
  out.cx = camera.cx;
  out.cy = camera.cy;
  out.depth_scale = camera.depth_scale;
  return out;
}

namespace {

// What a PNG is read as: a depth image (16-bit grayscale) or a colour image (8-bit RGB, RGBA,
// grayscale or grayscale+alpha).
enum class PngKind { kDepth, kColor };

const char* pngNoun(PngKind kind) {
  return kind == PngKind::kDepth ? "depth image" : "colour image";
}

const char* pngFormats(PngKind kind) {
  return kind == PngKind::kDepth ? "depth images must be 16-bit grayscale PNGs"
                                 : "colour images must be 8-bit RGB, RGBA or grayscale PNGs";
}

// The bytes a pixel of an accepted format takes in the file, before deflate.
std::uint64_t pngPixelBytes(PngKind kind, int color_type) {
  if (kind == PngKind::kDepth) return 2;
  switch (color_type) {
    case PNG_COLOR_TYPE_GRAY:
      return 1;
    case PNG_COLOR_TYPE_GRAY_ALPHA:
      return 2;
    case PNG_COLOR_TYPE_RGB:
      return 3;
    default:
      return 4;
  }
}

bool acceptedFormat(PngKind kind, int bit_depth, int color_type) {
  if (kind == PngKind::kDepth) return bit_depth == 16 && color_type == PNG_COLOR_TYPE_GRAY;
  return bit_depth == 8 &&
         (color_type == PNG_COLOR_TYPE_GRAY || color_type == PNG_COLOR_TYPE_GRAY_ALPHA ||
          color_type == PNG_COLOR_TYPE_RGB || color_type == PNG_COLOR_TYPE_RGB_ALPHA);
}

// Reads the header of the PNG in `r` (its source set); throws unless it is of a format `kind`
// accepts and its bytes can hold its pixels, with at most `max_pixels` pixels (0: no limit).
// Its colour type in `color_type`.
void readPngHeader(PngReader& r, const std::string& path, PngKind kind, png_uint_32* width,
                   png_uint_32* height, std::uint64_t max_pixels, int* color_type) {
  const std::string noun = pngNoun(kind);
  unsigned char signature[8];
  if (r.read(signature, 8) != 8 || png_sig_cmp(signature, 0, 8) != 0)
    throw Error(ErrorCode::kFormat,
                noun + " '" + path + "' is not a PNG file; " + pngFormats(kind));
  r.png = png_create_read_struct(PNG_LIBPNG_VER_STRING, &r, pngError, pngWarning);
  if (r.png) r.info = png_create_info_struct(r.png);
  if (!r.png || !r.info)
    throw Error(ErrorCode::kIo, "cannot read " + noun + " '" + path + "': libpng is out of memory");
  limitPngMemory(r.png);

  int bit_depth = 0;
  if (!pngReadHeader(r, width, height, &bit_depth, color_type))
    throw Error(ErrorCode::kFormat,
                noun + " '" + path +
                    "' is a corrupt or truncated PNG (libpng: " + std::string(r.message) + ")");
  if (!acceptedFormat(kind, bit_depth, *color_type))
    throw Error(ErrorCode::kFormat,
                noun + " '" + path + "' is a " + colorTypeName(*color_type) + " PNG of bit depth " +
                    std::to_string(bit_depth) + "; " + pngFormats(kind) +
                    (kind == PngKind::kColor && bit_depth == 16
                         ? " (16-bit colour is not read: convert the images to 8 bits)"
                         : ""));
  // libpng's user limit refuses these first (a "corrupt" PNG whose message says so); kept for a
  // libpng built without user limits.
  if (*width > kMaxPngSide || *height > kMaxPngSide)
    throw Error(ErrorCode::kFormat, noun + " '" + path + "' is " + std::to_string(*width) + " x " +
                                        std::to_string(*height) + " pixels; at most " +
                                        std::to_string(kMaxPngSide) + " in each direction");
  // The pixels' bytes as deflate's input: a filter byte and the pixels' bytes per row (interlaced
  // images need more). Deflate shrinks data at most 1032-fold, so a file too small to hold them is
  // cut short or damaged: refused before its pixels are allocated (a few kB of file could
  // otherwise claim 8 GiB).
  const std::uint64_t raw =
      std::uint64_t{*height} * (1 + pngPixelBytes(kind, *color_type) * std::uint64_t{*width});
  if (r.source_size > 0 && raw > io::kDeflateMaxRatio * r.source_size)
    throw Error(ErrorCode::kFormat,
                noun + " '" + path + "' is a corrupt or truncated PNG: its header announces " +
                    std::to_string(*width) + " x " + std::to_string(*height) +
                    " pixels, more than its " + std::to_string(r.source_size) + " bytes can hold");
  // Refused from the header, before its pixels are decoded (a 530 kB PNG can hold 16000 x 16000).
  const std::uint64_t pixels = std::uint64_t{*width} * *height;
  if (max_pixels != 0 && pixels > max_pixels)
    throw Error(ErrorCode::kInvalidArgument,
                noun + " '" + path + "' is " + std::to_string(*width) + " x " +
                    std::to_string(*height) + " = " + std::to_string(pixels) +
                    " pixels; a scan takes at most " + std::to_string(max_pixels) +
                    " points on this device: scale the image down or crop it");
}

// Opens the file `path` in `r` and reads its header (see readPngHeader).
void openPng(PngReader& r, const std::string& path, PngKind kind, png_uint_32* width,
             png_uint_32* height, std::uint64_t max_pixels, int* color_type) {
  r.file = std::fopen(path.c_str(), "rb");
  if (!r.file)
    throw Error(ErrorCode::kIo, std::string("cannot read ") + pngNoun(kind) + " '" + path +
                                    "': " + std::strerror(errno));
  std::error_code ec;
  if (fs::is_regular_file(path, ec)) r.source_size = fs::file_size(path, ec);
  if (ec) r.source_size = 0;
  readPngHeader(r, path, kind, width, height, max_pixels, color_type);
}

// Reads the pixels of the PNG in `r`, whose header has been read.
DepthPng readDepthPngPixels(PngReader& r, const std::string& path, png_uint_32 width,
                            png_uint_32 height) {
  DepthPng out;
  out.width = width;
  out.height = height;
  out.depths.resize(std::size_t{width} * height);
  std::vector<png_bytep> rows(height);
  for (png_uint_32 y = 0; y < height; ++y)
    rows[y] = reinterpret_cast<png_bytep>(out.depths.data() + std::size_t{y} * width);
  if (!pngReadRows(r, rows.data()))
    throw Error(ErrorCode::kFormat,
                "depth image '" + path +
                    "' is a corrupt or truncated PNG (libpng: " + std::string(r.message) + ")");
  return out;
}

// libpng turns every accepted colour format into 3 bytes a pixel, r g b: the layout of Rgb.
static_assert(sizeof(Rgb) == 3 && alignof(Rgb) == 1);

bool pngReadColorRows(PngReader& r, png_bytepp rows, int color_type) {
  if (setjmp(png_jmpbuf(r.png))) return false;
  if (color_type & PNG_COLOR_MASK_ALPHA) png_set_strip_alpha(r.png);
  if (!(color_type & PNG_COLOR_MASK_COLOR)) png_set_gray_to_rgb(r.png);
  png_read_image(r.png, rows);
  png_read_end(r.png, nullptr);
  return true;
}

// Reads the pixels of the colour PNG in `r`, whose header has been read.
ColorPng readColorPngPixels(PngReader& r, const std::string& path, png_uint_32 width,
                            png_uint_32 height, int color_type) {
  ColorPng out;
  out.width = width;
  out.height = height;
  out.colors.resize(std::size_t{width} * height);
  std::vector<png_bytep> rows(height);
  for (png_uint_32 y = 0; y < height; ++y)
    rows[y] = reinterpret_cast<png_bytep>(out.colors.data() + std::size_t{y} * width);
  if (!pngReadColorRows(r, rows.data(), color_type))
    throw Error(ErrorCode::kFormat,
                "colour image '" + path +
                    "' is a corrupt or truncated PNG (libpng: " + std::string(r.message) + ")");
  return out;
}

}  // namespace

namespace {

// `f(reader, width, height, colour type)` on the PNG file `path` once its header passed
// openPng's checks for `kind`, under `call`'s host-memory guard.
template <typename F>
auto withPngFile(const char* call, const std::string& path, PngKind kind, std::uint64_t max_pixels,
                 F&& f) {
  return hostMemoryGuard(call, [&] {
    PngReader r;
    png_uint_32 width = 0, height = 0;
    int color_type = 0;
    openPng(r, path, kind, &width, &height, max_pixels, &color_type);
    return f(r, width, height, color_type);
  });
}

}  // namespace

DepthPngSize checkDepthPng(const std::string& path, std::uint64_t max_pixels) {
  return withPngFile("checkDepthPng", path, PngKind::kDepth, max_pixels,
                     [](PngReader&, png_uint_32 w, png_uint_32 h, int) {
                       return DepthPngSize{w, h};
                     });
}

DepthPng readDepthPng(const std::string& path, std::uint64_t max_pixels) {
  return withPngFile("readDepthPng", path, PngKind::kDepth, max_pixels,
                     [&](PngReader& r, png_uint_32 w, png_uint_32 h, int) {
                       return readDepthPngPixels(r, path, w, h);
                     });
}

DepthPng io::decodeDepthPng(std::string_view bytes, const std::string& name) {
  PngReader r;
  r.memory = bytes;
  r.source_size = bytes.size();
  png_uint_32 width = 0, height = 0;
  int color_type = 0;
  readPngHeader(r, name, PngKind::kDepth, &width, &height, 0, &color_type);
  return readDepthPngPixels(r, name, width, height);
}

DepthPngSize checkColorPng(const std::string& path, std::uint64_t max_pixels) {
  return withPngFile("checkColorPng", path, PngKind::kColor, max_pixels,
                     [](PngReader&, png_uint_32 w, png_uint_32 h, int) {
                       return DepthPngSize{w, h};
                     });
}

ColorPng readColorPng(const std::string& path, std::uint64_t max_pixels) {
  return withPngFile("readColorPng", path, PngKind::kColor, max_pixels,
                     [&](PngReader& r, png_uint_32 w, png_uint_32 h, int color_type) {
                       return readColorPngPixels(r, path, w, h, color_type);
                     });
}

ColorPng io::decodeColorPng(std::string_view bytes, const std::string& name) {
  PngReader r;
  r.memory = bytes;
  r.source_size = bytes.size();
  png_uint_32 width = 0, height = 0;
  int color_type = 0;
  readPngHeader(r, name, PngKind::kColor, &width, &height, 0, &color_type);
  return readColorPngPixels(r, name, width, height, color_type);
}

}  // namespace octovk
