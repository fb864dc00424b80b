// The bytes-in half of the TUM RGB-D reader (src/io/tum_sequence.cpp): depth.txt, groundtruth.txt
// and rgb.txt from their contents, and a 16-bit PNG depth image or an 8-bit colour PNG from memory.
// No file system: readTumSequence and readDepthPng read the files and call these, and the unit
// tests and the fuzz targets (tests/fuzz/fuzz_tum_lists.cpp, fuzz_depth_png.cpp) call them on bytes
// directly.
#pragma once

#include <cstdint>
#include <functional>
#include <string>
#include <string_view>
#include <vector>

#include "io/byte_source.hpp"
#include "octovk/tum_sequence.hpp"

namespace octovk::io {

/// The names a TUM sequence's messages use and the folder its image names are joined to.
struct TumListNames {
  std::string dir;          ///< joined with each image's file name (TumFrame::image_path)
  std::string depth;        ///< names depth.txt in messages
  std::string groundtruth;  ///< names groundtruth.txt in messages
  std::string rgb;          ///< names rgb.txt in messages
};

/// One line of rgb.txt: an image's timestamp, its file name as listed and the line (1-based).
struct ListedImage {
  double timestamp = 0.0;
  std::string name;
  std::size_t line = 0;
};

/// One line of groundtruth.txt.
struct GroundTruthPose {
  double timestamp = 0.0;
  Pose pose;
};

/// Parses the contents of groundtruth.txt (`timestamp tx ty tz qx qy qz qw` per line; '#' comment
/// lines and blank lines skipped, a trailing '\r' ignored, a line over 64 KiB refused), in the
/// file's order. Throws
/// Error(kFormat) naming `name` and the line for a malformed line or a non-unit quaternion, or
/// when no pose is listed.
std::vector<GroundTruthPose> parseGroundTruth(std::string_view text, const std::string& name);
/// parseGroundTruth on a file read line by line as it is parsed (readTumSequence).
std::vector<GroundTruthPose> parseGroundTruth(ByteSource& source, const std::string& name);

/// Parses the contents of depth.txt (`timestamp filename` per line) and gives each image the
/// nearest of `poses` as readTumSequence does, with its checks and errors (kFormat, naming
/// `names.depth` and the line). `frame_taken`, when set, is called for each image that takes a
/// pose, in depth.txt's order, before the next line is parsed (readTumSequence checks there that
/// the image file exists). Empty `poses` are refused as groundtruth.txt listing none.
TumSequence associateDepthList(std::string_view text, std::vector<GroundTruthPose> poses,
                               const TumListNames& names, double max_time_difference_s,
                               const std::function<void(const TumFrame&)>& frame_taken = {});
/// associateDepthList on a file read line by line as it is parsed (readTumSequence).
TumSequence associateDepthList(ByteSource& source, std::vector<GroundTruthPose> poses,
                               const TumListNames& names, double max_time_difference_s,
                               const std::function<void(const TumFrame&)>& frame_taken = {});

/// Parses the contents of rgb.txt (`timestamp filename` per line, as depth.txt: the same comment,
/// blank-line and file-name rules), in the file's order. Throws Error(kFormat) naming `name` and
/// the line for a malformed line or a name that is absolute or has a '..', or when no image is
/// listed.
std::vector<ListedImage> parseImageList(std::string_view text, const std::string& name);
/// parseImageList on a file read line by line as it is parsed (readTumSequence).
std::vector<ListedImage> parseImageList(ByteSource& source, const std::string& name);

/// Gives every frame of `sequence` the image of `images` nearest in time (the earlier on a tie;
/// an image may serve several frames) as readTumSequence does with TumColor::kRgbTxt: its path
/// joined to `names.dir`, timestamp and line; a frame with none less than
/// `max_time_difference_s` away is a kFormat error naming the frame's image and depth.txt line,
/// the nearest image and the limit. Sets sequence.color_images. Empty `images` are refused.
void associateColorImages(TumSequence& sequence, std::vector<ListedImage> images,
                          const TumListNames& names, double max_time_difference_s);

/// Decodes a 16-bit grayscale PNG held in memory as readDepthPng decodes a file, with the same
/// checks and errors (kFormat) naming `name`.
DepthPng decodeDepthPng(std::string_view bytes, const std::string& name);

/// Decodes an 8-bit colour PNG held in memory as readColorPng decodes a file, with the same
/// checks and errors (kFormat) naming `name`.
ColorPng decodeColorPng(std::string_view bytes, const std::string& name);

/// The largest factor by which deflate can shrink data (zlib's documented bound, 1032:1): a PNG
/// of N bytes cannot hold more than kDeflateMaxRatio * N bytes of image data, so a header
/// announcing more is a truncated or corrupt file, refused before its pixels are allocated.
inline constexpr std::uint64_t kDeflateMaxRatio = 1032;

}  // namespace octovk::io
