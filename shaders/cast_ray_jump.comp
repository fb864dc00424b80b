#version 460
#extension GL_GOOGLE_include_directive : require
// castRay's ray-tracing backend for the rays that stop at unknown space: cast_ray_rt.glsl
// without ray queries, OctoMap's walk jumping exactly through the free nodes it meets.
#include "cast_ray_rt.glsl"
