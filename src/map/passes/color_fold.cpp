// A colour scan's fold: color_fold.comp grouping the scan's points by the node search() finds,
// then folding each node's colours in the cloud's order (ColorOcTree::averageNodeColor or
// integrateNodeColor).
#include <algorithm>

#include "map/buffer_sizes.hpp"
#include "map/passes/passes.hpp"

namespace octovk::passes {

void recordColorFold(Recorder& r, std::size_t count, ColorFold fold, VkBuffer source,
                     VkDeviceSize offset) {
  MapBuffers& b = r.buffers;
  const std::size_t chunk = b.colorChunk();
  const std::uint32_t table_log2 = sizes::colorTableLog2(b.pointCapacity(), chunk);
  const std::size_t table_bytes = 2 * (std::size_t{1} << table_log2) * sizeof(std::uint32_t);
  r.stream.copyFrom(source, offset, b.color_fold, count * 2 * sizeof(std::uint32_t), table_bytes);
  // One chunk after another, in the points' order (one chunk where loops are not limited).
  for (std::size_t first = 0; first < count; first += chunk) {
    const std::size_t n = std::min(chunk, count - first);
    r.stream.fill(b.color_fold, gpu::kFoldEmpty, 0, table_bytes);
    r.stream.barrier();
    gpu::ColorFoldConstants pc{.mode = gpu::kColorFoldGroup,
                               .table_log2 = table_log2,
                               .first = static_cast<std::uint32_t>(first),
                               .count = static_cast<std::uint32_t>(n)};
    r.dispatch<Shader::kColorFold>(n, pc);
    pc.mode = fold == ColorFold::kIntegrate ? gpu::kColorFoldIntegrate : gpu::kColorFoldAverage;
    r.dispatch<Shader::kColorFold>(std::size_t{1} << table_log2, pc);
  }
}

std::uint32_t foldedListAt(const MapBuffers& b, std::size_t count) {
  return static_cast<std::uint32_t>(sizes::colorFoldedAt(b.pointCapacity(), b.colorChunk(), count));
}

}  // namespace octovk::passes
