// The distance field's Vulkan interop (include/octovk/vulkan_interop.hpp): queries between
// ranges of the caller's buffers.
#include "field/field_impl.hpp"
#include "map/host_memory.hpp"
#include "octovk/vulkan_interop.hpp"

namespace octovk {

class FieldInteropAccess {
 public:
  static DistanceField::Impl& impl(DistanceField& field) { return field.self(); }
};

void distancesOnDevice(DistanceField& field, BufferRange spheres, std::uint32_t count,
                       BufferRange results, WaitSemaphore wait, SignalSemaphore signal) {
  hostMemoryGuard("distancesOnDevice", [&] {
    DistanceField::Impl& impl = FieldInteropAccess::impl(field);
    impl.queryOnDevice(spheres.buffer, spheres.offset, results.buffer, results.offset, count,
                       wait.semaphore, wait.value);
    // The results are written (queryOnDevice waited); the signal follows on the same queue, as
    // the map's own *OnDevice calls signal (OccupancyMap::Impl::signal).
    impl.map().signal(signal.semaphore, signal.value);
  });
}

}  // namespace octovk
