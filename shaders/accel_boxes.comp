#version 460
#extension GL_GOOGLE_include_directive : require
// The boxes the ray-tracing backend of castRay (cast_ray_rt.comp) traces against, into the
// AccelHeader's buffer (layout: gpu_types.h), each enlarged by a quarter cell (and a relative
// margin for the float arithmetic far from the origin) so that the acceleration structure's
// float test cannot miss a box that OctoMap's walk enters, then sorted along a Morton curve:
// kAccelBoxesOccupied: the occupied leaves of the leaf-box buffer (leaf_boxes.comp's rebuild),
//                      unsorted, with the extent of the small boxes' centres.
// kAccelBoxesScan:     for scans through ray tracing (scan_rays_rt.comp), one invocation per
//                      block: every leaf above clamp_min_log (occupied, or free and not clamped:
//                      a free update could change it) and the unknown regions, i.e. every missing
//                      child of a node that has children (a block's slots that are not live); a
//                      leaf clamped free gets no box. A block's slots give at most 8 boxes.
// kAccelBoxesCount, kAccelBoxesChunks, kAccelBoxesOffsets, kAccelBoxesScatter: a counting sort
//                      of the list on 2^(3 bucket_bits) Morton cells of that extent (the
//                      header's bucket_bits: kAccelBucketBits for castRay, fewer for a scan,
//                      whose fixed cost of clearing and summing the buckets counts per scan).
// kAccelBoxesTail:     the sorted list's slots after its count filled with an empty box outside
//                      the map, so that a build over the whole capacity, recorded before the
//                      count is known, finds nothing more where rays go.
// No node is written in this pass: links are read plainly (see linkOf).
#define OCTOVK_NODES_READ_ONLY
#include "tree_search.glsl"
#include "block_key.glsl"

layout(push_constant) uniform PushBlock { AccelBoxesConstants pc; };

layout(buffer_reference, std430, buffer_reference_align = 8) buffer AccelRef {
  AccelHeader header;
  AccelBox boxes[];
};
layout(buffer_reference, std430, buffer_reference_align = 4) buffer UintsRef { uint v[]; };

const uint kSmallBox = 64u;  // boxes of at most this many cells set the sort's extent

// The sorted list at box 0, the unsorted one after it, then the sort's counters.
UintsRef bucketCounters(AccelRef s) {
  uint64_t boxes = 2ul * uint64_t(s.header.box_capacity);
  return UintsRef(pc.boxes + 64ul + boxes * 24ul);
}
// The sort's buckets: 2^(3 * bucket_bits) (the header's; at most kAccelBuckets). The chunk sums
// follow the counters.
uint bucketsOf(AccelRef s) { return 1u << (3u * s.header.bucket_bits); }
uint chunkSum(AccelRef s, uint c) { return bucketsOf(s) + c; }

// A quarter cell for castRay's boxes; a 64th for a scan's (kAccelBoxesScan), whose walk looks
// every cell up anyway: near surfaces a ray grazes many boxes it never enters, each a ray query,
// and the hardware's float error is still a thousandth of that.
float margin(vec3 centre, float size) {
  float m = max(abs(centre.x), max(abs(centre.y), abs(centre.z))) + size;
  float part = pc.mode == kAccelBoxesScan ? 1.0 / 64.0 : 0.25;
  return float(params.resolution) * part + m * float(kRangeMargin);
}

// The cell key of a coordinate, clamped to the map.
uvec3 clampedKey(vec3 c) {
  dvec3 k = floor(params.resolution_factor * dvec3(c)) + 32768.0lf;
  return uvec3(clamp(k, dvec3(0.0lf), dvec3(65535.0lf)));
}

void append(AccelRef s, vec3 lo, vec3 hi, double size) {
  vec3 c = 0.5 * (lo + hi);
  float m = margin(c, float(size));
  uint at = atomicAdd(s.header.box_count, 1u);
  s.boxes[s.header.box_capacity + at] =
      AccelBox(lo.x - m, lo.y - m, lo.z - m, hi.x + m, hi.y + m, hi.z + m);
  if (size <= double(kSmallBox) * params.resolution) {
    uvec3 k = clampedKey(c);
    atomicMin(s.header.lo_x, k.x);
    atomicMin(s.header.lo_y, k.y);
    atomicMin(s.header.lo_z, k.z);
    atomicMax(s.header.hi_x, k.x);
    atomicMax(s.header.hi_y, k.y);
    atomicMax(s.header.hi_z, k.z);
  }
}

uint spreadBits(uint v, uint bits) {  // bits 0..bits-1 of v to bits 0, 3, 6, ...
  uint r = 0u;
  for (uint b = 0u; b < bits; ++b) r |= ((v >> b) & 1u) << (3u * b);
  return r;
}

