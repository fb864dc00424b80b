// SPIR-V of the compute shaders, compiled by glslangValidator at build time and embedded.
#pragma once

#include <cstdint>
#include <span>
#include <string_view>

namespace octovk::vk {

/// The SPIR-V words of shaders/<name>.comp (or of a ray-tracing stage, shaders/<name> with its
/// extension, e.g. "accel_box.rint"), or an empty span if there is no such shader.
std::span<const std::uint32_t> findShader(std::string_view name);

}  // namespace octovk::vk
