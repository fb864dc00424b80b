// libFuzzer target of the TUM RGB-D list reader (readTumSequence's parser): the input is
// groundtruth.txt's contents, a NUL byte, then depth.txt's (no NUL: all of it is groundtruth.txt
// and depth.txt is empty). A refusal must be a kFormat error; an accepted sequence must count its
// images consistently, and every frame must take a finite pose of unit-ish rotation less than
// kTumMaxTimeDifference away and an image name with no '..' in it. Anything else (a crash, a
// sanitizer report, a hang, an allocation past -rss_limit_mb) is a finding.
#include <algorithm>
#include <cmath>
#include <cstdint>
#include <cstdlib>
#include <filesystem>
#include <string>
#include <string_view>

#include "io/tum_parse.hpp"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  const std::string_view bytes(reinterpret_cast<const char*>(data), size);
  const std::size_t nul = bytes.find('\0');
  const std::string_view groundtruth = bytes.substr(0, nul);
  const std::string_view depth =
      nul == std::string_view::npos ? std::string_view() : bytes.substr(nul + 1);
  const octovk::io::TumListNames names{"fuzz-dir", "fuzz-dir/depth.txt",
                                       "fuzz-dir/groundtruth.txt"};
  octovk::TumSequence sequence;
  std::size_t taken = 0;
  try {
    std::vector<octovk::io::GroundTruthPose> poses =
        octovk::io::parseGroundTruth(groundtruth, names.groundtruth);
    sequence = octovk::io::associateDepthList(depth, std::move(poses), names,
                                              octovk::kTumMaxTimeDifference,
                                              [&](const octovk::TumFrame&) { ++taken; });
  } catch (const octovk::Error& e) {
    if (e.code() != octovk::ErrorCode::kFormat) std::abort();
    return 0;
  }
  if (sequence.frames.empty() || sequence.poses == 0 || taken != sequence.frames.size() ||
      sequence.frames.size() + sequence.skipped_no_pose != sequence.images_listed)
    std::abort();
  for (const octovk::TumFrame& frame : sequence.frames) {
    if (!std::isfinite(frame.timestamp) || !std::isfinite(frame.pose_timestamp) ||
        !(std::abs(frame.timestamp - frame.pose_timestamp) < octovk::kTumMaxTimeDifference) ||
        frame.line == 0 || frame.image_path.rfind("fuzz-dir/", 0) != 0)
      std::abort();
    // Inside the folder by name: no '..' climbs out (links are the file reader's to check).
    const std::filesystem::path name(frame.image_path);
    if (std::any_of(name.begin(), name.end(), [](const auto& part) { return part == ".."; }))
      std::abort();
    const octovk::Pose& pose = frame.T_world_camera;
    if (!pose.translation.allFinite() || !pose.rotation.coeffs().allFinite() ||
        std::abs(static_cast<double>(pose.rotation.norm()) - 1.0) > 0.011)
      std::abort();
  }
  return 0;
}
