#include "map/capture_mirror.hpp"

#include <algorithm>
#include <bit>

#include "octovk/octovk.hpp"

namespace octovk {

void CaptureMirror::keep(Kept kept, std::size_t limit) {
  kept_.push_back(std::move(kept));
  while (kept_.size() > limit) {
    apply(kept_.front());
    kept_.pop_front();
  }
}

bool CaptureMirror::holds(std::uint64_t ticket) const noexcept {
  return std::any_of(kept_.begin(), kept_.end(), [&](const Kept& k) { return k.ticket == ticket; });
}

bool CaptureMirror::apply(const Kept& k) {
  const PoolCapture& pool = k.pool;
  if (!k.change) {
    // The whole pool, in its staging: the copy is made from it when a change first follows
    // (where every capture is whole, none is).
    whole_ = Whole{pool.nodes, pool.payload, pool.memory};
    copy_.reset();
    version_ = pool.version;
    valid_ = true;
    return true;
  }
  if (!valid_ || version_ != k.base || !k.complete) {
    valid_ = false;
    return false;
  }
  if (!copy_) {
    copy_ = std::make_shared<Pool>();
    copy_->nodes.assign(whole_.nodes.begin(), whole_.nodes.end());
    copy_->payload.assign(whole_.payload.begin(), whole_.payload.end());
    whole_ = {};  // its staging free for another capture
  } else if (copy_.use_count() > 1) {
    copy_ = std::make_shared<Pool>(*copy_);  // a capture still reads it
  }
  Pool& c = *copy_;
  // The pool only grows between whole captures (a scan takes blocks from its end or its free
  // stack); nodes past the used ones are stale.
  c.nodes.resize(std::max(c.nodes.size(), k.nodes));
  const bool payload = pool.kind != Payload::kNone;
  if (payload) c.payload.resize(c.nodes.size());
  for (const gpu::CaptureRecord& r : k.records) {
    const gpu::Node node = std::bit_cast<gpu::Node>(r.node);
    const std::size_t block = node.link & gpu::kBlockMask;
    if (r.index >= c.nodes.size() ||
        (block != gpu::kNoChildren && block * 8 + 8 > c.nodes.size())) {
      valid_ = false;
      return false;
    }
    c.nodes[r.index] = node;
    if (payload) c.payload[r.index] = r.payload;
    if (block != gpu::kNoChildren) {
      std::transform(std::begin(r.children), std::end(r.children), c.nodes.begin() + block * 8,
                     [](std::uint64_t word) { return std::bit_cast<gpu::Node>(word); });
      if (payload)
        std::copy(std::begin(r.child_payload), std::end(r.child_payload),
                  c.payload.begin() + block * 8);
    }
  }
  version_ = pool.version;
  return true;
}

std::optional<PoolCapture> CaptureMirror::take(std::uint64_t ticket) {
  while (!kept_.empty() && kept_.front().ticket < ticket) {
    apply(kept_.front());
    kept_.pop_front();
  }
  if (kept_.empty() || kept_.front().ticket != ticket) return std::nullopt;
  Kept k = std::move(kept_.front());
  kept_.pop_front();
  const bool applied = apply(k);
  if (!k.change) return std::move(k.pool);  // read in the scan's staging
  if (!applied)
    throw Error(ErrorCode::kInternal,
                "internal error: the host's copy of the map does not follow scan " +
                    std::to_string(ticket) +
                    " (a capture before it was lost, or the map changed otherwise in between); "
                    "please report this with the input");
  PoolCapture c = std::move(k.pool);
  c.nodes = {copy_->nodes.data(), k.nodes};
  if (c.kind != Payload::kNone) c.payload = {copy_->payload.data(), k.nodes};
  c.memory = copy_;
  c.from_change = true;
  return c;
}

}  // namespace octovk
