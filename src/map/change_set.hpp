// The change set: OctoMap's change detection (enableChangeDetection, changedKeysBegin/End,
// numChangesDetected, resetChangeDetection) kept on the device. descend notes each updated leaf
// in it (shaders/change_set.glsl); this part turns it on, grows it (rehash), resets it and reads
// it out. The caller takes the results of the scans in flight first (OccupancyMap::Impl does).
#pragma once

#include <cstdint>
#include <vector>

#include "map/map_core.hpp"
#include "octovk/octovk.hpp"

namespace octovk {

/// log2 of the slots a change set starts with when change detection is first turned on.
inline constexpr std::uint32_t kInitialChangesLog2 = 12;

/// Grows the change set so that `keys` slots stay within 3/4 of it, moving the keys it holds
/// (rehash_changes); nothing may be in flight. Throws (the set as before) where it may not grow.
void growChangeSet(MapCore& core, std::uint64_t keys);

/// The change set's header (slots used, keys in it), read back (waited for).
gpu::ChangeHeader readChangeHeader(MapCore& core);

class ChangeSet {
 public:
  explicit ChangeSet(MapCore& core) : core_(core) {}

  /// Turns change detection on or off for the scans submitted after this; the keys noted so
  /// far stay (as OctoMap's). Turning it on the first time makes the set (under the cap).
  void enable(bool on);
  bool enabled() const noexcept { return core_.change_detection; }
  /// Empties the set (resetChangeDetection).
  void reset();
  /// Turns change detection off and gives the set's memory back (the one-slot idle set), as a
  /// map that never had it on; for the distance fields that turned it on (map_impl.hpp).
  void release();
  /// Keys in the set (numChangesDetected).
  std::size_t count();
  /// The keys and their flags, in no particular order.
  std::vector<ChangedKey> keys();
  /// Writes a ChangedKeysHeader and the keys into a range of the caller's buffer (interop).
  void onDevice(VkBuffer out, VkDeviceSize out_offset, VkDeviceSize out_size);

 private:
  MapCore& core_;
};

}  // namespace octovk
