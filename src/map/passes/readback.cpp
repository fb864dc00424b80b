// The counters and the pool state, copied to the host-visible readback buffer: what the host
// learns of a scan (its statistics, overflows, the pool's fill).
#include <cstring>

#include "map/passes/passes.hpp"

namespace octovk::passes {

void recordReadback(Recorder& r) {
  MapBuffers& b = r.buffers;
  r.stream.copy(b.counters, b.readback, sizeof(gpu::ScanCounters));
  r.stream.copy(b.pool, b.readback, sizeof(gpu::PoolState), 0, sizeof(gpu::ScanCounters));
}

void readBack(const MapBuffers& buffers, gpu::ScanCounters& counters, gpu::PoolState& pool) {
  const auto* bytes = static_cast<const unsigned char*>(buffers.readback.mapped());
  std::memcpy(&counters, bytes, sizeof(counters));
  std::memcpy(&pool, bytes + sizeof(counters), sizeof(pool));
}

}  // namespace octovk::passes
