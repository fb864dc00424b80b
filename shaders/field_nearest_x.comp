#version 450
#extension GL_GOOGLE_include_directive : require
// The first axis of the exact Euclidean distance transform: one invocation per x-line of the
// box (y, z): for each cell x, the x of the nearest obstacle on the line (the nearer of the last
// one at or before x and the first one at or after it, the lower on a tie), read from the
// occupancy bits, into line_x (kFieldNone on a line without obstacles). With pc.full == 0 only
// the lines marked dirty are redone, and a y-line (x, z) is marked dirty wherever the answer
// changed; the other lines keep their answers, which their unchanged bits would give again.
// Each line is owned by one invocation. A line costs at most n + n / 32 + 2 loop iterations (field_passes.hpp
// bounds n); a loop that ends early sets kFieldStatusCut.
#include "field.glsl"

layout(push_constant) uniform PushBlock { FieldEdtConstants pc; };

// The first obstacle of the line at or after `from` (n where none). A word loop that ends
// before the line's last word without finding one was cut short: kFieldStatusCut.
int nextObstacle(FieldHeaderRef f, FieldWordsRef occ, uint row_word, int from, int n) {
  if (from >= n) return n;
  uint w = uint(from) / 32u;
  uint words = (uint(n) + 31u) / 32u;
  uint bits = occ.v[row_word + w] & (0xFFFFFFFFu << (uint(from) % 32u));
  while (bits == 0u && w + 1u < words) bits = occ.v[row_word + (++w)];
  if (bits == 0u) {
    if (w + 1u < words) atomicOr(f.h.status, kFieldStatusCut);
    return n;
  }
  return min(int(w * 32u) + findLSB(bits), n);
}

void main() {
  FieldHeaderRef f = FieldHeaderRef(pc.header);
  uvec3 size = fieldSize(f);
  uint row = invocationIndex();
  if (row >= size.y * size.z) return;
  bool full = pc.full != 0u;
  if (!full && !fieldDirty(f, 0u, row)) return;
  FieldWordsRef occ = FieldWordsRef(f.h.occupancy);
  FieldWordsRef out_x = FieldWordsRef(f.h.line_x);
  uint row_word = row * f.h.words_per_row;
  uint base = row * size.x;
  uint z = row / size.y;
  int n = int(size.x);
  int before = -1;  // the last obstacle at or before x
  int after = nextObstacle(f, occ, row_word, 0, n);
  int x = 0;
  for (; x < n; ++x) {
    if (x > after) after = nextObstacle(f, occ, row_word, x, n);
    if (x == after) before = x;
    uint nearest = kFieldNone;
    if (before >= 0 && (after >= n || x - before <= after - x)) nearest = uint(before);
    else if (after < n) nearest = uint(after);
    if (full) {
      out_x.v[base + uint(x)] = nearest;
    } else if (out_x.v[base + uint(x)] != nearest) {
      out_x.v[base + uint(x)] = nearest;
      markFieldDirty(f, f.h.dirty_y, uint(x) + size.x * z);
    }
  }
  if (x != n) atomicOr(f.h.status, kFieldStatusCut);
}
