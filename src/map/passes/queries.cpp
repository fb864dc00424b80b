// Queries on the map: lookup.comp (OctoMap's search) and cast_ray.comp (OctoMap's castRay), in
// one batch: the rays, then the lookup points, in the input; their results in the same order in
// the output, castRay's walk states after them.
#include <algorithm>
#include <cmath>
#include <cstring>
#include <limits>
#include <utility>

#include "map/passes/passes.hpp"
#include "map/walk_budget.hpp"

namespace octovk::passes {

std::uint32_t firstRayState(std::size_t results) {
  return static_cast<std::uint32_t>((results * sizeof(gpu::RayResult) + sizeof(gpu::RayState) - 1) /
                                    sizeof(gpu::RayState));
}

std::size_t queryOutputBytes(std::size_t rays, std::size_t lookups) {
  static_assert(sizeof(gpu::RayResult) == sizeof(gpu::LookupResult));
  return (firstRayState(rays + lookups) + rays) * sizeof(gpu::RayState);
}

namespace {

// The low 5 bits of a spread to every third bit, the low 8 bits of b to every second bit: one
// coordinate of a 3D / 2D Morton code.
std::uint32_t spread3(std::uint32_t a) {
  a &= 0x1Fu;
  a = (a | (a << 8)) & 0x0300Fu;
  a = (a | (a << 4)) & 0x030C3u;
  a = (a | (a << 2)) & 0x09249u;
  return a;
}
std::uint32_t spread2(std::uint32_t b) {
  b &= 0xFFu;
  b = (b | (b << 4)) & 0x0F0Fu;
  b = (b | (b << 2)) & 0x3333u;
  b = (b | (b << 1)) & 0x5555u;
  return b;
}

// v (any float, NaN included) as an integer in [0, top]: clamped, NaN to 0.
std::uint32_t clampToInt(float v, float top) {
  if (!(v > 0.0f)) return 0;
  return v >= top ? static_cast<std::uint32_t>(top) : static_cast<std::uint32_t>(v);
}

// Where a ray sorts (32 bits): its kind (bit 31), then the block of 64 cells its origin lies in
// (bits 16..30: a Morton code of the blocks' coordinates modulo 32, so neighbouring blocks stay
// together), then its direction on the octahedral map (bits 0..15: a Morton code of 256 x 256
// cells). Only grouping matters; nothing depends on the order.
std::uint32_t rayKey(const Ray& ray, float inv_block) {
  std::uint32_t origin = 0;
  for (int a = 0; a < 3; ++a) {
    // The block index modulo 32, from the coordinate offset by 2^20 blocks (clamped: no
    // conversion of an out-of-range float).
    const float b = ray.origin[a] * inv_block + 1048576.0f;
    origin |= spread3(clampToInt(b, 2097151.0f)) << a;
  }
  // The octahedral map: the direction onto |x| + |y| + |z| = 1, the lower half folded out.
  const float x = ray.direction.x(), y = ray.direction.y(), z = ray.direction.z();
  const float l1 = std::abs(x) + std::abs(y) + std::abs(z);
  float u = 0.0f, v = 0.0f;
  if (l1 > 0.0f && l1 <= std::numeric_limits<float>::max()) {
    u = x / l1;
    v = y / l1;
    if (z < 0.0f) {
      const float fu = (1.0f - std::abs(v)) * (u >= 0.0f ? 1.0f : -1.0f);
      v = (1.0f - std::abs(u)) * (v >= 0.0f ? 1.0f : -1.0f);
      u = fu;
    }
  }
  const std::uint32_t direction = spread2(clampToInt((u + 1.0f) * 128.0f, 255.0f)) |
                                  spread2(clampToInt((v + 1.0f) * 128.0f, 255.0f)) << 1;
  return (ray.ignore_unknown ? 1u : 0u) << 31 | origin << 16 | direction;
}

}  // namespace

std::vector<std::uint32_t> rayOrder(std::span<const Ray> rays, double resolution,
                                    std::uint32_t& stop_rays) {
  // A stable LSD radix sort of key << 32 | index on the key's three 11-bit digits; a digit all
  // rays share is skipped (the kind, where all are of one kind).
  const auto inv_block = static_cast<float>(1.0 / (resolution * 64.0));
  std::vector<std::uint64_t> a(rays.size()), b(rays.size());
  stop_rays = 0;
  for (std::size_t i = 0; i < rays.size(); ++i) {
    a[i] = std::uint64_t{rayKey(rays[i], inv_block)} << 32 | i;
    stop_rays += rays[i].ignore_unknown ? 0u : 1u;
  }
  constexpr unsigned kDigit = 11;
  constexpr std::uint64_t kMask = (1u << kDigit) - 1u;
  std::vector<std::uint32_t> count(std::size_t{1} << kDigit);
  for (unsigned shift = 32; shift < 64; shift += kDigit) {
    std::fill(count.begin(), count.end(), 0u);
    for (const std::uint64_t e : a) ++count[(e >> shift) & kMask];
    if (std::any_of(count.begin(), count.end(), [&](std::uint32_t c) { return c == a.size(); }))
      continue;  // one digit for all: this pass would not move anything
    std::uint32_t sum = 0;
    for (std::uint32_t& c : count) sum += std::exchange(c, sum);
    for (const std::uint64_t e : a) b[count[(e >> shift) & kMask]++] = e;
    a.swap(b);
  }
  std::vector<std::uint32_t> order(rays.size());
  for (std::size_t i = 0; i < rays.size(); ++i) order[i] = static_cast<std::uint32_t>(a[i]);
  return order;
}

void stageQueries(MapBuffers& buffers, const QueryRequest& q,
                  std::span<const std::uint32_t> ray_order) {
  const std::size_t ray_bytes = q.rays.size() * sizeof(gpu::RayQuery);
  const std::size_t point_bytes = q.lookups.size() * 3 * sizeof(float);
  buffers.ensureQueries(ray_bytes + point_bytes, queryOutputBytes(q.rays.size(), q.lookups.size()));
  auto* bytes = static_cast<unsigned char*>(buffers.query_staging_in.mapped());
  for (std::size_t i = 0; i < q.rays.size(); ++i) {
    const Ray& ray = q.rays[ray_order.empty() ? i : ray_order[i]];
    gpu::RayQuery g{};
    g.max_range = ray.max_range_m;
    g.origin_x = ray.origin.x();
    g.origin_y = ray.origin.y();
    g.origin_z = ray.origin.z();
    g.direction_x = ray.direction.x();
    g.direction_y = ray.direction.y();
    g.direction_z = ray.direction.z();
    g.ignore_unknown = ray.ignore_unknown ? 1u : 0u;
    std::memcpy(bytes + i * sizeof(g), &g, sizeof(g));
  }
  static_assert(sizeof(Eigen::Vector3f) == 3 * sizeof(float));
  if (point_bytes) std::memcpy(bytes + ray_bytes, q.lookups.data(), point_bytes);
}

void recordQueries(Recorder& r, const gpu::ScanParams& sp, const QueryRequest& q,
                   TraceScene ray_scene, std::uint32_t stop_rays) {
  MapBuffers& b = r.buffers;
  const auto rays = static_cast<std::uint32_t>(q.rays.size());
  const auto points = static_cast<std::uint32_t>(q.lookups.size());
  const std::size_t in_bytes = rays * sizeof(gpu::RayQuery) + points * 3 * sizeof(float);
  r.setParams(sp);
  r.stream.copy(b.query_staging_in, b.query_in, in_bytes);
  r.stream.barrier();
  if (rays && ray_scene) {
    recordCastRaysRt(r, ray_scene, {0, stop_rays}, {stop_rays, rays - stop_rays});
  } else if (rays) {
    recordCastRays(r, rays, firstRayState(rays + points));
  }
  if (points)
    recordLookups(r, points, rays,
                  static_cast<std::uint32_t>(rays * sizeof(gpu::RayQuery) / sizeof(float)));
  r.stream.copy(b.query_out, b.query_staging_out, (rays + points) * sizeof(gpu::RayResult));
}

void recordCastRays(Recorder& r, std::uint32_t rays, std::uint32_t first_state) {
  // Where the driver limits loops (see recordRayKeys) the walk runs in segments of the walk
  // budget (30000 on llvmpipe); the longest castRay (3 * 65536 steps, each with a search of up
  // to 17 iterations) then needs 112 continuations, over ever fewer rays. Elsewhere each ray is
  // walked in one segment.
  const std::uint32_t budget = walkBudget(r.device);
  const std::uint32_t rounds = walkContinuations(r.device, 3u * 65536u * 17u);
  // The unfinished walks are listed (walk_count / walk_args, free once the scan's rays are
  // walked) and continued by indirect dispatches, which cost next to nothing once empty.
  // Both lists empty, with whole dispatch arguments: the counters may hold anything here (a map
  // imported and queried before any scan has never had them reset).
  static_assert(offsetof(gpu::ScanCounters, walk_args) ==
                offsetof(gpu::ScanCounters, walk_count) + sizeof(gpu::ScanCounters::walk_count));
  const gpu::ScanCounters fresh = freshCounters();
  r.stream.update(r.buffers.counters, &fresh.walk_count,
                  sizeof(fresh.walk_count) + sizeof(fresh.walk_args),
                  offsetof(gpu::ScanCounters, walk_count));
  r.stream.barrier();
  r.dispatch<Shader::kCastRay>(
      rays, gpu::CastRayConstants{
                .budget = budget, .ray_count = rays, .resume = 0, .first_state = first_state});
  r.continuations<Shader::kCastRay>(rounds, [&](std::uint32_t from, bool) {
    return gpu::CastRayConstants{
        .budget = budget, .ray_count = rays, .resume = from + 1, .first_state = first_state};
  });
}

void recordLookups(Recorder& r, std::uint32_t points, std::uint32_t first_result,
                   std::uint32_t first_float) {
  r.dispatch<Shader::kLookup>(
      points, gpu::LookupConstants{
                  .point_count = points, .first_float = first_float, .first_result = first_result});
}

void collectQueries(const MapBuffers& buffers, const QueryRequest& q,
                    std::span<const std::uint32_t> ray_order, QueryResults& out) {
  const auto* bytes = static_cast<const unsigned char*>(buffers.query_staging_out.mapped());
  out.rays.resize(q.rays.size());
  for (std::size_t i = 0; i < q.rays.size(); ++i) {
    gpu::RayResult res;
    std::memcpy(&res, bytes + i * sizeof(res), sizeof(res));
    if (res.hit == gpu::kRayUnfinished)
      throw Error(ErrorCode::kMissingFeature,
                  "castRays: ray " + std::to_string(ray_order.empty() ? i : ray_order[i]) +
                      " crosses more cells than octovk walks in one batch on this device (its "
                      "loop limit); give it a max range, or split long rays");
    out.rays[ray_order.empty() ? i : ray_order[i]] = {
        res.hit != 0, Eigen::Vector3f(res.end_x, res.end_y, res.end_z)};
  }
  out.lookups.resize(q.lookups.size());
  for (std::size_t i = 0; i < q.lookups.size(); ++i) {
    gpu::LookupResult res;
    std::memcpy(&res, bytes + (q.rays.size() + i) * sizeof(res), sizeof(res));
    out.lookups[i] = {static_cast<CellState>(res.state), res.log_odds, res.depth, res.payload};
  }
}

}  // namespace octovk::passes
