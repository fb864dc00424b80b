// Depth-image sequences in the TUM RGB-D layout
// (https://cvg.cit.tum.de/data/datasets/rgbd-dataset): DIR/depth.txt, DIR/groundtruth.txt and
// 16-bit grayscale PNG depth images, and for colour DIR/rgb.txt and its 8-bit colour PNGs.
#pragma once

#include <cstddef>
#include <cstdint>
#include <string>
#include <vector>

#include "octovk/octovk.hpp"

namespace octovk {

/// Largest gap between an image's timestamp and the ground-truth pose it takes (seconds, TUM's).
inline constexpr double kTumMaxTimeDifference = 0.02;

/// A pinhole camera and depth scale; the defaults are TUM RGB-D's (the ROS default intrinsics,
/// depth in 1/5000 m).
struct CameraIntrinsics {
  float fx = 525.0f, fy = 525.0f, cx = 319.5f, cy = 239.5f;
  float depth_scale = 5000.0f;  ///< depth units per metre
};

/// One image of a sequence that has a ground-truth pose.
struct TumFrame {
  double timestamp = 0.0;       ///< of the image (depth.txt)
  double pose_timestamp = 0.0;  ///< of the ground-truth pose it takes (groundtruth.txt)
  std::string image_path;       ///< DIR joined with the file name depth.txt gives
  std::size_t line = 0;         ///< line of depth.txt that lists the image (1-based)
  /// The camera in the world, as octomath::Pose6D(Vector3(tx, ty, tz), Quaternion(qw, qx, qy,
  /// qz)) with the values read as float.
  Pose T_world_camera;
  /// With TumColor::kRgbTxt: the colour image of rgb.txt nearest in time (registered to the depth
  /// image: pixel (u, v) of one is pixel (u, v) of the other). Empty without colour.
  std::string color_path;        ///< DIR joined with the file name rgb.txt gives
  double color_timestamp = 0.0;  ///< its timestamp (rgb.txt)
  std::size_t color_line = 0;    ///< line of rgb.txt that lists it (1-based); 0 without colour
};

/// What a sequence folder lists: the images that have a pose, in depth.txt's order.
struct TumSequence {
  std::string dir;
  std::vector<TumFrame> frames;
  std::size_t images_listed = 0;    ///< images listed in depth.txt
  std::size_t skipped_no_pose = 0;  ///< of those, without a pose within the time difference
  std::size_t poses = 0;            ///< poses listed in groundtruth.txt
  std::size_t color_images = 0;     ///< images listed in rgb.txt (0 without colour)
};

/// Whether readTumSequence gives each image a colour image.
enum class TumColor {
  kNone,    ///< depth only: rgb.txt is not read
  kRgbTxt,  ///< each image with a pose takes the image of DIR/rgb.txt nearest in time
};

/// Reads DIR/depth.txt (`timestamp filename` per line, the file name relative to DIR) and
/// DIR/groundtruth.txt (`timestamp tx ty tz qx qy qz qw` per line); '#' starts a comment line,
/// blank lines are ignored. Each image takes the pose with the nearest timestamp (the earlier one
/// on a tie); images with none less than `max_time_difference_s` away are skipped and counted.
/// Checks that every image taken exists, but does not read it. The lists are read a line at a
/// time (a line over 64 KiB is malformed), and like the images they must lie inside DIR: a list
/// or image that is a symbolic link out of it is refused (kIo). Throws Error: kIo for a missing or
/// unreadable file, kFormat for a malformed line (the message names file and line; an absolute
/// image name is one), a non-unit quaternion, no images, no poses, or no image with a pose.
/// With TumColor::kRgbTxt it also reads DIR/rgb.txt (`timestamp filename`, as depth.txt, its
/// images inside DIR alike) and gives every image that has a pose the colour image nearest in
/// time (the earlier on a tie; one colour image may serve several depth images), checking that it
/// exists; an image with none less than `max_time_difference_s` away is a kFormat error naming
/// it, its depth.txt line, the nearest colour image and the limit (a colour map would otherwise
/// hold scans without colour), and so is an rgb.txt listing no image.
TumSequence readTumSequence(const std::string& dir,
                            double max_time_difference_s = kTumMaxTimeDifference,
                            TumColor color = TumColor::kNone);

/// A depth image read from a 16-bit grayscale PNG (TUM's format): depths row by row, in host order.
struct DepthPng {
  std::uint32_t width = 0;
  std::uint32_t height = 0;
  std::vector<std::uint16_t> depths;

  /// A DepthImage over these depths (valid while this object lives and is unchanged).
  DepthImage image(const CameraIntrinsics& camera) const;
};

/// Reads a PNG depth image. Only 16-bit grayscale is accepted: other bit depths and colour types
/// are refused with a kFormat error naming the file, its bit depth and colour type; an unreadable
/// or corrupt file is a kIo / kFormat error naming the file. A header announcing more pixels than
/// the file's bytes can hold (deflate shrinks at most 1032:1) is refused as corrupt before any
/// pixel memory is allocated, and so is one announcing more than `max_pixels` (when not 0; e.g.
/// maxDepthImagePixels(context)), as a kInvalidArgument error naming the limit.
DepthPng readDepthPng(const std::string& path, std::uint64_t max_pixels = 0);

/// A depth image's size, as its PNG header gives it.
struct DepthPngSize {
  std::uint32_t width = 0;
  std::uint32_t height = 0;
};

/// Reads only the header of a PNG depth image, throwing what readDepthPng would for a missing,
/// unreadable or non-PNG file, a wrong format or more than `max_pixels` pixels (not for damage
/// further in); its size.
DepthPngSize checkDepthPng(const std::string& path, std::uint64_t max_pixels = 0);

/// A colour image read from an 8-bit PNG (TUM's rgb images): colours row by row.
struct ColorPng {
  std::uint32_t width = 0;
  std::uint32_t height = 0;
  std::vector<Rgb> colors;  ///< width * height, for ScanOptions::colors of the depth image
};

/// Reads a PNG colour image. Accepted: 8-bit RGB, RGBA (the alpha dropped), grayscale (grey
/// colours) and grayscale+alpha; other bit depths (16-bit colour) and palette images are refused
/// with a kFormat error naming the file, its bit depth and colour type. Other errors and
/// `max_pixels` as readDepthPng.
ColorPng readColorPng(const std::string& path, std::uint64_t max_pixels = 0);

/// Reads only the header of a PNG colour image, throwing what readColorPng would for a missing,
/// unreadable or non-PNG file, a wrong format or more than `max_pixels` pixels; its size.
DepthPngSize checkColorPng(const std::string& path, std::uint64_t max_pixels = 0);

/// The most pixels a depth image may have to be inserted into a map on `context` in one scan
/// (the device's limit on a scan's points), to check a PNG's header against before decoding it.
std::uint64_t maxDepthImagePixels(Context& context);

}  // namespace octovk
