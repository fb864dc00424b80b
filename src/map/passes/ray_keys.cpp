// Stage 1, points to cells: unproject.comp (depth images), transform_points.comp,
// discretize.comp and ray_keys.comp (the walk of each ray into the cell set); clear_sets.comp
// (at the scan's end, and discretize's end cells before classify reuses the second set).
#include "map/passes/passes.hpp"
#include "map/walk_budget.hpp"

namespace octovk::passes {

void recordRayKeys(Recorder& r, const gpu::ScanParams& sp, const RayKeysInput& in) {
  MapBuffers& b = r.buffers;
  const gpu::ScanCounters counters = freshCounters();
  r.stamp(Stamp::kScanStart);
  r.setParams(sp);
  r.stream.update(b.counters, &counters, sizeof(counters));
  if (in.unproject) {
    r.stream.update(b.depth, &in.camera, sizeof(in.camera));
    r.stream.copyFrom(in.source, in.source_offset, b.depth, in.bytes, sizeof(in.camera));
  } else {
    r.stream.copyFrom(in.source, in.source_offset, b.points, in.bytes);
  }
  if (in.fill_sets) {
    r.stream.fill(b.cell_set_keys, 0xFFFFFFFFu);
    r.stream.fill(b.cell_set_flags, 0u);
    r.stream.fill(b.endpoint_keys, 0xFFFFFFFFu);
  }
  if (in.resume) r.stream.fill(b.pool, 0u, offsetof(gpu::PoolState, halted), 4);
  r.stream.barrier();
  r.stamp(Stamp::kUploaded);
  if (in.unproject)
    r.dispatch<Shader::kUnproject>(sp.point_count,
                                   gpu::UnprojectConstants{.pixel_count = sp.point_count});
  if (in.transform)
    r.dispatch<Shader::kTransformPoints>(
        sp.point_count, gpu::TransformPointsConstants{.point_count = sp.point_count});
  // Where the driver ends an invocation's loops early (the device probe measures it: llvmpipe
  // after 65535 iterations in total, silently, counted for 8 lanes at once), a walk stops after
  // its budget of iterations (steps and hash probes; 30000 there) and is continued by more
  // dispatches, each over the walks left unfinished (3 * 65536 steps reach any border, 24 of
  // 30000 leave room for the probes). A walk still unfinished after them is reported. Where no
  // limit was seen, every ray is walked in one go.
  const std::uint32_t budget = walkBudget(r.device);
  if (in.discretize)
    r.dispatch<Shader::kDiscretize>(sp.point_count,
                                    gpu::DiscretizeConstants{.point_count = sp.point_count});
  if (in.trace) return;  // scan_rays_rt.cpp traces the rays instead
  r.dispatch<Shader::kRayKeys>(
      sp.point_count,
      gpu::RayKeysConstants{.budget = budget,
                            .point_count = sp.point_count,
                            .mode = in.discretize ? gpu::kRayKeysEndCells : gpu::kRayKeysPoints});
  const std::uint32_t rounds = in.walk_rounds;
  r.continuations<Shader::kRayKeys>(rounds, [&](std::uint32_t from, bool last) {
    return gpu::RayKeysConstants{.budget = budget,
                                 .point_count = sp.point_count,
                                 .mode = last ? gpu::kRayKeysContinueLast : gpu::kRayKeysContinue,
                                 .from_list = from};
  });
}

void recordClearSets(Recorder& r, ClearSets which, std::uint32_t points) {
  if (which == ClearSets::kEndCells)
    r.dispatch<Shader::kClearSets>(points, gpu::ClearSetsConstants{.mode = gpu::kClearEndCells});
  else
    r.dispatchIndirect<Shader::kClearSets>(offsetof(gpu::ScanCounters, clear_args),
                                           gpu::ClearSetsConstants{.mode = gpu::kClearScan});
}

}  // namespace octovk::passes
