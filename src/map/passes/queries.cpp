// Queries on the map: lookup.comp (OctoMap's search) and cast_ray.comp (OctoMap's castRay), in
// one batch: the rays, then the lookup points, in the input; their results in the same order in
// the output, castRay's walk states after them.
#include <algorithm>
#include <cmath>
#include <cstring>
#include <utility>

#include "map/passes/passes.hpp"

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

// v (any double, NaN included) as an integer in [0, 2^bits): clamped, NaN to 0.
std::uint64_t quantise(double v, unsigned bits) {
  const double top = static_cast<double>((1u << bits) - 1u);
  if (!(v > 0.0)) return 0;
  return v >= top ? static_cast<std::uint64_t>(top) : static_cast<std::uint64_t>(v);
}

// The bits of a (below 2^bits) spread to every `stride`-th bit: one coordinate of a Morton code.
std::uint64_t spread(std::uint64_t a, unsigned bits, unsigned stride) {
  std::uint64_t out = 0;
  for (unsigned i = 0; i < bits; ++i) out |= ((a >> i) & 1u) << (i * stride);
  return out;
}

constexpr unsigned kOriginBits = 10;     // per axis, in blocks of 64 cells around the map's centre
constexpr unsigned kDirectionBits = 11;  // per coordinate of the octahedral map of the direction

// Where a ray sorts: its kind (bit 52), its origin's block along a Morton curve (bits 22..51),
// its direction on the octahedral map along a Morton curve (bits 0..21).
std::uint64_t rayKey(const Ray& ray, double resolution) {
  const double block = resolution * 64.0;
  const double centre = static_cast<double>(1u << (kOriginBits - 1));
  std::uint64_t origin = 0;
  for (unsigned a = 0; a < 3; ++a)
    origin |= spread(quantise(ray.origin[a] / block + centre, kOriginBits), kOriginBits, 3) << a;
  // The octahedral map: the direction onto |x| + |y| + |z| = 1, the lower half folded out.
  const double x = ray.direction.x(), y = ray.direction.y(), z = ray.direction.z();
  const double l1 = std::abs(x) + std::abs(y) + std::abs(z);
  double u = 0.0, v = 0.0;
  if (l1 > 0.0 && std::isfinite(l1)) {
    u = x / l1;
    v = y / l1;
    if (z < 0.0) {
      const double fu = (1.0 - std::abs(v)) * (u >= 0.0 ? 1.0 : -1.0);
      v = (1.0 - std::abs(u)) * (v >= 0.0 ? 1.0 : -1.0);
      u = fu;
    }
  }
  const double scale = static_cast<double>(1u << (kDirectionBits - 1));
  const std::uint64_t direction = spread(quantise((u + 1.0) * scale, kDirectionBits),
                                         kDirectionBits, 2) |
                                  spread(quantise((v + 1.0) * scale, kDirectionBits),
                                         kDirectionBits, 2)
                                      << 1;
  const std::uint64_t kind = ray.ignore_unknown ? 1u : 0u;
  return kind << (3 * kOriginBits + 2 * kDirectionBits) |
         origin << (2 * kDirectionBits) | direction;
}

}  // namespace

std::vector<std::uint32_t> rayOrder(std::span<const Ray> rays, double resolution,
                                    std::uint32_t& stop_rays) {
  // A stable LSD radix sort of (key, index) on 11-bit digits; a digit all keys share is skipped.
  struct Entry {
    std::uint64_t key;
    std::uint32_t index;
  };
  std::vector<Entry> a(rays.size()), b(rays.size());
  stop_rays = 0;
  for (std::size_t i = 0; i < rays.size(); ++i) {
    a[i] = {rayKey(rays[i], resolution), static_cast<std::uint32_t>(i)};
    stop_rays += rays[i].ignore_unknown ? 0u : 1u;
  }
  constexpr unsigned kDigit = 11;
  constexpr unsigned kKeyBits = 3 * kOriginBits + 2 * kDirectionBits + 1;
  std::vector<std::uint32_t> count(std::size_t{1} << kDigit);
  for (unsigned shift = 0; shift < kKeyBits; shift += kDigit) {
    std::fill(count.begin(), count.end(), 0u);
    for (const Entry& e : a) ++count[(e.key >> shift) & ((1u << kDigit) - 1u)];
    if (std::any_of(count.begin(), count.end(), [&](std::uint32_t c) { return c == a.size(); }))
      continue;  // one digit for all: this pass would not move anything
    std::uint32_t sum = 0;
    for (std::uint32_t& c : count) sum += std::exchange(c, sum);
    for (const Entry& e : a) b[count[(e.key >> shift) & ((1u << kDigit) - 1u)]++] = e;
    a.swap(b);
  }
  std::vector<std::uint32_t> order(rays.size());
  for (std::size_t i = 0; i < rays.size(); ++i) order[i] = a[i].index;
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
                   VkDeviceAddress ray_scene, std::uint32_t stop_rays) {
  MapBuffers& b = r.buffers;
  const auto rays = static_cast<std::uint32_t>(q.rays.size());
  const auto points = static_cast<std::uint32_t>(q.lookups.size());
  const std::size_t in_bytes = rays * sizeof(gpu::RayQuery) + points * 3 * sizeof(float);
  r.stream.update(b.params, &sp, sizeof(sp));
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
  const std::uint32_t budget = r.device.walkBudget();
  const std::uint32_t rounds = r.device.walkContinuations(3u * 65536u * 17u);
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
  r.dispatch("cast_ray", rays,
             gpu::CastRayConstants{
                 .budget = budget, .ray_count = rays, .resume = 0, .first_state = first_state});
  r.continuations("cast_ray", rounds, [&](std::uint32_t from, bool) {
    return gpu::CastRayConstants{
        .budget = budget, .ray_count = rays, .resume = from + 1, .first_state = first_state};
  });
}

void recordLookups(Recorder& r, std::uint32_t points, std::uint32_t first_result,
                   std::uint32_t first_float) {
  r.dispatch("lookup", points,
             gpu::LookupConstants{
                 .point_count = points, .first_float = first_float, .first_result = first_result});
}

QueryResults collectQueries(const MapBuffers& buffers, const QueryRequest& q,
                            std::span<const std::uint32_t> ray_order) {
  QueryResults out;
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
    out.lookups[i] = {static_cast<CellState>(res.state), res.log_odds, res.depth};
  }
  return out;
}

}  // namespace octovk::passes
