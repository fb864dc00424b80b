#version 460
#extension GL_GOOGLE_include_directive : require
// The miss shader of the ray-tracing pipelines: a trace that keeps no box leaves its payload as
// the ray generation shader set it (BoxSearch::found false).
void main() {}
