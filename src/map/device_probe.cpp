#include "map/device_probe.hpp"

#include <algorithm>
#include <bit>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <limits>
#include <optional>
#include <random>
#include <span>
#include <string>
#include <vector>

#include "gpu/gpu_types.h"
#include "vk/device.hpp"
#include "vk/disk_cache.hpp"
#include "vk/startup_trace.hpp"

namespace octovk {
namespace {

using gpu::kProbeCases;
using gpu::ProbeCase;
using gpu::ProbeHeader;
using gpu::ProbeResult;

// Cases that matter to the walk: quotients and products of floats widened to double (divFloat,
// tDelta, tMax), doubles with full 53-bit significands over a wide exponent range, exact ties and
// near-ties of the float rounding, float's subnormal range and overflow, signed zeros, and the
// key conversions (floor of scaled coordinates, negative and positive).
std::vector<ProbeCase> probeCases() {
  std::vector<ProbeCase> cases;
  cases.reserve(kProbeCases);
  std::mt19937_64 rng(20261123);
  auto fromBits = [](std::uint64_t bits) { return std::bit_cast<double>(bits); };
  auto randomDouble = [&](int min_exp, int max_exp) {
    std::uniform_int_distribution<int> e(min_exp, max_exp);
    const std::uint64_t mantissa = rng() & ((1ull << 52) - 1);
    const std::uint64_t sign = (rng() & 1) << 63;
    return fromBits(sign | (static_cast<std::uint64_t>(e(rng) + 1023) << 52) | mantissa);
  };
  std::uniform_real_distribution<float> unit(-40.0f, 40.0f);
  auto push = [&](double a, double b, float fa, float fb, float fc) {
    if (cases.size() < kProbeCases) cases.push_back(ProbeCase{a, b, fa, fb, fc, 0u});
  };
  // Edges of the float rounding: ties to even, ties one bit further, subnormals, overflow, zeros.
  const double edges[] = {0.0,
                          -0.0,
                          1.0 + std::ldexp(1.0, -24),                         // tie: down to even
                          1.0 + 3 * std::ldexp(1.0, -24),                     // tie: up to even
                          1.0 + std::ldexp(1.0, -24) + std::ldexp(1.0, -52),  // just above a tie
                          -(2.0 - std::ldexp(1.0, -25)),                      // carries to 2
                          std::ldexp(1.0, -149),                              // least subnormal
                          std::ldexp(1.0, -150),                              // tie to 0
                          std::ldexp(1.5, -150),                              // rounds up
                          std::ldexp(1.0, -127) * 1.75,                       // subnormal
                          std::ldexp(1.0, -126) * (1.0 - std::ldexp(1.0, -25)),  // to least normal
                          static_cast<double>(std::numeric_limits<float>::max()),
                          std::ldexp(1.0, 128) - std::ldexp(1.0, 103),         // tie: to inf
                          std::ldexp(1.0, 128) - std::ldexp(1.0, 104) * 0.75,  // down to max
                          std::ldexp(1.0, 200),
                          std::ldexp(1.0, -1030),  // double subnormal
                          -32768.5,
                          32767.999999999996,
                          0.1 * 0.5,
                          -0.05 * 0.5};
  for (double a : edges) push(a, 3.0, 1.0f, 3.0f, 0.5f);
  // Float operands as the walk has them (directions, coordinates, resolutions).
  while (cases.size() < kProbeCases / 2) {
    const float fa = unit(rng), fb = unit(rng), fc = unit(rng);
    const double resolution = static_cast<double>(1 + rng() % 40) * 0.005;
    switch (rng() % 4) {
      case 0:
        push(static_cast<double>(fa) / resolution, static_cast<double>(fb), fa, fb, fc);
        break;
      case 1:
        push(resolution, static_cast<double>(std::abs(fb)), fa, fb, fc);
        break;
      case 2:
        push(static_cast<double>(fa) * 20.0, static_cast<double>(fb), fa, fb, fc);
        break;
      default:
        push(static_cast<double>(fa) * static_cast<double>(fb), 1.0 / resolution, fa, fb, fc);
    }
  }
  // Full-precision doubles over a wide range.
  while (cases.size() < kProbeCases) {
    const double a = randomDouble(-160, 140), b = randomDouble(-40, 40);
    push(a, b, static_cast<float>(randomDouble(-20, 20)), static_cast<float>(randomDouble(-20, 20)),
         static_cast<float>(randomDouble(-20, 20)));
  }
  return cases;
}

// The host's answers: IEEE 754 binary64/binary32, round to nearest even, nothing fused (the
// library is built in ISO C++ mode, where GCC does not contract).
ProbeResult expected(const ProbeCase& c) {
  ProbeResult r{};
  r.sum = c.a + c.b;
  r.difference = c.a - c.b;
  r.product = c.a * c.b;
  r.quotient = c.a / c.b;
  r.root = std::sqrt(std::abs(c.a));
  r.floor_a = std::floor(c.a);
  r.rounded = static_cast<double>(static_cast<float>(c.a));
  const float product = c.fa * c.fb;
  r.float_madd = product + c.fc;
  r.float_div = static_cast<float>(static_cast<double>(c.fa) / static_cast<double>(c.fb));
  return r;
}

std::string hex(double d) {
  char text[64];
  std::snprintf(text, sizeof text, "%a", d);
  return text;
}

template <typename T>
bool sameBits(T x, T y) {
  return std::memcmp(&x, &y, sizeof(T)) == 0;
}

}  // namespace

std::vector<gpu::ProbeCase> deviceProbeCases() { return probeCases(); }

gpu::ProbeResult hostProbeResult(const gpu::ProbeCase& c) { return expected(c); }

std::int32_t hostProbeFloor(const gpu::ProbeCase& c) {
  const double f = std::floor(c.a);
  return (f >= -2147483648.0 && f < 2147483648.0) ? static_cast<std::int32_t>(f) : 0;
}

std::optional<std::string> firstProbeMismatch(std::span<const ProbeCase> cases,
                                              std::span<const ProbeResult> results,
                                              std::span<const std::int32_t> floors) {
  auto describe = [](const std::string& operation, const ProbeCase& c, const std::string& got,
                     const std::string& want) {
    return operation + " of a = " + hex(c.a) + ", b = " + hex(c.b) + " (fa = " + hex(c.fa) +
           ", fb = " + hex(c.fb) + ", fc = " + hex(c.fc) + ") gives " + got + ", IEEE 754 gives " +
           want;
  };
  for (std::size_t i = 0; i < cases.size(); ++i) {
    const ProbeCase& c = cases[i];
    const ProbeResult want = expected(c);
    const ProbeResult& got = results[i];
    const struct {
      const char* operation;
      double got, want;
    } doubles[] = {{"double addition", got.sum, want.sum},
                   {"double subtraction", got.difference, want.difference},
                   {"double multiplication", got.product, want.product},
                   {"double division", got.quotient, want.quotient},
                   {"double square root", got.root, want.root},
                   {"double floor", got.floor_a, want.floor_a},
                   {"rounding double to float (exact.glsl)", got.rounded, want.rounded}};
    for (const auto& d : doubles)
      if (!sameBits(d.got, d.want)) return describe(d.operation, c, hex(d.got), hex(d.want));
    if (!sameBits(got.float_madd, want.float_madd))
      return describe("unfused float multiply-add", c, hex(got.float_madd), hex(want.float_madd));
    if (!sameBits(got.float_div, want.float_div))
      return describe("float division (divFloat)", c, hex(got.float_div), hex(want.float_div));
    const std::int32_t want_int = hostProbeFloor(c);
    if (floors[i] != want_int)
      return describe("double to int conversion", c, std::to_string(floors[i]),
                      std::to_string(want_int));
  }
  return std::nullopt;
}

Result<DeviceProbe> probeDevice(vk::Device& device) {
  try {
    const std::vector<ProbeCase> cases = probeCases();
    const std::size_t out_bytes = sizeof(ProbeHeader) + kProbeCases * sizeof(std::int32_t) +
                                  kProbeCases * sizeof(ProbeResult);
    vk::Buffer in(device, cases.size() * sizeof(ProbeCase), /*host_visible=*/true);
    vk::Buffer out(device, out_bytes, /*host_visible=*/true);
    std::memcpy(in.mapped(), cases.data(), in.size());
    std::memset(out.mapped(), 0, out.size());
    ProbeHeader head{};
    head.loop_iterations = 0xFFFFFFFFu;
    std::memcpy(out.mapped(), &head, sizeof head);

    vk::BindingSet bindings(device);
    bindings.updateRange(gpu::kBindQueryIn, in.handle(), 0, in.size());
    bindings.updateRange(gpu::kBindQueryOut, out.handle(), 0, out.size());
    const vk::Pass& pass = device.pass("device_probe");
    vk::CommandStream stream(device);
    stream.begin(bindings);
    static_assert(sizeof(gpu::DeviceProbeConstants) == sizeof(gpu::PassConstants));
    const gpu::DeviceProbeConstants arithmetic{.mode = gpu::kProbeModeArithmetic,
                                               .case_count = kProbeCases};
    stream.dispatch(pass, kProbeCases / gpu::kWorkgroupSize, &arithmetic, sizeof arithmetic);
    const gpu::DeviceProbeConstants loop{.mode = gpu::kProbeModeLoop,
                                         .loop_iterations = kProbeLoopIterations};
    stream.dispatch(pass, 1, &loop, sizeof loop);
    stream.barrier();
    stream.submitAndWait();

    const auto* bytes = static_cast<const unsigned char*>(out.mapped());
    std::memcpy(&head, bytes, sizeof head);
    std::vector<std::int32_t> floors(kProbeCases);
    std::memcpy(floors.data(), bytes + sizeof head, floors.size() * sizeof(std::int32_t));
    std::vector<ProbeResult> results(kProbeCases);
    std::memcpy(results.data(), bytes + sizeof head + floors.size() * sizeof(std::int32_t),
                results.size() * sizeof(ProbeResult));

    const std::string who = "device '" + device.info().name + "' (" + device.info().driver + ")";
    if (std::optional<std::string> mismatch = firstProbeMismatch(cases, results, floors))
      return Error(ErrorCode::kMissingFeature,
                   who + " fails octovk's exactness check: " + *mismatch +
                       "; its maps would differ from OctoMap's. Choose another device with "
                       "OCTOVK_DEVICE");
    DeviceProbe probe;
    if (head.loop_iterations < kProbeLoopIterations) probe.loop_limit = head.loop_iterations;
    return probe;
  } catch (const Error& e) {
    return e;
  }
}

std::vector<double> deviceOccupancies(vk::Device& device, std::span<const float> log_odds) {
  std::vector<double> out(log_odds.size());
  if (log_odds.empty()) return out;
  vk::Buffer in(device, log_odds.size_bytes(), /*host_visible=*/true);
  vk::Buffer results(device, out.size() * sizeof(double), /*host_visible=*/true);
  std::memcpy(in.mapped(), log_odds.data(), log_odds.size_bytes());
  vk::BindingSet bindings(device);
  bindings.updateRange(gpu::kBindQueryIn, in.handle(), 0, in.size());
  bindings.updateRange(gpu::kBindQueryOut, results.handle(), 0, results.size());
  const vk::Pass& pass = device.pass("device_probe");
  vk::CommandStream stream(device);
  stream.begin(bindings);
  // Dispatches of at most 65,535 groups (the least maxComputeWorkGroupCount Vulkan allows).
  constexpr std::size_t kMostPerDispatch = std::size_t{65535} * gpu::kWorkgroupSize;
  for (std::size_t first = 0; first < log_odds.size(); first += kMostPerDispatch) {
    const std::size_t n = std::min(kMostPerDispatch, log_odds.size() - first);
    const gpu::DeviceProbeConstants pc{.mode = gpu::kProbeModeProbability,
                                       .case_count = static_cast<std::uint32_t>(n),
                                       .first = static_cast<std::uint32_t>(first)};
    stream.dispatch(pass,
                    static_cast<std::uint32_t>((n + gpu::kWorkgroupSize - 1) / gpu::kWorkgroupSize),
                    &pc, sizeof pc);
  }
  stream.barrier();
  stream.submitAndWait();
  std::memcpy(out.data(), results.mapped(), out.size() * sizeof(double));
  return out;
}

namespace {

constexpr const char* kProbeKind = "probe";

// The record's payload: a passing verdict (only those are kept) and the loop limit it saw.
struct KeptVerdict {
  std::uint32_t format = 1;
  std::uint32_t loop_limit = 0;
};

// What the verdict depends on besides the device, its driver and the shaders (which
// Device::cacheKey names): the cases, the host's answers and the loop's length.
std::string probeKey(const vk::Device& device) {
  const std::vector<ProbeCase> cases = probeCases();
  std::uint64_t h = vk::disk::hash64(std::as_bytes(std::span(cases)));
  for (const ProbeCase& c : cases) {
    const ProbeResult want = expected(c);
    const std::int32_t floor = hostProbeFloor(c);
    h = vk::disk::hash64(std::as_bytes(std::span(&want, 1)), h);
    h = vk::disk::hash64(std::as_bytes(std::span(&floor, 1)), h);
  }
  const std::uint32_t loop = kProbeLoopIterations;
  h = vk::disk::hash64(std::as_bytes(std::span(&loop, 1)), h);
  return device.cacheKey() + "; probe " + std::to_string(h);
}

bool reprobeRequested() {
  const char* env = std::getenv("OCTOVK_REPROBE");
  return env && *env && std::string(env) != "0";
}

}  // namespace

Result<DeviceProbe> checkDevice(vk::Device& device) {
  const auto t = std::chrono::steady_clock::now();
  std::filesystem::path file;
  std::string key;
  try {
    file = device.cacheFile(kProbeKind);
    key = probeKey(device);
  } catch (...) {  // no memory for the key: probe, keep nothing
    file.clear();
  }
  if (!file.empty() && !reprobeRequested()) {
    std::optional<std::vector<std::byte>> record;
    try {
      record = vk::disk::readRecord(file, kProbeKind, key);
    } catch (...) {
      record.reset();
    }
    KeptVerdict kept;
    if (record && record->size() == sizeof kept) {
      std::memcpy(&kept, record->data(), sizeof kept);
      if (kept.format == KeptVerdict{}.format) {
        vk::traceStep("device probe: verdict kept by an earlier run", t);
        return DeviceProbe{.loop_limit = kept.loop_limit, .kept = true};
      }
    }
  }
  Result<DeviceProbe> probe = probeDevice(device);
  if (!file.empty()) {
    try {
      if (probe) {
        const KeptVerdict kept{.loop_limit = probe.value().loop_limit};
        vk::disk::writeRecord(file, kProbeKind, key, std::as_bytes(std::span(&kept, 1)));
      } else {
        vk::disk::removeRecord(file);
      }
    } catch (...) {  // keeping the verdict is only a shortcut for the next process
    }
  }
  vk::traceStep("device probe: run", t);
  return probe;
}

}  // namespace octovk
