#include "map/change_set.hpp"

#include <algorithm>
#include <cstring>
#include <string>
#include <utility>

#include "map/buffer_sizes.hpp"

namespace octovk {

gpu::ChangeHeader ChangeSet::header() {
  MapCore& core = core_;
  core.stream.begin(core.buffers.bindings);
  core.stream.copy(core.buffers.changes, core.buffers.query_staging_out, sizeof(gpu::ChangeHeader));
  core.stream.submitAndWait();
  gpu::ChangeHeader header;
  std::memcpy(&header, core.buffers.query_staging_out.mapped(), sizeof(header));
  return header;
}

void ChangeSet::grow(std::uint64_t keys) {
  MapCore& core = core_;
  std::uint32_t log2 = std::max(core.buffers.changesLog2(), kInitialChangesLog2);
  while (log2 < 31 && keys > (std::uint64_t{1} << log2) - (std::uint64_t{1} << log2) / 4) ++log2;
  if (keys > (std::uint64_t{1} << log2) - (std::uint64_t{1} << log2) / 4)
    throw Error(ErrorCode::kOutOfDeviceMemory,
                "change detection: more than 2^30 changed keys; call resetChangeDetection() "
                "after reading them");
  if (log2 == core.buffers.changesLog2()) return;
  ++rehashes_;  // the rehash drops the keys that flipped back (fieldTracking)
  const std::uint32_t old_log2 = core.buffers.changesLog2();
  const std::uint32_t old_slots = std::uint32_t{1} << old_log2;
  vk::Buffer old = core.buffers.replaceChanges(log2);  // under the cap; nothing changed if not
  try {
    gpu::ScanParams sp = core.queryParams();
    sp.changes_log2 = log2;
    core.stream.begin(core.buffers.bindings);
    core.rec.setParams(sp);
    core.stream.barrier();
    passes::recordRehashChanges(core.rec, old.address(), old_slots);
    core.stream.submitAndWait();
  } catch (...) {  // the new set may hold part of the keys: the old one goes back
    core.buffers.restoreChanges(std::move(old), old_log2);
    throw;
  }
}

void ChangeSet::enableByUser(bool on) {
  if (on && core_.buffers.changesLog2() == 0) grow(1);
  enabled_ = on;
  by_user_ = true;
  by_fields_ = false;
}

void ChangeSet::reset() {
  ++epoch_;
  core_.buffers.resetChanges();
}

void ChangeSet::release() {
  enabled_ = false;
  if (core_.buffers.changesLog2() == 0) return;
  ++epoch_;
  (void)core_.buffers.replaceChanges(0);  // the old set goes with the returned buffer
}

void ChangeSet::followByField() {
  if (!by_user_ && !enabled_) {
    if (core_.buffers.changesLog2() == 0) grow(1);
    enabled_ = true;
    by_fields_ = true;
  }
  ++fields_;
}

void ChangeSet::unfollowByField() {
  if (fields_ > 0 && --fields_ == 0 && by_fields_) {
    by_fields_ = false;
    release();
  }
}

bool ChangeSet::resetForField() {
  if (!by_fields_ || fields_ != 1) return false;
  reset();
  return true;
}

std::size_t ChangeSet::count() { return header().live; }

std::vector<ChangedKey> ChangeSet::keys() {
  const gpu::ChangeHeader header = this->header();
  if (header.live == 0) return {};
  const std::size_t bytes = sizeof(gpu::ChangedKeysHeader) + header.live * sizeof(gpu::ChangedKey);
  core_.buffers.ensureQueries(sizes::kSmallQuery, bytes);
  core_.stream.begin(core_.buffers.bindings);
  passes::recordListChanges(core_.rec, core_.queryParams());
  core_.stream.copy(core_.buffers.query_out, core_.buffers.query_staging_out, bytes);
  core_.stream.submitAndWait();
  gpu::ChangedKeysHeader out_header;
  const auto* mapped = static_cast<const unsigned char*>(core_.buffers.query_staging_out.mapped());
  std::memcpy(&out_header, mapped, sizeof(out_header));
  if (out_header.count != header.live)
    throw Error(ErrorCode::kInternal,
                "change detection: the set lists " + std::to_string(out_header.count) +
                    " keys, its header counts " + std::to_string(header.live));
  std::vector<ChangedKey> out(header.live);
  for (std::size_t i = 0; i < out.size(); ++i) {
    gpu::ChangedKey k;
    std::memcpy(&k, mapped + sizeof(out_header) + i * sizeof(k), sizeof(k));
    out[i].key = {static_cast<std::uint16_t>(k.key_x), static_cast<std::uint16_t>(k.key_y),
                  static_cast<std::uint16_t>(k.key_z)};
    out[i].created = k.created != 0;
  }
  return out;
}

void ChangeSet::onDevice(VkBuffer out, VkDeviceSize out_offset, VkDeviceSize out_size) {
  const VkDeviceSize align = core_.device.storageOffsetAlignment();
  if (out == VK_NULL_HANDLE)
    throw Error(ErrorCode::kInvalidArgument, "changedKeysOnDevice: the buffer is VK_NULL_HANDLE");
  if (out_offset % align != 0)
    throw Error(ErrorCode::kInvalidArgument,
                "changedKeysOnDevice: the offset must be a multiple of " + std::to_string(align) +
                    " (minStorageBufferOffsetAlignment)");
  const std::size_t live = header().live;
  const std::size_t bytes = sizeof(gpu::ChangedKeysHeader) + live * sizeof(gpu::ChangedKey);
  if (out_size < bytes)
    throw Error(ErrorCode::kInvalidArgument,
                "changedKeysOnDevice: " + std::to_string(live) + " changed keys need " +
                    std::to_string(bytes) + " bytes, the range has " + std::to_string(out_size));
  core_.buffers.bindings.updateRange(gpu::kBindQueryOut, out, out_offset, out_size);
  try {
    core_.stream.begin(core_.buffers.bindings);
    passes::recordListChanges(core_.rec, core_.queryParams());
    core_.stream.submitAndWait();
  } catch (...) {
    core_.buffers.rebind();
    throw;
  }
  core_.buffers.rebind();
}

}  // namespace octovk
