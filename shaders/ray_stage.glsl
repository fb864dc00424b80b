// The prelude of every stage of octovk's ray-tracing pipelines (cast_ray_rt.rgen,
// scan_rays_rt.rgen, accel_box.rint, accel_box.rahit, accel_box.rmiss), included first: those
// stages share the compute passes' bindings, types and walk (bindings.glsl and what builds on
// it), which bindings.glsl writes for a compute shader. Until it leaves the compute-only parts out
// for these stages, its workgroup size becomes a default qualifier no declaration here uses, and
// the work item index (invocationIndex) counts the launch's IDs as a 1-D workload folded into x
// and y, as the host launches it (vk::RayPipeline::recordTrace).
#ifndef OCTOVK_RAY_STAGE_GLSL
#define OCTOVK_RAY_STAGE_GLSL

#extension GL_EXT_ray_tracing : require

#define gl_GlobalInvocationID gl_LaunchIDEXT
#define gl_NumWorkGroups gl_LaunchSizeEXT
#define gl_WorkGroupSize uvec3(1u)
#define in out
#define local_size_x input_attachment_index
#include "bindings.glsl"
#undef in
#undef local_size_x

// The pipelines' push constants follow the compute passes' (gpu::PassConstants, 16 B): a
// pipeline layout's ranges may not overlap for different stages, and the compute passes push
// theirs for the compute stage alone (vk::RayPipeline::kConstantsOffset).
#define OCTOVK_RAY_CONSTANTS(Type) \
  layout(push_constant) uniform PushBlock { layout(offset = 16) Type pc; }

#endif  // OCTOVK_RAY_STAGE_GLSL
