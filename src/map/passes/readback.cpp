// The counters and the pool state, copied to the recording frame's region of the host-visible
// readback buffer: what the host learns of a scan (its statistics, whether it was applied, the
// pool's fill), once that frame's submission is done.
#include <cstring>

#include "map/passes/passes.hpp"

namespace octovk::passes {

void recordReadback(Recorder& r) {
  MapBuffers& b = r.buffers;
  const std::size_t region = std::size_t{r.stream.frame()} * kReadbackBytes;
  r.stream.copy(b.counters, b.readback, sizeof(gpu::ScanCounters), 0, region);
  r.stream.copy(b.pool, b.readback, sizeof(gpu::PoolState), 0, region + sizeof(gpu::ScanCounters));
}

void readBack(const MapBuffers& buffers, std::uint32_t frame, gpu::ScanCounters& counters,
              gpu::PoolState& pool) {
  const auto* bytes = static_cast<const unsigned char*>(buffers.readback.mapped()) +
                      std::size_t{frame} * kReadbackBytes;
  std::memcpy(&counters, bytes, sizeof(counters));
  std::memcpy(&pool, bytes + sizeof(counters), sizeof(pool));
}

}  // namespace octovk::passes
