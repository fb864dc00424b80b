#version 450
#extension GL_GOOGLE_include_directive : require
#extension GL_EXT_shader_explicit_arithmetic_types_int64 : require
// The device probe, run once when a Context is created (src/map/device_probe.cpp):
//   kProbeModeArithmetic: per case, the operations the exact ray walk takes from the hardware
//           (double add, subtract, multiply, divide, square root, floor, the conversions) and the
//           integer float rounding of exact.glsl, written out to be compared bit for bit with the
//           host;
//   kProbeModeLoop: how many iterations a loop of pc.loop_iterations iterations really gets to
//           run (llvmpipe ends an invocation's loops early, silently), in invocation 0;
//   kProbeModeProbability (tests only, not part of the probe): occupancyProbability
//           (probability.glsl) of floats, for the tests to compare with the host's
//           octomap::probability bit for bit.
// Uses only the two query bindings, with its own views of them.
#include "gpu/gpu_types.h"
#include "exact.glsl"
#include "probability.glsl"

layout(local_size_x = 64) in;
layout(push_constant) uniform PushBlock { DeviceProbeConstants pc; };
layout(std430, binding = kBindQueryIn) readonly buffer ProbeIn { ProbeCase cases[]; };
layout(std430, binding = kBindQueryOut) buffer ProbeOut {
  ProbeHeader header;
  int floors[kProbeCases];
  ProbeResult results[];
};
layout(std430, binding = kBindQueryIn) readonly buffer LogOddsIn { float log_odds_in[]; };
layout(std430, binding = kBindQueryOut) buffer ProbabilityOut { double probability_out[]; };

void main() {
  uint i = gl_GlobalInvocationID.x;
  if (pc.mode == kProbeModeLoop) {
    // One invocation is enough (a limit applies to each invocation, or to its SIMD batch), and
    // costs a CPU driver one batch instead of eight. The exit test reads memory the compiler
    // cannot see through, so the loop is not folded.
    if (i != 0u) return;
    uint n = 0u;
    for (uint k = 0u; k < pc.loop_iterations; ++k) {
      if (cases[(k + i) % kProbeCases].pad == 0xFFFFFFFFu) break;
      ++n;
    }
    atomicMin(header.loop_iterations, n);
    return;
  }
  if (pc.mode == kProbeModeProbability) {
    if (i >= pc.case_count) return;
    probability_out[pc.first + i] = occupancyProbability(log_odds_in[pc.first + i]);
    return;
  }
  if (i >= pc.case_count) return;
  ProbeCase c = cases[i];
  ProbeResult r;
  precise double sum = c.a + c.b;
  precise double difference = c.a - c.b;
  precise double product = c.a * c.b;
  precise double quotient = c.a / c.b;
  r.sum = sum;
  r.difference = difference;
  r.product = product;
  r.quotient = quotient;
  r.root = sqrt(abs(c.a));
  precise double f = floor(c.a);
  r.floor_a = f;
  floors[i] = (f >= -2147483648.0lf && f < 2147483648.0lf) ? int(f) : 0;
  r.rounded = roundedToFloat(c.a);
  precise float madd = c.fa * c.fb + c.fc;
  r.float_madd = madd;
  r.float_div = divFloat(c.fa, c.fb);
  results[i] = r;
}
