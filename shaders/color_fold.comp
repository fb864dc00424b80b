#version 450
#extension GL_GOOGLE_include_directive : require
// A colour scan's colours folded into the map after its tree passes: for every point i, in the
// cloud's order, ColorOcTree::averageNodeColor(point_i, colour_i) (or integrateNodeColor) on the
// node search() finds.
// Points that fall in one node are folded in order by one invocation; nodes are independent.
// The points come in chunks of consecutive indices (all at once where loops are not limited),
// each chunk grouped and folded before the next: the order is kept across chunks.
// kColorFoldGroup (per point): its node (a NaN point, one outside the map or in unknown space
//   has none and is skipped, as OctoMap's coordToKeyChecked / search skip it), that node's entry
//   in the table (open addressing, claimed by compare-and-swap), and the point pushed on the
//   entry's list (atomic exchange of the head; the links say nothing of the order).
// kColorFoldAverage, kColorFoldIntegrate (per table entry): the entry's list sorted by point
//   index (a merge sort of the linked list, n log n, in place), then the fold in that order on the
//   node's colour. The node's log-odds (integrateNodeColor's weight) is final by then: the fold
//   changes colours only.
// Each node whose colour changes goes on the folded list (FoldedNode), for a store's capture.
// Nothing is done for a scan the device refused (kStatusNotApplied): it runs again whole.
#define OCTOVK_NODES_READ_ONLY
#include "tree_search.glsl"
#include "probability.glsl"

layout(push_constant) uniform PushBlock { ColorFoldConstants pc; };

uint tableWord(uint entry, uint w) { return 2u * entry + w; }
uint pointWord(uint p, uint w) { return (2u << pc.table_log2) + 2u * p + w; }
uint colorOf(uint p) { return COLOR_FOLD[pointWord(p, 0u)]; }
uint linkAfter(uint p) { return COLOR_FOLD[pointWord(p, 1u)]; }
void setLinkAfter(uint p, uint next) { COLOR_FOLD[pointWord(p, 1u)] = next; }

// Simon Tatham's bottom-up merge sort of a singly linked list, by point index.
uint sortedList(uint head) {
  for (uint run = 1u;; run *= 2u) {
    uint p = head, tail = kFoldEmpty, merges = 0u;
    head = kFoldEmpty;
    while (p != kFoldEmpty) {
      ++merges;
      uint q = p, p_size = 0u;
      for (uint i = 0u; i < run && q != kFoldEmpty; ++i) {
        ++p_size;
        q = linkAfter(q);
      }
      uint q_size = run;
      while (p_size > 0u || (q_size > 0u && q != kFoldEmpty)) {
        uint e;
        if (p_size == 0u) {
          e = q;
          q = linkAfter(q);
          --q_size;
        } else if (q_size == 0u || q == kFoldEmpty || p < q) {
          e = p;
          p = linkAfter(p);
          --p_size;
        } else {
          e = q;
          q = linkAfter(q);
          --q_size;
        }
        if (tail == kFoldEmpty) head = e;
        else setLinkAfter(tail, e);
        tail = e;
      }
      p = q;
    }
    if (tail != kFoldEmpty) setLinkAfter(tail, kFoldEmpty);
    if (merges <= 1u) return head;
  }
  return head;
}

// averageNodeColor's step: an unset colour takes the new one, a set one the int mean per channel.
uint averaged(uint old, uint c) {
  if (!colorSet(old)) return c;
  uvec3 a = uvec3(old & 0xFFu, (old >> 8) & 0xFFu, (old >> 16) & 0xFFu);
  uvec3 b = uvec3(c & 0xFFu, (c >> 8) & 0xFFu, (c >> 16) & 0xFFu);
  uvec3 m = (a + b) / 2u;
  return m.x | (m.y << 8) | (m.z << 16);
}

