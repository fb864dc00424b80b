// The change set's passes: list_changes.comp (its keys compacted into the query output, after a
// ChangedKeysHeader) and rehash_changes.comp (its keys moved into a larger set). Emptying it is
// MapBuffers' (recordEmptyChanges: fills, no shader).
#include "map/passes/passes.hpp"

namespace octovk::passes {

void recordListChanges(Recorder& r, const gpu::ScanParams& sp) {
  MapBuffers& b = r.buffers;
  const std::uint32_t slots = std::uint32_t{1} << b.changesLog2();
  r.setParams(sp);
  r.stream.barrier();
  r.dispatch<Shader::kListChanges>(
      1, gpu::ListChangesConstants{.capacity = slots, .mode = gpu::kListChangesHeader});
  r.stream.barrier();
  r.dispatch<Shader::kListChanges>(
      slots, gpu::ListChangesConstants{.capacity = slots, .mode = gpu::kListChangesKeys});
  r.stream.barrier();
}

void recordRehashChanges(Recorder& r, VkDeviceAddress old_set, std::uint32_t old_slots) {
  r.dispatch<Shader::kRehashChanges>(
      old_slots, gpu::RehashChangesConstants{
                     .old_address_lo = static_cast<std::uint32_t>(old_set),
                     .old_address_hi = static_cast<std::uint32_t>(old_set >> 32),
                     .old_capacity = old_slots});
  r.stream.barrier();
}

}  // namespace octovk::passes
