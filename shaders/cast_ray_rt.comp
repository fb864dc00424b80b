#version 460
#extension GL_GOOGLE_include_directive : require
#extension GL_EXT_ray_query : require
// castRay's ray-tracing backend for the rays that ignore unknown space: cast_ray_rt.glsl with
// ray queries against the map's acceleration structure.
#define OCTOVK_CAST_RAY_TRACE
#include "cast_ray_rt.glsl"
