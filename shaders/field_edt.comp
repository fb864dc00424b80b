#version 450
#extension GL_GOOGLE_include_directive : require
// The second and third axes of the exact Euclidean distance transform (Felzenszwalb and
// Huttenlocher's lower envelope of parabolas, in integers): one invocation per line of the box
// along pc.axis, y (line (x, z), reading line_x, writing plane_xy) or z (line (x, y), reading
// plane_xy, writing sites). For each cell p of the line, out(p) = the nearest obstacle of
// argmin over the line's cells q of in(q) + (p - q)^2, where in(q) is the squared distance from
// q to its nearest obstacle so far (along x; in the z-plane). The squared Euclidean distance
// separates by axis, so after z every cell names an obstacle at the exact minimum distance.
// Invocation i runs the line at x = i % size_x: neighbouring invocations read and write
// neighbouring words. Integers: sizes are at most kFieldMaxAxisCells, so every squared distance
// and sum below stays under 2^31; the parabolas' crossing is a floor of a quotient of integers
// below 2^31 by one below 2^16, exact in double.
// The envelope (entry k: t(k) | v(k) << 16, parabola v(k) wins from cell t(k) on, and v(k)'s
// input, its nearest obstacle so far) is built in the line's cells of the envelope scratch. With pc.full == 0 only lines marked dirty are
// redone; along y a z-line is marked dirty wherever the answer changed (other lines' inputs did
// not change, so they would give the same answers). Each line is owned by one invocation.
// A line costs at most 4 n + 8 loop iterations (field_passes.hpp bounds n); a loop that ends
// early sets kFieldStatusCut.
#include "field.glsl"

layout(push_constant) uniform PushBlock { FieldEdtConstants pc; };

// The squared distance from the line's cell at (x, y) to the obstacle `site` in the input's
// packing: line_x holds its x (along y), plane_xy its x | y << 16 (along z).
int squaredTo(uint site, uint x, uint y) {
  int dx = int(x) - int(site & 0xFFFFu);
  if (pc.axis == 1u) return dx * dx;
  int dy = int(y) - int(site >> 16);
  return dx * dx + dy * dy;
}

void main() {
  FieldHeaderRef f = FieldHeaderRef(pc.header);
  uvec3 size = fieldSize(f);
  uint i = invocationIndex();
  bool along_y = pc.axis == 1u;
  if (i >= size.x * (along_y ? size.z : size.y)) return;
  uint x = i % size.x;
  uint y = i / size.x;  // the line's y along z (unused along y)
  bool full = pc.full != 0u;
  if (!full && !fieldDirty(f, along_y ? f.h.dirty_y : f.h.dirty_z, i)) return;
  uint base, stride;
  int n;
  if (along_y) {
    base = x + size.x * size.y * (i / size.x);
    stride = size.x;
    n = int(size.y);
  } else {
    base = x + size.x * y;
    stride = size.x * size.y;
    n = int(size.z);
  }
  FieldWordsRef in_v = FieldWordsRef(along_y ? f.h.line_x : f.h.plane_xy);
  FieldPairsRef env = FieldPairsRef(f.h.envelope);
  FieldWordsRef out_v = FieldWordsRef(along_y ? f.h.plane_xy : f.h.sites);

  // The lower envelope, first cell to last.
  int k = -1;
  int q = 0;
  for (; q < n; ++q) {
    uint sq = in_v.v[base + uint(q) * stride];
    if (sq == kFieldNone) continue;
    int fq = squaredTo(sq, x, y);
    bool push = true;
    while (k >= 0) {
      uvec2 e = env.v[base + uint(k) * stride];
      int t = int(e.x & 0xFFFFu), v = int(e.x >> 16);
      int fv = squaredTo(e.y, x, y);
      // q is at least as near as v where v starts winning, so from there on: v never wins.
      if (fv + (t - v) * (t - v) >= fq + (t - q) * (t - q)) {
        --k;
        continue;
      }
      // q wins strictly from the first integer after the parabolas' crossing (the numerator is
      // > 0 here: q does not win at t(k) >= 0 and v < q).
      int num = q * q - v * v + fq - fv;
      int w = int(floor(double(num) / double(2 * (q - v)))) + 1;
      push = w < n;
      if (push) {
        ++k;
        env.v[base + uint(k) * stride] = uvec2(uint(w) | (uint(q) << 16), sq);
      }
      break;
    }
    if (k < 0) {
      k = 0;
      env.v[base] = uvec2(uint(q) << 16, sq);
    }
  }
  // Last cell to first: each cell takes the parabola whose region holds it.
  uvec2 e = k >= 0 ? env.v[base + uint(k) * stride] : uvec2(0u);
  int p = n - 1;
  for (; p >= 0; --p) {
    uint answer = kFieldNone;
    if (k >= 0) {
      while (int(e.x & 0xFFFFu) > p) {
        --k;
        e = env.v[base + uint(k) * stride];
      }
      uint v = e.x >> 16;
      uint site = e.y;
      answer = along_y ? site | (v << 16)
                       : (site & 0xFFFFu) + size.x * ((site >> 16) + size.y * v);
    }
    uint at = base + uint(p) * stride;
    if (full || !along_y) {
      out_v.v[at] = answer;
    } else if (out_v.v[at] != answer) {
      out_v.v[at] = answer;
      markFieldDirty(f, f.h.dirty_z, x + size.x * uint(p));
    }
  }
  if (q != n || p != -1) atomicOr(f.h.status, kFieldStatusCut);
}
