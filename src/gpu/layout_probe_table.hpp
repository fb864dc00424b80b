// The host's half of the layout probe (internal: tests/layout_test.cpp reads it): where each
// marker shaders/layout_probe.comp writes must land. Generated with the probe's GLSL by
// cmake/LayoutProbe.cmake from the structs of gpu_types.h and octovk/device_types.h, as the
// table layout_probe_table.cpp in the build tree, which also static_asserts the sizes and
// offsets their comments state.
#pragma once

#include <cstddef>
#include <cstdint>
#include <span>

#include "gpu/gpu_types.h"

namespace octovk::gpu::layout {

/// How a marker is written: uint 0xC0DE0000 + id, float id + 0.5, double id + 0.25, uint64
/// 0xC0DE0000C0DE0000 + id, where id is the field's place in probedFields().
enum class Kind : std::uint32_t { kUint, kFloat, kDouble, kUint64 };

/// One scalar the probe writes: its GLSL name, and the binding and byte offset (C++ offsetof)
/// where its marker must land.
struct ProbedField {
  const char* name;
  std::uint32_t binding;
  std::size_t offset;
  Kind kind;
};

/// Bytes the probe writes whole (each struct's elements, field by field): a byte left unwritten
/// is padding the C++ struct has and the GLSL one does not name, or the other way round.
struct ProbedSpan {
  const char* name;
  std::uint32_t binding;
  std::size_t offset;
  std::size_t bytes;
};

/// A struct's size as its comment states it, and sizeof.
struct StatedSize {
  const char* name;
  std::size_t stated;
  std::size_t size;
};

std::span<const ProbedField> probedFields();
std::span<const ProbedSpan> probedSpans();
std::span<const StatedSize> statedSizes();

}  // namespace octovk::gpu::layout
