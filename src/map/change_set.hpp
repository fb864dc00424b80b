// The change set: OctoMap's change detection (enableChangeDetection, changedKeysBegin/End,
// numChangesDetected, resetChangeDetection) kept on the device. descend notes each updated leaf
// in it (shaders/change_set.glsl); this part owns whether it is on and who turned it on (the user
// or the distance fields following the map through it), turns it on, grows it (rehash), resets
// it, reads it out, and tells a field what the set can vouch for. The caller takes the results
// of the scans in flight first (OccupancyMap::Impl does).
#pragma once

#include <cstdint>
#include <vector>

#include "map/map_core.hpp"
#include "octovk/octovk.hpp"

namespace octovk {

/// log2 of the slots a change set starts with when change detection is first turned on.
inline constexpr std::uint32_t kInitialChangesLog2 = 12;

class ChangeSet {
 public:
  explicit ChangeSet(MapCore& core) : core_(core) {}

  // ---- the user's change detection ----
  /// enableChangeDetection: on or off for the scans submitted after this; the keys noted so far
  /// stay (as OctoMap's). Turning it on the first time makes the set (under the cap). From now
  /// on the set is the user's: a distance field never resets or releases it.
  void enableByUser(bool on);
  bool enabled() const noexcept { return enabled_; }
  /// Empties the set (resetChangeDetection).
  void reset();
  /// Keys in the set (numChangesDetected).
  std::size_t count();
  /// The keys and their flags, in no particular order.
  std::vector<ChangedKey> keys();
  /// Writes a ChangedKeysHeader and the keys into a range of the caller's buffer (interop).
  void onDevice(VkBuffer out, VkDeviceSize out_offset, VkDeviceSize out_size);

  // ---- scans ----
  /// The changes_log2 a scan records with: the set's size while change detection is on, else 0
  /// (the scan notes nothing).
  std::uint32_t scanLog2() const noexcept { return enabled_ ? core_.buffers.changesLog2() : 0u; }
  /// A scan recorded with change detection on changed the tree (after MapCore::treeChanged):
  /// the set holds that change.
  void scanNoted() noexcept { ++noted_version_; }
  /// The set's header (slots used, keys in it), read back (waited for).
  gpu::ChangeHeader header();
  /// Grows the set so that `keys` slots stay within 3/4 of it, moving the keys it holds
  /// (rehash_changes); nothing may be in flight. Throws (the set as before) where it may not.
  void grow(std::uint64_t keys);

  // ---- distance fields following the map through the set ----
  /// What a field follows the tree by: the tree changes the set does not hold (uploads, edits,
  /// scans without change detection), the set's resets and its growths. Equal `unnoted` and
  /// `epoch` since a field's last update, and equal `rehashes` too unless that update ended by
  /// resetting the set, mean the set holds every cell whose occupancy differs from then.
  struct FieldTracking {
    std::uint64_t unnoted = 0;
    std::uint64_t epoch = 0;
    std::uint64_t rehashes = 0;
  };
  FieldTracking fieldTracking() const {
    return {core_.tree_version - noted_version_, epoch_, rehashes_};
  }
  /// A field follows the map: turns change detection on (as DynamicEDTOctomap's constructor
  /// does) unless the user chose it either way.
  void followByField();
  /// A field is gone: the last one turns change detection off again and gives the set's memory
  /// back if the fields turned it on; the map is then as if no field had been built.
  void unfollowByField();
  /// After a field's update: empties the set if the fields turned change detection on (one the
  /// user turned on is theirs) and no other field follows it (whose next update needs the
  /// keys). True when it did.
  bool resetForField();

 private:
  /// Turns change detection off and gives the set's memory back (the one-slot idle set).
  void release();

  MapCore& core_;
  bool enabled_ = false;
  /// The tree changes the set holds (scanNoted): MapCore::tree_version minus this counts every
  /// other change.
  std::uint64_t noted_version_ = 0;
  std::uint64_t epoch_ = 0;     ///< resets of the set
  std::uint64_t rehashes_ = 0;  ///< growths, whose rehash drops keys that flipped back
  /// Who turned change detection on: the user (the set is theirs), or the fields following it
  /// (`fields_` of them; the last to go turns it off).
  bool by_user_ = false;
  bool by_fields_ = false;
  std::uint32_t fields_ = 0;
};

}  // namespace octovk
