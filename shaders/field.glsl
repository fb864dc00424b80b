// The distance field's buffers (gpu_types.h, FieldHeader): the header by the device address a
// pass gets in its push constants, the two FieldCell arrays by the addresses in the header.
#ifndef OCTOVK_FIELD_GLSL
#define OCTOVK_FIELD_GLSL

#include "bindings.glsl"

layout(buffer_reference, std430, buffer_reference_align = 8) buffer FieldHeaderRef {
  FieldHeader h;
};
layout(buffer_reference, std430, buffer_reference_align = 8) buffer FieldCellsRef {
  FieldCell v[];
};

uvec3 fieldSize(FieldHeaderRef f) { return uvec3(f.h.size_x, f.h.size_y, f.h.size_z); }
uvec3 fieldMinKey(FieldHeaderRef f) { return uvec3(f.h.min_key_x, f.h.min_key_y, f.h.min_key_z); }

// Cell index i of a box of `size` as (x, y, z).
uvec3 fieldCell(uint i, uvec3 size) {
  return uvec3(i % size.x, (i / size.x) % size.y, i / (size.x * size.y));
}

#endif  // OCTOVK_FIELD_GLSL
