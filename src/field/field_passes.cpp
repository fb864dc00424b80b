#include "field/field_passes.hpp"

namespace octovk::field {

void recordRaster(passes::Recorder& r, VkDeviceAddress header, std::uint32_t words,
                  bool compare) {
  r.dispatch<vk::Shader::kFieldRaster>(
      words, gpu::FieldRasterConstants{
                 .header = header, .word_count = words, .compare = compare ? 1u : 0u});
}

void recordChanges(passes::Recorder& r, VkDeviceAddress header, std::uint32_t capacity) {
  r.dispatch<vk::Shader::kFieldChanges>(
      capacity, gpu::FieldChangesConstants{.header = header, .capacity = capacity});
}

void recordNearestX(passes::Recorder& r, VkDeviceAddress header,
                    const std::array<std::uint32_t, 3>& size, bool full) {
  r.dispatch<vk::Shader::kFieldNearestX>(
      std::size_t{size[1]} * size[2],
      gpu::FieldEdtConstants{.header = header, .axis = 0, .full = full ? 1u : 0u});
}

void recordEdt(passes::Recorder& r, VkDeviceAddress header,
               const std::array<std::uint32_t, 3>& size, bool full) {
  // Along y one invocation per line (x, z), along z per line (x, y); x varies fastest.
  for (std::uint32_t axis = 1; axis < 3; ++axis) {
    const std::size_t lines = std::size_t{size[0]} * size[axis == 1 ? 2 : 1];
    r.dispatch<vk::Shader::kFieldEdt>(
        lines, gpu::FieldEdtConstants{.header = header, .axis = axis, .full = full ? 1u : 0u});
  }
}

void recordQueries(passes::Recorder& r, VkDeviceAddress header, std::uint32_t count) {
  r.dispatch<vk::Shader::kFieldQuery>(count,
                                      gpu::FieldQueryConstants{.header = header, .query_count = count});
}

}  // namespace octovk::field
