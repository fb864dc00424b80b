// The distance field's buffers (gpu_types.h, FieldHeader): the header by the device address a
// pass gets in its push constants, its arrays by the addresses in the header; the dirty bitmaps.
#ifndef OCTOVK_FIELD_GLSL
#define OCTOVK_FIELD_GLSL

#include "bindings.glsl"

layout(buffer_reference, std430, buffer_reference_align = 8) buffer FieldHeaderRef {
  FieldHeader h;
};
layout(buffer_reference, std430, buffer_reference_align = 4) buffer FieldWordsRef {
  uint v[];
};
layout(buffer_reference, std430, buffer_reference_align = 8) buffer FieldPairsRef {
  uvec2 v[];
};

uvec3 fieldSize(FieldHeaderRef f) { return uvec3(f.h.size_x, f.h.size_y, f.h.size_z); }
uvec3 fieldMinKey(FieldHeaderRef f) { return uvec3(f.h.min_key_x, f.h.min_key_y, f.h.min_key_z); }

// Cell index i of a box of `size` as (x, y, z).
uvec3 fieldCell(uint i, uvec3 size) {
  return uvec3(i % size.x, (i / size.x) % size.y, i / (size.x * size.y));
}

// Bit `bit` of the dirty bitmap starting at word `first`.
bool fieldDirty(FieldHeaderRef f, uint first, uint bit) {
  return (FieldWordsRef(f.h.dirty).v[first + bit / 32u] & (1u << (bit % 32u))) != 0u;
}
// Many invocations mark bits of one word in the same dispatch: atomically.
void markFieldDirty(FieldHeaderRef f, uint first, uint bit) {
  atomicOr(FieldWordsRef(f.h.dirty).v[first + bit / 32u], 1u << (bit % 32u));
}

#endif  // OCTOVK_FIELD_GLSL
