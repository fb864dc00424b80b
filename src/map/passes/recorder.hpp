// What every pass's host function records with: the device's passes, the command stream and the
// map's buffers, and the one way to dispatch a pass (push constants checked against gpu_types.h).
#pragma once

#include <cstddef>
#include <cstdint>
#include <type_traits>

#include "map/map_buffers.hpp"
#include "octovk/gpu_types.h"
#include "vk/device.hpp"

namespace octovk::passes {

inline std::uint32_t groupsFor(std::size_t items) {
  return static_cast<std::uint32_t>((items + gpu::kWorkgroupSize - 1) / gpu::kWorkgroupSize);
}

class Recorder {
 public:
  Recorder(vk::Device& device, vk::CommandStream& stream, MapBuffers& buffers)
      : device(device), stream(stream), buffers(buffers) {}

  /// One invocation per work item; each pass reads the 16-byte push range as its own struct
  /// from gpu_types.h, spelled out at the call (NoConstants for the passes that take none).
  template <typename Constants>
  void dispatch(const char* pass, std::size_t items, const Constants& pc) {
    checkConstants<Constants>();
    stream.dispatch(device.pass(pass), groupsFor(items), &pc, sizeof(pc));
    stream.barrier();
  }
  void dispatch(const char* pass, std::size_t items) { dispatch(pass, items, gpu::NoConstants{}); }

  /// Groups read from the scan counters at byte `args_offset` (a DispatchArgs).
  template <typename Constants>
  void dispatchIndirect(const char* pass, std::size_t args_offset, const Constants& pc) {
    checkConstants<Constants>();
    stream.dispatchIndirect(device.pass(pass), buffers.counters, args_offset, &pc, sizeof(pc));
    stream.barrier();
  }
  void dispatchIndirect(const char* pass, std::size_t args_offset) {
    dispatchIndirect(pass, args_offset, gpu::NoConstants{});
  }

  /// `rounds` indirect dispatches of `pass` that continue the walks listed in the two lists of
  /// ScanCounters::walk_count, alternately: each round empties the other list, then continues
  /// the listed walks, which list the ones still unfinished in it. `constants(from, last)`
  /// gives the push constants for the round that continues list `from` (`last`: the last one).
  template <typename MakeConstants>
  void continuations(const char* pass, std::uint32_t rounds, MakeConstants constants) {
    for (std::uint32_t round = 0; round < rounds; ++round) {
      const std::uint32_t from = round % 2, to = 1 - from;
      stream.fill(buffers.counters, 0u, offsetof(gpu::ScanCounters, walk_count) + 4 * to, 4);
      stream.fill(buffers.counters, 0u,
                  offsetof(gpu::ScanCounters, walk_args) + to * sizeof(gpu::DispatchArgs), 4);
      stream.barrier();
      dispatchIndirect(pass,
                       offsetof(gpu::ScanCounters, walk_args) + from * sizeof(gpu::DispatchArgs),
                       constants(from, round + 1 == rounds));
    }
  }

  vk::Device& device;
  vk::CommandStream& stream;
  MapBuffers& buffers;

 private:
  template <typename Constants>
  static void checkConstants() {
    static_assert(
        sizeof(Constants) == sizeof(gpu::PassConstants) && std::is_trivially_copyable_v<Constants>,
        "push constants are one of gpu_types.h's 16-byte structs");
  }
};

}  // namespace octovk::passes