// integrateNodeColor's step: an unset colour takes the new one; a set one
// old * p + new * (0.99 - p) per channel in double, p the node's occupancy (probability.glsl),
// `weight_new` = 0.99 - p.
uint integratedChannel(uint old, uint c, double p, double weight_new) {
  precise double v = double(old) * p + double(c) * weight_new;
  // OctoMap's (uint8_t) of that double, as x86-64 GCC compiles it (liboctomap's cvttsd2si): to a
  // 32-bit int toward zero, the low 8 bits kept. v is in (-3, 256); it is negative only where p >
  // 0.99 (a clamping_max above 0.99): -1.3 gives -1, so 255. (C++ leaves it undefined.)
  precise double toward_zero = v >= 0.0lf ? floor(v) : -floor(-v);
  return uint(int(toward_zero)) & 0xFFu;
}

uint integrated(uint old, uint c, double p, double weight_new) {
  if (!colorSet(old)) return c;
  return integratedChannel(old & 0xFFu, c & 0xFFu, p, weight_new) |
         (integratedChannel((old >> 8) & 0xFFu, (c >> 8) & 0xFFu, p, weight_new) << 8) |
         (integratedChannel((old >> 16) & 0xFFu, (c >> 16) & 0xFFu, p, weight_new) << 16);
}

void main() {
  if ((counters.status & kStatusNotApplied) != 0u) return;
  uint i = invocationIndex();
  uint mask = (1u << pc.table_log2) - 1u;
  if (pc.mode == kColorFoldGroup) {
    if (i >= pc.count) return;
    uint p = pc.first + i;
    uvec3 k;
    if (!coordToKeyChecked(POINTS[3u * p], k.x) || !coordToKeyChecked(POINTS[3u * p + 1u], k.y) ||
        !coordToKeyChecked(POINTS[3u * p + 2u], k.z))
      return;
    uint node, depth;
    if (!searchNode(k, node, depth)) return;
    // The load of the table is at most a half (2^table_log2 >= 2 * a chunk's points): a free
    // entry is always found.
    uint e = (node * 2654435761u) & mask;
    for (;;) {
      uint was = atomicCompSwap(COLOR_FOLD[tableWord(e, 0u)], kFoldEmpty, node);
      if (was == kFoldEmpty || was == node) break;
      e = (e + 1u) & mask;
    }
    setLinkAfter(p, atomicExchange(COLOR_FOLD[tableWord(e, 1u)], p));
    return;
  }
  // kColorFoldAverage, kColorFoldIntegrate
  if (i > mask) return;
  uint node = COLOR_FOLD[tableWord(i, 0u)];
  if (node == kFoldEmpty) return;
  uint before = nodePayload(node);
  uint c = before;
  uint p = sortedList(COLOR_FOLD[tableWord(i, 1u)]);
  uint first = p;
  if (pc.mode == kColorFoldAverage) {
    for (; p != kFoldEmpty; p = linkAfter(p)) c = averaged(c, colorOf(p));
  } else {
    precise double occupancy = occupancyProbability(nodeLogOdds(node));
    precise double weight_new = doubleOfBits(0x3FEFAE14u, 0x7AE147AEu) - occupancy;  // 0.99 - p
    for (; p != kFoldEmpty; p = linkAfter(p)) c = integrated(c, colorOf(p), occupancy, weight_new);
  }
  setNodePayload(node, c);
  if (c == before) return;
  // The folded list, after the points' words: the node, and where it lies (a key of one of its
  // points, its depth).
  uvec3 k;
  coordToKeyChecked(POINTS[3u * first], k.x);  // in the map: the point was grouped
  coordToKeyChecked(POINTS[3u * first + 1u], k.y);
  coordToKeyChecked(POINTS[3u * first + 2u], k.z);
  uint found, depth;
  searchNode(k, found, depth);
  uint at = pointWord(params.point_count, 0u) + 3u * atomicAdd(counters.folded_count, 1u);
  COLOR_FOLD[at] = node;
  COLOR_FOLD[at + 1u] = k.x | (k.y << 16);
  COLOR_FOLD[at + 2u] = k.z | (depth << 16);
}
