#version 450
#extension GL_GOOGLE_include_directive : require
// One axis of the exact Euclidean distance transform (Felzenszwalb and Huttenlocher's lower
// envelope of parabolas, in integers): one invocation per line of the box along pc.axis. For each
// cell x of the line, out(x) = min over the line's cells q of in(q).squared + (x - q)^2, with
// in(q)'s site. Run along x, y and z in turn over the obstacles, this is the squared distance to
// the nearest obstacle of the box (the minimum separates by axis). Exact: integer arithmetic in
// 64 bits, each line owned by one invocation, no order between invocations.
// The envelope (t: where parabola k starts winning, v: its cell) is kept in the line's own output
// cells while it is built: entry k sits at cell k <= t(k), and the backward pass writes cell x
// only after the entries it still needs (k <= x) were read.
// Each line costs at most 4 n loop iterations; the host keeps n below the driver's loop budget,
// and a loop that ends early anyway sets kFieldStatusCut.
#include "field.glsl"

layout(push_constant) uniform PushBlock { FieldEdtConstants pc; };

void main() {
  FieldHeaderRef f = FieldHeaderRef(pc.header);
  uvec3 size = fieldSize(f);
  uint axis = pc.axis, a1 = (axis + 1u) % 3u, a2 = (axis + 2u) % 3u;
  uint line = invocationIndex();
  if (line >= size[a1] * size[a2]) return;
  uvec3 c = uvec3(0u);
  c[a1] = line % size[a1];
  c[a2] = line / size[a1];
  uint base = c.x + size.x * (c.y + size.y * c.z);
  uint stride = axis == 0u ? 1u : (axis == 1u ? size.x : size.x * size.y);
  int n = int(size[axis]);
  FieldCellsRef src = FieldCellsRef(pc.from_b == 0u ? f.h.cells_a : f.h.cells_b);
  FieldCellsRef dst = FieldCellsRef(pc.from_b == 0u ? f.h.cells_b : f.h.cells_a);

  // The lower envelope, left to right. Entry k: squared = t(k), site = v(k).
  int k = -1;
  int q = 0;
  for (; q < n; ++q) {
    uint fq = src.v[base + uint(q) * stride].squared;
    if (fq == kFieldFar) continue;
    bool push = true;
    while (k >= 0) {
      FieldCell e = dst.v[base + uint(k) * stride];
      int64_t t = int64_t(e.squared), v = int64_t(e.site);
      int64_t fv = int64_t(src.v[base + e.site * stride].squared);
      // q is at least as near as v where v starts winning, so from there on: v never wins.
      if (fv + (t - v) * (t - v) >= int64_t(fq) + (t - q) * (t - q)) {
        --k;
        continue;
      }
      // q wins strictly from the first integer after the parabolas' crossing (> t(k) >= 0 here,
      // so the division truncates as floor).
      int64_t num = int64_t(q) * q - v * v + int64_t(fq) - fv;
      int64_t w = num / (2 * (int64_t(q) - v)) + 1;
      push = w < int64_t(n);
      if (push) {
        ++k;
        dst.v[base + uint(k) * stride] = FieldCell(uint(w), uint(q));
      }
      break;
    }
    if (k < 0) {
      k = 0;
      dst.v[base] = FieldCell(0u, uint(q));
    }
  }
  // Right to left: each cell takes the parabola whose region holds it.
  int x = n - 1;
  if (k < 0) {
    for (; x >= 0; --x) dst.v[base + uint(x) * stride] = FieldCell(kFieldFar, kFieldNoSite);
  } else {
    FieldCell e = dst.v[base + uint(k) * stride];
    for (; x >= 0; --x) {
      while (int(e.squared) > x) {
        --k;
        e = dst.v[base + uint(k) * stride];
      }
      FieldCell s = src.v[base + e.site * stride];
      int64_t d = int64_t(x) - int64_t(e.site);
      dst.v[base + uint(x) * stride] = FieldCell(uint(int64_t(s.squared) + d * d), s.site);
    }
  }
  if (q != n || x != -1) atomicOr(f.h.status, kFieldStatusCut);
}
