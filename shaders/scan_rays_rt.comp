#version 460
#extension GL_GOOGLE_include_directive : require
#extension GL_EXT_ray_query : require
// Scans through ray tracing with ray queries in a compute pass: scan_rays_rt.glsl.
#include "scan_rays_rt.glsl"
