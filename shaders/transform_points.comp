#version 450
#extension GL_GOOGLE_include_directive : require
// Sensor frame to world, in place: octomath::Pose6D::transform, i.e. q * (0, v) * q^-1 then the
// translation, with the same float operations in the same order.
#include "bindings.glsl"

layout(push_constant) uniform PushBlock { TransformPointsConstants pc; };

vec4 quatMul(vec4 a, vec4 b) {  // (u, x, y, z), as octomath::Quaternion::operator*
  precise float u = a.x * b.x - a.y * b.y - a.z * b.z - a.w * b.w;
  precise float x = a.z * b.w - b.z * a.w + a.x * b.y + b.x * a.y;
  precise float y = a.w * b.y - b.w * a.y + a.x * b.z + b.x * a.z;
  precise float z = a.y * b.z - b.y * a.z + a.x * b.w + b.x * a.w;
  return vec4(u, x, y, z);
}

void main() {
  uint i = invocationIndex();
  if (i >= pc.point_count) return;
  vec4 q = vec4(params.rot_u, params.rot_x, params.rot_y, params.rot_z);
  vec4 q_inv = vec4(q.x, -q.y, -q.z, -q.w);
  vec4 v = vec4(0.0, POINTS[3u * i], POINTS[3u * i + 1u], POINTS[3u * i + 2u]);
  // A non-finite point stays as it is for the ray pass to skip: Vulkan does not promise NaN or
  // inf results from arithmetic on them.
  if (!finiteBits(v.yzw)) return;
  vec4 r = quatMul(quatMul(q, v), q_inv);
  precise float x = r.y + params.trans_x;
  precise float y = r.z + params.trans_y;
  precise float z = r.w + params.trans_z;
  POINTS[3u * i] = x;
  POINTS[3u * i + 1u] = y;
  POINTS[3u * i + 2u] = z;
}
