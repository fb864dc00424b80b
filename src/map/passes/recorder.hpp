// What every pass's host function records with: the device's passes, the command stream and the
// map's buffers, the one way to dispatch a pass (by its typed handle, with the push constants its
// shader declares: both checked at compile time) and the named timestamps of a scan.
#pragma once

#include <algorithm>
#include <array>
#include <cstddef>
#include <cstdint>
#include <type_traits>
#include <vector>

#include "gpu/gpu_types.h"
#include "map/map_buffers.hpp"
#include "shader_ids.hpp"
#include "vk/device.hpp"

namespace octovk::passes {

inline std::uint32_t groupsFor(std::size_t items) {
  return static_cast<std::uint32_t>((items + gpu::kWorkgroupSize - 1) / gpu::kWorkgroupSize);
}

using vk::Shader;

/// The points of a scan's recording that its device timestamps mark, by name: StageTimes are the
/// spans between them (stageTimes()).
enum class Stamp : std::uint8_t {
  kScanStart,      ///< before the scan's uploads
  kUploaded,       ///< its inputs and parameters are on the device
  kBoxesStart,     ///< ScanRays::kRayTracing: the scene's boxes begin
  kBoxesEnd,       ///< and end
  kBuildEnd,       ///< the scene's acceleration structure is built
  kClassifyStart,  ///< the ray keys (walked or traced) are done
  kClassifyEnd,
  kTreeUpdateEnd,
  kPruneEnd,
  kLeafBoxesEnd,
  kCount
};

class Recorder {
 public:
  Recorder(vk::Device& device, vk::CommandStream& stream, MapBuffers& buffers)
      : device(device), stream(stream), buffers(buffers), stamps_(stream.frames()) {}

  /// One invocation per work item, with the push constants shader S declares (its
  /// vk::ShaderConstants, read from its source at build time): another struct does not compile.
  template <Shader S>
  void dispatch(std::size_t items, const typename vk::ShaderConstants<S>::type& pc) {
    stream.dispatch(device.pass(vk::shaderName(S)), groupsFor(items), &pc, sizeof(pc));
    stream.barrier();
  }
  /// The same for a shader without push constants.
  template <Shader S>
  requires std::is_same_v<typename vk::ShaderConstants<S>::type, gpu::NoConstants>
  void dispatch(std::size_t items) { dispatch<S>(items, gpu::NoConstants{}); }

  /// Groups read from the scan counters at byte `args_offset` (a DispatchArgs).
  template <Shader S>
  void dispatchIndirect(std::size_t args_offset, const typename vk::ShaderConstants<S>::type& pc) {
    stream.dispatchIndirect(device.pass(vk::shaderName(S)), buffers.counters, args_offset, &pc,
                            sizeof(pc));
    stream.barrier();
  }
  template <Shader S>
  requires std::is_same_v<typename vk::ShaderConstants<S>::type, gpu::NoConstants>
  void dispatchIndirect(std::size_t args_offset) {
    dispatchIndirect<S>(args_offset, gpu::NoConstants{});
  }

  /// `rounds` indirect dispatches of shader S that continue the walks listed in the two lists of
  /// ScanCounters::walk_count, alternately: each round empties the other list, then continues
  /// the listed walks, which list the ones still unfinished in it. `constants(from, last)`
  /// gives the push constants for the round that continues list `from` (`last`: the last one).
  template <Shader S, typename MakeConstants>
  void continuations(std::uint32_t rounds, MakeConstants constants) {
    for (std::uint32_t round = 0; round < rounds; ++round) {
      const std::uint32_t from = round % 2, to = 1 - from;
      stream.fill(buffers.counters, 0u, offsetof(gpu::ScanCounters, walk_count) + 4 * to, 4);
      stream.fill(buffers.counters, 0u,
                  offsetof(gpu::ScanCounters, walk_args) + to * sizeof(gpu::DispatchArgs), 4);
      stream.barrier();
      dispatchIndirect<S>(offsetof(gpu::ScanCounters, walk_args) + from * sizeof(gpu::DispatchArgs),
                          constants(from, round + 1 == rounds));
    }
  }

  /// Writes the parameters every pass reads (binding kBindParams): the one place that records
  /// into the params buffer.
  void setParams(const gpu::ScanParams& sp) { stream.update(buffers.params, &sp, sizeof(sp)); }

  /// Records a device timestamp named `stamp` in the recording under way; kScanStart forgets
  /// the frame's earlier stamps.
  void stamp(Stamp stamp) {
    Stamps& frame = stamps_[stream.frame()];
    if (stamp == Stamp::kScanStart) frame.fill(-1);
    frame[static_cast<std::size_t>(stamp)] = static_cast<std::int32_t>(stream.timestamp());
  }
  /// The device time from stamp `from` to stamp `to` of frame `frame`'s last scan, given that
  /// frame's timestamps (CommandStream::timestampsNs); 0 where either was not recorded.
  double spanMs(std::uint32_t frame, const std::vector<double>& ns, Stamp from, Stamp to) const {
    const Stamps& f = stamps_.at(frame);
    const std::int32_t a = f[static_cast<std::size_t>(from)], b = f[static_cast<std::size_t>(to)];
    if (a < 0 || b < 0 || static_cast<std::size_t>(std::max(a, b)) >= ns.size()) return 0.0;
    return (ns[static_cast<std::size_t>(b)] - ns[static_cast<std::size_t>(a)]) * 1e-6;
  }

  vk::Device& device;
  vk::CommandStream& stream;
  MapBuffers& buffers;

 private:
  using Stamps = std::array<std::int32_t, static_cast<std::size_t>(Stamp::kCount)>;
  std::vector<Stamps> stamps_;  // per frame: each stamp's timestamp index, -1 when not recorded
};

}  // namespace octovk::passes
