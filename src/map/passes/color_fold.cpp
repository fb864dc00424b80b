// A colour scan's fold: color_fold.comp grouping the scan's points by the node search() finds,
// then folding each node's colours in the cloud's order (ColorOcTree::averageNodeColor).
#include "map/buffer_sizes.hpp"
#include "map/passes/passes.hpp"

namespace octovk::passes {

void recordColorFold(Recorder& r, std::size_t count, VkBuffer source, VkDeviceSize offset) {
  MapBuffers& b = r.buffers;
  const std::size_t capacity = b.pointCapacity();
  const std::uint32_t table_log2 = sizes::colorTableLog2(capacity);
  const std::size_t word = sizeof(std::uint32_t);
  r.stream.copyFrom(source, offset, b.color_fold, count * word);
  r.stream.fill(b.color_fold, gpu::kFoldEmpty, 2 * capacity * word,
                2 * (std::size_t{1} << table_log2) * word);
  r.stream.barrier();
  const gpu::ColorFoldConstants pc{.mode = gpu::kColorFoldGroup,
                                   .point_capacity = static_cast<std::uint32_t>(capacity),
                                   .table_log2 = table_log2};
  r.dispatch<Shader::kColorFold>(count, pc);
  gpu::ColorFoldConstants apply = pc;
  apply.mode = gpu::kColorFoldApply;
  r.dispatch<Shader::kColorFold>(std::size_t{1} << table_log2, apply);
}

}  // namespace octovk::passes
