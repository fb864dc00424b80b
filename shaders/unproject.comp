#version 450
#extension GL_GOOGLE_include_directive : require
// Depth image to points, before the ray pass: pixel i = (u, v) with depth d becomes the
// camera-frame point z = d / depth_scale, x = (u - cx) * z / fx, y = (v - cy) * z / fy, in
// float, correctly rounded, in that order (unprojectDepthImage is the host's twin). A pixel with
// no usable depth (d or z zero, subnormal or non-finite) becomes a NaN point, which the ray pass
// skips, and is counted in ScanCounters::no_depth. Decided on the bits, before any arithmetic:
// Vulkan lets an operation on NaN, inf or a subnormal give something else than IEEE's answer.
#include "bindings.glsl"

layout(push_constant) uniform PushBlock { UnprojectConstants pc; };

// A normal float: neither zero, subnormal, inf nor NaN.
bool normalBits(float x) {
  uint e = floatBitsToUint(x) & 0x7F800000u;
  return e != 0u && e != 0x7F800000u;
}

void main() {
  uint i = invocationIndex();
  if (i >= pc.pixel_count) return;
  // Field by field: glslang 11 does not finish compiling a whole-struct load through a buffer
  // reference.
  DepthRef image = DEPTH_IMAGE;
  float d;
  if (image.camera.encoding == kDepthUint16) {
    uint word = image.words[i >> 1u];
    d = float((i & 1u) != 0u ? (word >> 16u) : (word & 0xFFFFu));  // exact: below 2^24
  } else {
    d = uintBitsToFloat(image.words[i]);
  }
  float z = 0.0;
  if (normalBits(d)) z = divFloat(d, image.camera.depth_scale);
  if (!normalBits(d) || !normalBits(z)) {
    atomicAdd(counters.no_depth, 1u);
    POINTS[3u * i] = uintBitsToFloat(0x7FC00000u);
    POINTS[3u * i + 1u] = uintBitsToFloat(0x7FC00000u);
    POINTS[3u * i + 2u] = uintBitsToFloat(0x7FC00000u);
    return;
  }
  uint width = image.camera.width;
  uint u = i % width;
  uint v = i / width;
  precise float du = float(u) - image.camera.cx;
  precise float dv = float(v) - image.camera.cy;
  precise float xz = du * z;
  precise float yz = dv * z;
  POINTS[3u * i] = divFloat(xz, image.camera.fx);
  POINTS[3u * i + 1u] = divFloat(yz, image.camera.fy);
  POINTS[3u * i + 2u] = z;
}
