// A map's node pool copied to the host as the device holds it, with the nodes near the root that
// changed since an earlier capture (TreeTransfer::capture, StoreAccess::capture).
#pragma once

#include <cstdint>
#include <memory>
#include <span>
#include <vector>

#include "gpu/gpu_types.h"
#include "octovk/params.hpp"
#include "octovk/queries.hpp"

namespace octovk {

/// The node pool as the device holds it (TreeTransfer::capture), and which of its nodes near the
/// root changed since an earlier capture: what a store needs to find the tiles a scan changed
/// without building a host tree of the whole map.
struct PoolCapture {
  /// The tree's version (MapCore::tree_version) captured: the `since` of the next capture.
  std::uint64_t version = 0;
  bool root_exists = false;
  /// The pool's used blocks, raw: node index = block * 8 + slot, the root at 0; free blocks
  /// hold stale nodes, only what hangs from the root is the tree. They lie in `memory`, the
  /// host-visible staging they were copied into (read where they are: no second copy), or in
  /// the host's copy that the scan's change was applied to (from_change).
  std::span<const gpu::Node> nodes;
  /// Their payload words (MapParams::payload: a colour or a stamp per node, in the same
  /// staging), empty for a plain map.
  std::span<const std::uint32_t> payload;
  Payload kind = Payload::kNone;
  std::shared_ptr<const void> memory;
  /// Whether `changed` is complete: every node at depth <= the capture's `depth` whose subtree
  /// changed since the version `since` is in it (the tree is `since`'s, or one scan after it,
  /// whose touched lists hold the nodes on its updated paths). False: anything may have changed.
  bool incremental = false;
  /// Sorted indices of those nodes (some may since have been merged away: not in the tree).
  std::vector<std::uint32_t> changed;
  /// A colour map's nodes whose colour the scan's fold changed, which need not be on its updated
  /// paths (a leaf at the clamping bound takes no update): a cell in each (its key) and the
  /// node's depth. Part of what `incremental` says is complete.
  struct Folded {
    Key key{};
    unsigned depth = 0;
    /// From a FoldedNode's (or a folded CaptureRecord's) words.
    static Folded of(std::uint32_t key_xy, std::uint32_t key_z_depth) {
      return {
          {static_cast<std::uint16_t>(key_xy & 0xFFFFu), static_cast<std::uint16_t>(key_xy >> 16),
           static_cast<std::uint16_t>(key_z_depth & 0xFFFFu)},
          key_z_depth >> 16};
    }
  };
  std::vector<Folded> folded;
  /// Made from the scan's change applied to the host's copy of the pool before it
  /// (gpu::CaptureRecord, CaptureMirror), not from a copy of the whole pool.
  bool from_change = false;
};

}  // namespace octovk
