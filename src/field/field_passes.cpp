#include "field/field_passes.hpp"

namespace octovk::field {

void recordRaster(passes::Recorder& r, VkDeviceAddress header, std::uint32_t cells) {
  r.dispatch<vk::Shader::kFieldRaster>(cells,
                                       gpu::FieldRasterConstants{.header = header, .cell_count = cells});
}

void recordTransform(passes::Recorder& r, VkDeviceAddress header,
                     const std::array<std::uint32_t, 3>& size) {
  // x: A -> B, y: B -> A, z: A -> B. Each dispatch has one invocation per line along its axis.
  for (std::uint32_t axis = 0; axis < 3; ++axis) {
    const std::size_t lines = std::size_t{size[(axis + 1) % 3]} * size[(axis + 2) % 3];
    r.dispatch<vk::Shader::kFieldEdt>(
        lines, gpu::FieldEdtConstants{.header = header, .axis = axis, .from_b = axis % 2});
  }
}

void recordQueries(passes::Recorder& r, VkDeviceAddress header, std::uint32_t count) {
  r.dispatch<vk::Shader::kFieldQuery>(count,
                                      gpu::FieldQueryConstants{.header = header, .query_count = count});
}

}  // namespace octovk::field
