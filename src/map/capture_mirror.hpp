// A store's captures of the scans (ScanPipeline::captureScans), kept by ticket until the store
// takes them, and the host's copy of the pool that a scan's change applies to. A capture is the
// whole pool (the first one, and whenever the tree changed otherwise since the last), or the
// scan's change (gpu::CaptureRecord per node on its updated paths): a scan lists some thousand
// nodes of a pool of millions.
#pragma once

#include <cstdint>
#include <deque>
#include <memory>
#include <optional>
#include <span>
#include <vector>

#include "gpu/gpu_types.h"
#include "map/pool_capture.hpp"

namespace octovk {

class CaptureMirror {
 public:
  /// One scan's capture, as keepCapture made it from the scan's staging.
  struct Kept {
    std::uint64_t ticket = 0;
    /// The tree's version before the scan: a change applies to the copy at that version.
    std::uint64_t base = 0;
    /// The whole pool (pool.nodes, pool.payload in the scan's staging), or for a change its
    /// pool fields but the spans, with `nodes` the pool's used nodes after the scan.
    PoolCapture pool;
    bool change = false;
    std::size_t nodes = 0;
    /// A change's records; false `complete`: the lists held more than the staging (the copy
    /// cannot follow the scan).
    std::vector<gpu::CaptureRecord> records;
    bool complete = true;
  };

  /// Keeps `kept` (tickets in order). At most `limit` wait: beyond, the oldest is applied to
  /// the copy and dropped.
  void keep(Kept kept, std::size_t limit);
  /// Whether scan `ticket`'s capture is kept.
  bool holds(std::uint64_t ticket) const noexcept;
  /// Scan `ticket`'s capture, once the captures before it are applied: nothing when none is
  /// kept for it. A change that does not follow the copy (a capture before it lost, the tree
  /// changed otherwise between) throws Error(kInternal).
  std::optional<PoolCapture> take(std::uint64_t ticket);

 private:
  struct Pool {
    std::vector<gpu::Node> nodes;
    std::vector<std::uint32_t> payload;
  };
  /// The copy after `k`; false when `k` is a change that does not follow it (the copy is then
  /// unknown until a whole capture).
  bool apply(const Kept& k);
  /// The last whole capture applied, in its staging, until a change needs the copy made.
  struct Whole {
    std::span<const gpu::Node> nodes;
    std::span<const std::uint32_t> payload;
    std::shared_ptr<const void> memory;
  };
  std::deque<Kept> kept_;
  Whole whole_;
  std::shared_ptr<Pool> copy_;  ///< shared with the captures taken from it (copied on write)
  std::uint64_t version_ = 0;   ///< the tree's version the copy is at
  bool valid_ = false;
};

}  // namespace octovk
