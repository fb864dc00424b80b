// The distance field's stages, one host function per shader (shaders/field_*.comp). None
// submits or waits; DistanceField::Impl (field_impl.hpp) decides what runs when.
#pragma once

#include <array>
#include <cstdint>

#include "map/passes/recorder.hpp"

namespace octovk::field {

/// field_raster: the box's obstacles into array A (one invocation per cell).
void recordRaster(passes::Recorder& r, VkDeviceAddress header, std::uint32_t cells);
/// field_edt along x, y and z (one invocation per line each): the exact squared distances and
/// nearest obstacles into array B.
void recordTransform(passes::Recorder& r, VkDeviceAddress header,
                     const std::array<std::uint32_t, 3>& size);
/// field_query over `count` spheres in the bound query input, results into the query output.
void recordQueries(passes::Recorder& r, VkDeviceAddress header, std::uint32_t count);

/// Loop iterations field_edt takes on a line of `n` cells at most (the forward and backward
/// scans, each with at most one envelope pop per cell).
inline std::uint64_t edtLoopIterations(std::uint32_t n) { return 4 * std::uint64_t{n} + 8; }

}  // namespace octovk::field