// The Morton cell of box b's centre within the small boxes' extent (larger boxes are clamped).
uint bucketOf(AccelRef s, AccelBox b) {
  uvec3 lo = uvec3(s.header.lo_x, s.header.lo_y, s.header.lo_z);
  uvec3 hi = uvec3(s.header.hi_x, s.header.hi_y, s.header.hi_z);
  if (any(greaterThan(lo, hi))) {  // no small box: the whole map
    lo = uvec3(0u);
    hi = uvec3(65535u);
  }
  uint extent = max(hi.x - lo.x, max(hi.y - lo.y, hi.z - lo.z));
  uint shift = 0u;
  uint bits = s.header.bucket_bits;
  while ((extent >> shift) >= (1u << bits)) ++shift;
  uvec3 k = clampedKey(0.5 * vec3(b.min_x + b.max_x, b.min_y + b.max_y, b.min_z + b.max_z));
  uvec3 q = min((max(k, lo) - lo) >> shift, uvec3((1u << bits) - 1u));
  return spreadBits(q.x, bits) | (spreadBits(q.y, bits) << 1) | (spreadBits(q.z, bits) << 2);
}

void main() {
  uint i = invocationIndex();
  AccelRef s = AccelRef(pc.boxes);
  if (pc.mode == kAccelBoxesOccupied) {
    if (i >= pool.leaf_count) return;
    LeafBox leaf = LEAF_BOXES[i];
    if (leaf.log_odds < params.occupancy_log) return;
    vec3 c = vec3(leaf.center_x, leaf.center_y, leaf.center_z);
    float half_size = leaf.size * 0.5;
    append(s, c - half_size, c + half_size, double(leaf.size));
    return;
  }
  if (pc.mode == kAccelBoxesScan) {
    if (i >= pool.bump) return;
    if (i == 0u) {  // block 0 holds only the root: a box when it is a leaf (the whole map)
      if (pool.root_exists != 0u && childBlock(kRootNode) == kNoChildren &&
          !(nodeLogOdds(kRootNode) <= params.clamp_min_log)) {
        double size = params.resolution * 65536.0lf;
        vec3 lo = vec3(-0.5lf * size);
        append(s, lo, -lo, size);
      }
      return;
    }
    uint parent = BLOCK_PARENT[i];
    if (parent == kNoBlock) return;
    uint depth;
    uvec3 parent_key = parentKeyOfBlock(parent, depth);
    uint bit = 15u - depth;
    double size = params.resolution * double(1u << bit);
    for (uint slot = 0u; slot < 8u; ++slot) {
      uint child = i * 8u + slot;
      uint link = linkOf(child);
      // classify's early abort for a free update: the leaf search() finds is at clamp_min_log.
      if (linkLive(link) && (linkHasChildren(link) || nodeLogOdds(child) <= params.clamp_min_log))
        continue;
      uvec3 key = parent_key | (uvec3(slot & 1u, (slot >> 1) & 1u, (slot >> 2) & 1u) << bit);
      // The region's lower corner, (key - 32768) * resolution, exact in double.
      dvec3 lo = dvec3(ivec3(key) - ivec3(32768)) * params.resolution;
      append(s, vec3(lo), vec3(lo + size), size);
    }
    return;
  }
  if (pc.mode == kAccelBoxesTail) {
    if (i >= s.header.box_capacity || i < s.header.box_count) return;
    // Not the spec's inactive box (min x NaN): lavapipe copies it into its BVH, whose bounds
    // then turn NaN (MIN2(a, NaN) is NaN) and every ray misses. A point two cells outside the
    // map's lower corner instead: no ray of a scan (between two points of the map) comes near.
    float far = float(-(double(kTreeMaxVal) + 2.0lf) * params.resolution);
    s.boxes[i] = AccelBox(far, far, far, far, far, far);
    return;
  }
  if (pc.mode == kAccelBoxesChunks || pc.mode == kAccelBoxesOffsets) {
    if (i >= kAccelChunks) return;
    uint c = i;
    UintsRef n = bucketCounters(s);
    const uint per_chunk = bucketsOf(s) / kAccelChunks;
    uint first = c * per_chunk;
    if (pc.mode == kAccelBoxesChunks) {
      uint sum = 0u;
      for (uint b = 0u; b < per_chunk; ++b) sum += n.v[first + b];
      n.v[chunkSum(s, c)] = sum;
      return;
    }
    uint offset = 0u;
    for (uint p = 0u; p < c; ++p) offset += n.v[chunkSum(s, p)];
    for (uint b = 0u; b < per_chunk; ++b) {
      uint count = n.v[first + b];
      n.v[first + b] = offset;
      offset += count;
    }
    return;
  }
  // kAccelBoxesCount, kAccelBoxesScatter: one invocation per unsorted box.
  if (i >= s.header.box_count) return;
  AccelBox b = s.boxes[s.header.box_capacity + i];
  uint at = bucketOf(s, b);
  UintsRef n = bucketCounters(s);
  if (pc.mode == kAccelBoxesCount) {
    atomicAdd(n.v[at], 1u);
    return;
  }
  s.boxes[atomicAdd(n.v[at], 1u)] = b;
}
