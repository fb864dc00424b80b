// The distance field's stages, one host function per shader (shaders/field_*.comp). None
// submits or waits; DistanceField::Impl (field_impl.hpp) decides what runs when.
#pragma once

#include <array>
#include <cstdint>

#include "map/passes/recorder.hpp"

namespace octovk::field {

/// field_raster: the box's obstacles from the tree into the occupancy bits (one invocation per
/// word of 32 cells of an x-line); `compare`: marking the x-lines whose bits changed.
void recordRaster(passes::Recorder& r, VkDeviceAddress header, std::uint32_t words, bool compare);
/// field_changes: the occupancy bits of the cells in the change set (`capacity` slots, bound at
/// kBindChanges) from the tree, marking the x-lines whose bits flipped.
void recordChanges(passes::Recorder& r, VkDeviceAddress header, std::uint32_t capacity);
/// field_nearest_x: the nearest obstacle on each x-line (one invocation per line); `full`: every
/// line, else the dirty ones (marking the y-lines that changed).
void recordNearestX(passes::Recorder& r, VkDeviceAddress header,
                    const std::array<std::uint32_t, 3>& size, bool full);
/// field_edt along y, then along z (one invocation per line each): the nearest obstacle in each
/// z-plane, then in the box; `full`: every line, else the dirty ones.
void recordEdt(passes::Recorder& r, VkDeviceAddress header,
               const std::array<std::uint32_t, 3>& size, bool full);
/// field_query over `count` spheres in the bound query input, results into the query output.
void recordQueries(passes::Recorder& r, VkDeviceAddress header, std::uint32_t count);

/// Loop iterations field_edt takes on a line of `n` cells at most (the forward and backward
/// scans, each with at most one envelope pop per cell); field_nearest_x takes fewer.
inline std::uint64_t edtLoopIterations(std::uint32_t n) { return 4 * std::uint64_t{n} + 8; }

}  // namespace octovk::field
