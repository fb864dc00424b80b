// The device probe: checks, when a Context is created, what the exact ray walk takes from the
// device (shaders/device_probe.comp), so that a device that would build a different map than
// OctoMap is refused with the operation named instead of mapping silently wrong. A passing
// verdict is kept in the cache folder (vk/disk_cache.hpp) for this device, driver and build of
// octovk, so that later processes skip the probe; OCTOVK_REPROBE=1 probes again.
#pragma once

#include <cstdint>
#include <optional>
#include <span>
#include <string>
#include <vector>

#include "gpu/gpu_types.h"
#include "octovk/octovk.hpp"

namespace octovk {
namespace vk {
class Device;
}

struct DeviceProbe {
  /// Loop iterations an invocation gets before the driver ends its loops (llvmpipe: 65535);
  /// 0 when no limit was seen within kProbeLoopIterations.
  std::uint32_t loop_limit = 0;
  /// The verdict came from the record an earlier process kept (checkDevice), not a probe.
  bool kept = false;
};

/// Iterations of the probe's loop: a limit above this is not seen (and does not matter: the
/// longest walk is 3 * 65536 steps plus its hash probes, cut into budgets well below it).
inline constexpr std::uint32_t kProbeLoopIterations = 4u << 20;

/// The probe's cases (deterministic), for tests.
std::vector<gpu::ProbeCase> deviceProbeCases();
/// What IEEE 754 gives for one case (the host's answer the device must match).
gpu::ProbeResult hostProbeResult(const gpu::ProbeCase& c);
/// int(floor(a)) where it fits an int, else 0: what the probe's conversion must give.
std::int32_t hostProbeFloor(const gpu::ProbeCase& c);

/// The first case where the device's results differ from the host's IEEE 754 answers, in words
/// (the operation, its operands, what the device gave, what IEEE 754 gives); none when all agree.
std::optional<std::string> firstProbeMismatch(std::span<const gpu::ProbeCase> cases,
                                              std::span<const gpu::ProbeResult> results,
                                              std::span<const std::int32_t> floors);

/// Tests only: the device's occupancyProbability (shaders/probability.glsl: octomap::probability,
/// 1 - 1 / (1 + exp(l)) in double) of each log-odds, through the probe shader's
/// kProbeModeProbability, for a bit-for-bit comparison with the host.
std::vector<double> deviceOccupancies(vk::Device& device, std::span<const float> log_odds);

/// Runs the probe. Fails with kMissingFeature naming the first operation whose result differs
/// from the host's (IEEE 754 double, round to nearest even), with its operands.
Result<DeviceProbe> probeDevice(vk::Device& device);

/// The probe's verdict for `device`: the one kept by an earlier process when its record was
/// written for this device, driver and octovk build (vk::Device::cacheKey) and for these very
/// probe cases and answers; else probeDevice's, kept when it passes (a failure removes the
/// record). OCTOVK_REPROBE set and not "0" ignores a kept verdict. Never fails for the record's
/// sake: a missing, corrupt or foreign record, or a cache folder that cannot be written, only
/// means the probe runs.
Result<DeviceProbe> checkDevice(vk::Device& device);

}  // namespace octovk
