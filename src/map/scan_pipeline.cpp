#include "map/scan_pipeline.hpp"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <iterator>
#include <string>
#include <string_view>
#include <utility>

#include "gpu/gpu_types.h"
#include "map/buffer_sizes.hpp"
#include "map/walk_budget.hpp"
#include "shader_ids.hpp"

namespace octovk {

namespace {

// Whether an applied scan changed the tree: cells updated, or colours folded into nodes (a leaf
// at the clamping bound takes no update, yet its colour changes).
bool changesTree(const gpu::ScanCounters& counters) {
  return counters.active_cells + counters.leaf_cells + counters.folded_count > 0;
}

double msSince(std::chrono::steady_clock::time_point start) {
  return std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - start)
      .count();
}

}  // namespace

// ---- one scan ---------------------------------------------------------------------------------

void ScanPipeline::record(PendingScan& p) {
  gpu::ScanParams sp = core_.scanParams(p.origin, p.pose ? &*p.pose : nullptr,
                                        p.options.max_range_m, p.count);  // sizes may grow
  sp.changes_log2 = changes_.scanLog2();
  sp.stamp = p.options.stamp;
  sp.tile_group = p.group | ((p.groups - 1) << 16);
  p.noted_changes = sp.changes_log2 != 0;
  passes::RayKeysInput input = p.input;
  if (p.input_at == ScanInput::kStaging)
    input.source = core_.buffers.uploads[p.staging_frame].handle();
  input.fill_sets = core_.buffers.setsNeedFill();  // new sets; else the last scan emptied them
  input.resume = gate_ == Gate::kHalted;
  input.trace = scenes_.traceScans();
  RayScene* scene = input.trace ? &scenes_.scanScene() : nullptr;  // before recording: it may wait
  // A store's capture after the scan's last part, into staging sized for the pool now (taken
  // before recording: it may allocate).
  p.capture.reset();
  if (capture_depth_ != 0 && p.closes_scan && !tiles_.enabled()) {
    // Its change alone, when the host's copy will be the tree as the scan finds it.
    const std::uint64_t others = core_.tree_version - scan_changes_;
    const bool change =
        p.groups == 1 && core_.scans_recorded == capture_recording_ && others == capture_others_;
    p.capture_layout =
        passes::captureLayout(core_.buffers, core_.params.payload, change, input.colors, p.count);
    p.capture = captureStaging(p.capture_layout.bytes());
    capture_recording_ = core_.scans_recorded + 1;  // this recording
    capture_others_ = others;
  }
  passes::Recorder& rec = core_.rec;
  core_.stream.begin(core_.buffers.bindings);
  core_.touched.version = 0;  // the lists become this scan's
  p.recording = ++core_.scans_recorded;
  passes::recordRayKeys(rec, sp, input);
  if (scene) {
    passes::recordScanScene(rec, scene->accel, scene->boxes, scenes_.scanHeader());
    scenes_.noteSceneBytes();  // the build allocated before recording
    passes::recordScanRaysRt(rec, scenes_.scanTrace(), sp.point_count, input.discretize);
  }
  passes::recordClassify(rec, input.discretize, sp.point_count);
  passes::recordTreeUpdate(rec);
  passes::recordPrune(rec);
  if (input.colors && p.closes_scan)  // after every part: the nodes the points end in
    passes::recordColorFold(rec, p.count, p.options.color_fold,
                            core_.buffers.uploads[p.staging_frame].handle(), input.colors_offset);
  if (leaf_boxes_every_scan_) passes::recordLeafBoxes(rec);
  if (p.queries) passes::recordQueries(rec, core_.queryParams(), *p.queries);
  passes::recordClearSets(rec);
  if (p.capture) passes::recordCapture(rec, p.capture_layout, *p.capture);
  passes::recordReadback(rec);
  p.serial = core_.stream.submit();
  p.frame = core_.stream.frame();
  p.state = ScanState::kInFlight;
  ++p.stats.cell_set_attempts;
  core_.buffers.setSetsNeedFill(false);
  gate_ = Gate::kOpen;
  core_.leaf_boxes = leaf_boxes_every_scan_ ? LeafBoxes::kCurrent : LeafBoxes::kStale;
}

std::uint64_t ScanPipeline::submit(const ScanSource& source, const Eigen::Vector3f& origin,
                                   const Pose* pose, const ScanOptions& options) {
  return enqueue(source, origin, pose, options, ScanCaller::kSubmit, nullptr, nullptr);
}

// Before a map's first scan: the passes every walked scan records, built side by side, the
// longest first (ray_keys, the walk, takes llvmpipe 30-40 ms, the others 0.2-3 ms each); later
// maps of the context find them built. The others (discretize, unproject, ray tracing, queries)
// are built at first use.
void ScanPipeline::buildScanPasses() {
  if (core_.params.scan_rays != ScanRays::kWalk) return;
  using vk::Shader;
  static constexpr Shader kScanPasses[] = {
      Shader::kRayKeys,  Shader::kListCells, Shader::kDescend,   Shader::kClassifyBlocks,
      Shader::kPrune,    Shader::kClassify,  Shader::kLink,      Shader::kTransformPoints,
      Shader::kTreeGate, Shader::kAlloc,     Shader::kClearSets, Shader::kTreeBegin,
      Shader::kTreeFixup};
  std::string_view names[std::size(kScanPasses)];
  for (std::size_t i = 0; i < std::size(kScanPasses); ++i)
    names[i] = vk::shaderName(kScanPasses[i]);
  core_.device.buildPasses(names);
}

std::uint64_t ScanPipeline::enqueue(const ScanSource& source, const Eigen::Vector3f& origin,
                                    const Pose* pose, const ScanOptions& options, ScanCaller caller,
                                    const QueryRequest* queries, QueryResults* results) {
  const auto start = std::chrono::steady_clock::now();
  const std::size_t count = source.count();
  checkScan(core_.device, count, origin, pose, options);
  checkPayloadOptions(core_.params.payload, count, options);
  if (queries && !queries_.fitsOneBatch(queries->rays.size(), queries->lookups.size()))
    throw Error(ErrorCode::kInvalidArgument,
                "insertPointCloud with queries: " + std::to_string(queries->rays.size()) +
                    " rays and " + std::to_string(queries->lookups.size()) +
                    " search points are more than one submission takes on this device (one "
                    "buffer binding of " +
                    std::to_string(core_.device.maxBindingBytes()) +
                    " bytes each way); insert the scan, then call search() / castRays(), "
                    "which split any batch");
  PendingScan p;
  p.stats.points = count;
  p.caller = caller;
  if (count > 0) {
    if (next_ticket_ == 1) buildScanPasses();
    scenes_.releaseUnderCap();  // the scan's growth comes first; castRays builds it again
    const std::size_t depth_bytes = depthBytesOf(source);
    if (growth_.mustGrow(count, depth_bytes)) {
      flush();  // buffers are replaced (and rebound) only while no scan is in flight
      growth_.growFor(count, depth_bytes);
    }
    if (queries) {
      passes::stageQueries(core_.buffers, *queries);  // after the growth: nothing in flight
      // Sized now: collected once the scan is in the map, where nothing may fail.
      results->rays.resize(queries->rays.size());
      results->lookups.resize(queries->lookups.size());
    }
    p.input_at = source.device == VK_NULL_HANDLE ? ScanInput::kStaging : ScanInput::kCaller;
    p.origin = origin;
    if (pose) p.pose = *pose;
    p.options = options;
    p.options.colors = {};  // staged: the caller's span may go once this returns
    p.count = count;
    // A frame for its first part first: the scans it waits for (refused ones run again) say
    // how many parts scans like it need.
    while (pending_.size() >= core_.stream.frames()) confirmOldest();
    p.groups = groupsFor(count);
    // The same for every part: the walk's rounds (from every point's ray length) and its kind.
    p.input.transform = pose != nullptr;
    p.input.discretize = options.discretize;
    p.input.walk_rounds =
        walkRounds(core_.device,
                   worstSteps(source, origin, pose, options.max_range_m, core_.params.resolution));
  }
  const std::uint64_t ticket = next_ticket_;
  p.ticket = p.stats.ticket = ticket;
  // A scan applied in groups of tiles is one part per group, each staged in its own frame.
  for (std::uint32_t group = 0; group < p.groups; ++group) {
    PendingScan part = p;
    part.group = group;
    part.closes_scan = group + 1 == p.groups;
    if (count > 0) {
      // The frame this part records into must have no scan of ours in flight.
      while (pending_.size() >= core_.stream.frames()) confirmOldest();
      part.staging_frame = core_.stream.nextFrame();
      part.input = stage(source, core_.buffers.uploads[part.staging_frame]);
      part.input.transform = p.input.transform;
      part.input.discretize = p.input.discretize;
      part.input.walk_rounds = p.input.walk_rounds;
      if (!options.colors.empty() && part.closes_scan) {
        part.input.colors = true;
        part.input.colors_offset = stageColors(source, part.input, options.colors,
                                               core_.buffers.uploads[part.staging_frame]);
      }
      if (part.closes_scan) {
        part.queries = queries;
        part.results = results;
      }
    }
    // The part takes its place in the queue before it is submitted: a submitted scan changes the
    // map, so nothing that can fail (a queue that cannot grow) may come between the two.
    pending_.push_back(std::move(part));
    PendingScan& q = pending_.back();  // stays valid: the deque only grows at its end meanwhile
    if (count > 0) {
      try {
        // A caller's semaphore guards its buffer: the first submission that reads it waits.
        if (source.wait != VK_NULL_HANDLE && group == 0)
          core_.stream.waitBeforeNextSubmit(source.wait, source.wait_value);
        record(q);
      } catch (const Error& e) {
        pending_.pop_back();
        core_.stream.waitBeforeNextSubmit(VK_NULL_HANDLE, 0);  // not for some later submission
        if (group == 0) throw;
        // Parts of the scan are submitted (a recording fails only on a device error): the
        // last of them closes it, and the message says the map holds them.
        pending_.back().closes_scan = true;
        throw Error(e.code(),
                    std::string(e.what()) + " [the scan was being applied in " +
                        std::to_string(p.groups) + " groups of tiles; the map holds the first " +
                        std::to_string(group) + "]",
                    ticket);
      } catch (...) {
        pending_.pop_back();
        core_.stream.waitBeforeNextSubmit(VK_NULL_HANDLE, 0);
        if (group > 0) pending_.back().closes_scan = true;
        throw;
      }
    }
    q.stats.wall_ms = msSince(start);
  }
  ++next_ticket_;  // only for a scan submitted (or empty)
  // Results already there are taken without waiting (statistics early, growth ahead asked for);
  // never this scan's own: a scan refused on the device is then always noticed after the scan
  // submitted next, which the device refused too (halted) and which runs again with it.
  while (pending_.size() > 1 && core_.stream.finished(pending_.front().serial)) confirmOldest();
  return ticket;
}

// ---- results ----------------------------------------------------------------------------------

bool ScanPipeline::takeResult(PendingScan& p, const gpu::ScanCounters& counters,
                              const gpu::PoolState& pool) {
  if (counters.status & gpu::kStatusNotApplied) {
    p.state = ScanState::kRefused;
    capture_recording_ = 0;  // its capture is not kept: the next one recorded is whole
    return false;
  }
  if (counters.status & gpu::kStatusPoolFull)
    throw Error(ErrorCode::kInternal,
                "internal error: the node pool ran out during a scan despite its size check; "
                "please report this with the input");
  ScanStats& stats = p.stats;
  // The scan is in the map: from here on nothing may throw (statistics go without, instead).
  std::vector<double> t;
  try {
    t = core_.stream.timestampsNs(p.frame);
  } catch (const std::bad_alloc&) {
    // no memory for the timestamps: the statistics go without device times
  }
  const auto span = [&](passes::Stamp from, passes::Stamp to) {
    return core_.rec.spanMs(p.frame, t, from, to);
  };
  using passes::Stamp;
  stats.device.upload_ms = span(Stamp::kScanStart, Stamp::kUploaded);
  stats.device.ray_keys_ms = span(Stamp::kUploaded, Stamp::kClassifyStart);
  stats.device.classify_ms = span(Stamp::kClassifyStart, Stamp::kClassifyEnd);
  stats.device.tree_update_ms = span(Stamp::kClassifyEnd, Stamp::kTreeUpdateEnd);
  stats.device.prune_ms = span(Stamp::kTreeUpdateEnd, Stamp::kPruneEnd);
  stats.device.leaf_boxes_ms = span(Stamp::kPruneEnd, Stamp::kLeafBoxesEnd);
  // With ScanRays::kRayTracing, the parts of ray_keys_ms: boxes, build, then the trace.
  stats.device.scan_boxes_ms = span(Stamp::kBoxesStart, Stamp::kBoxesEnd);
  stats.device.scan_build_ms = span(Stamp::kBoxesEnd, Stamp::kBuildEnd);
  stats.device.scan_trace_ms = span(Stamp::kBuildEnd, Stamp::kClassifyStart);
  if (p.queries) passes::collectQueries(core_.buffers, *p.queries, {}, *p.results);
  stats.skipped_no_depth = counters.no_depth;
  stats.skipped_nonfinite = counters.skipped_nonfinite - counters.no_depth;  // NaN points
  stats.skipped_outside = counters.skipped_outside;
  stats.free_cells = counters.free_cells;
  stats.occupied_cells = counters.occupied_cells;
  stats.aborted_cells = counters.aborted;
  stats.nodes = pool.root_exists ? pool.live_nodes + tiles_.spilledNodes() : 0;
  last_nodes_ = stats.nodes;
  if (changesTree(counters)) {
    core_.treeChanged();
    ++scan_changes_;
    if (p.noted_changes) changes_.scanNoted();  // the change set holds what it changed
    // Nothing recorded after it, and all its cells in one part: the lists are its own.
    if (p.recording == core_.scans_recorded && p.groups == 1) {
      core_.touched.version = core_.tree_version;
      std::copy(std::begin(counters.touched_count), std::end(counters.touched_count),
                core_.touched.counts.begin());
      core_.touched.generation = core_.buffers.listsGeneration();
      core_.touched.pool = pool;
      core_.touched.folded = counters.folded_count;
      core_.touched.folded_at = passes::foldedListAt(core_.buffers, p.count);
      core_.touched.fold_generation = core_.buffers.foldGeneration();
    }
  }
  if (p.capture && p.closes_scan) keepCapture(p, counters, pool);
  if (parts_.ticket != p.ticket) parts_ = PartTotals{.ticket = p.ticket};
  if (p.groups > 1) notePart(p, counters);
  if (!p.closes_scan) {
    // A part of a scan applied in groups of tiles: the scan's last part reports them all.
    ++parts_.parts;
    addCounts(parts_.sum, stats);
  } else {
    // The parts before it, if any.
    stats.tile_groups += parts_.parts;
    addCounts(stats, parts_.sum);
    if (p.caller == ScanCaller::kInsert)
      blocking_stats_ = stats;  // the call's result, which must not need an allocation
    else
      keepStats(stats);
  }
  // Room ahead for more scans like this one, so that they are not run twice: after a blocking
  // call, for the next one; after a submitted scan, for as many as may be in flight when the
  // growth is next possible (the submits behind it were recorded before its result was seen).
  // Grown at the next submit (or at the end of the blocking call).
  const std::uint64_t scans_ahead = p.caller == ScanCaller::kInsert ? 1 : core_.stream.frames();
  growth_.noteApplied(counters, pool, scans_ahead, p.count);
  return true;
}

void ScanPipeline::keepStats(const ScanStats& stats) noexcept {
  try {
    finished_stats_.push_back(stats);
  } catch (const std::bad_alloc&) {
    return;  // the scan is in the map; without host memory its statistics are dropped
  }
  if (finished_stats_.size() > kKeptStats) finished_stats_.pop_front();
}

void ScanPipeline::confirmOldest() {
  PendingScan& p = pending_.front();
  if (p.state == ScanState::kEmpty) {  // in the map once the scans before it are
    p.stats.nodes = last_nodes_;
    keepStats(p.stats);
    pending_.pop_front();
    return;
  }
  core_.stream.wait(p.serial);
  gpu::ScanCounters counters{};
  gpu::PoolState pool{};
  passes::readBack(core_.buffers, p.frame, counters, pool);
  if (!takeResult(p, counters, pool)) return recover(counters, pool);
  pending_.pop_front();
}

void ScanPipeline::recover(gpu::ScanCounters counters, gpu::PoolState pool) {
  // Every scan behind the refused one was refused too (halted): the map is as before it.
  core_.stream.waitIdle();
  gate_ = Gate::kHalted;
  // The scratch a split scan's part needs: what splitting it halves.
  constexpr std::uint32_t kScratchShort =
      gpu::kStatusHashFull | gpu::kStatusEndpointHashFull | gpu::kStatusListsShort;
  try {
    while (!pending_.empty()) {
      if (pending_.front().state == ScanState::kEmpty) {
        confirmOldest();
        continue;
      }
      if (pending_.front().state == ScanState::kInFlight) {
        // A whole scan halted behind the refused one starts in as many parts as scans like it
        // were last seen to need.
        if (pending_.front().groups == 1 && pending_.front().closes_scan)
          splitOldest(groupsFor(pending_.front().count));
        PendingScan& p = pending_.front();
        // Halted on the device behind the refused one, its result not read: run it again.
        // What the scans run again so far asked for (`pool`: the last one's state, the current
        // one); the scratch stays: it holds the inputs of the scans still to run.
        growth_.growAhead(&pool, /*release=*/false);
        record(p);
        core_.stream.wait(p.serial);
        passes::readBack(core_.buffers, p.frame, counters, pool);
      }
      while (!takeResult(pending_.front(), counters, pool)) {
        gate_ = Gate::kHalted;
        // Tiles the scan reaches are off the device: loaded (others evicted for them) and the
        // scan run again; where they do not fit with the pool's other tiles, the scan goes on
        // in groups of tiles, each part loading its own.
        if (counters.status & gpu::kStatusTilesNeeded) {
          if (!rebalanceTiles(counters)) {
            if (!splitOldest(2))
              throw Error(ErrorCode::kOutOfDeviceMemory,
                          "insertPointCloud: the tiles that the smallest part of the scan reaches "
                          "do not fit the node pool beside the tree above them under "
                          "max_device_bytes; the map is unchanged. Raise max_device_bytes");
          }
          PendingScan& p = pending_.front();
          record(p);
          core_.stream.wait(p.serial);
          passes::readBack(core_.buffers, p.frame, counters, pool);
          continue;
        }
        // A walk outran the rounds estimated for its length (the set's probes): every round.
        const std::uint32_t full = fullWalkRounds(core_.device);
        if ((counters.status & gpu::kStatusRayCut) && pending_.front().input.walk_rounds < full) {
          pending_.front().input.walk_rounds = full;
          counters.status &= ~gpu::kStatusRayCut;
        }
        try {
          growth_.growForRetry(counters, pool);
        } catch (const Error& e) {
          // The scratch cannot grow: the scan goes on in two parts, each the cells of half its
          // tiles. A pool that cannot grow takes the room of the sets and lists first (they
          // grow again for the parts, within what is left); where even that is not enough the
          // map outgrows the cap, and the scan fails. The parts the device applied stay in the
          // map; the error of a later part says so.
          const bool pool_short = counters.status & gpu::kStatusPoolShort;
          if (e.code() != ErrorCode::kOutOfDeviceMemory || (counters.status & gpu::kStatusRayCut) ||
              !(pool_short || (counters.status & kScratchShort)))
            throw;
          // A map that spills tiles (TileWorkingSet) evicts cold ones for the pool's room.
          if (!(pool_short && rebalanceTiles(counters))) {
            if (!growth_.poolBeforeScratch(counters, pool)) throw;
            const std::uint32_t parts = partsNeeded(counters);
            if (!splitOldest(parts)) throw;
            // Scans submitted from now on start with as many parts for as many points.
            const PendingScan& first = pending_.front();
            split_groups_ = std::max(split_groups_, std::min(first.groups, kMaxTileGroups));
            split_points_ = first.count;
          }
        }
        PendingScan& p = pending_.front();
        record(p);
        core_.stream.wait(p.serial);
        passes::readBack(core_.buffers, p.frame, counters, pool);
      }
      pending_.pop_front();
    }
  } catch (const Error& e) {
    // The map holds every scan before the one that failed; it and the later ones are dropped.
    const std::uint64_t failed = pending_.empty() ? 0 : pending_.front().ticket;
    // A scan applied in groups of tiles keeps the parts the device applied before this one.
    const std::size_t parts_in = !pending_.empty() && parts_.ticket == failed ? parts_.parts : 0;
    std::size_t dropped = 0;
    for (const PendingScan& p : pending_) dropped += p.ticket != failed && p.closes_scan;
    ++dropped;
    const bool alone = dropped == 1 && pending_.front().caller == ScanCaller::kInsert;
    pending_.clear();
    gate_ = Gate::kHalted;
    if (parts_in > 0) {
      std::string message = e.message();
      for (std::size_t at; (at = message.find("; the map is unchanged")) != std::string::npos;)
        message.erase(at, std::string_view("; the map is unchanged").size());
      throw Error(e.code(),
                  message + " [scan " + std::to_string(failed) +
                      " ran out of device memory while applied in groups of tiles: the map " +
                      "holds the first " + std::to_string(parts_in) +
                      (parts_in == 1 ? " part" : " parts") + " of it" +
                      (dropped > 1 ? ", and not the " + std::to_string(dropped - 1) +
                                         " scans submitted after it"
                                   : std::string()) +
                      "]",
                  failed, e.detail());
    }
    if (alone) throw;  // the blocking call's own scan: its message says the map is unchanged
    throw Error(e.code(),
                std::string(e.what()) + " [scan " + std::to_string(failed) +
                    " was not inserted, nor the " + std::to_string(dropped - 1) +
                    " submitted after it; the map holds every scan before it]",
                failed);
  } catch (...) {
    pending_.clear();
    gate_ = Gate::kHalted;
    throw;
  }
}

bool ScanPipeline::rebalanceTiles(const gpu::ScanCounters& counters) {
  if (!tiles_.enabled()) return false;
  const PendingScan& p = pending_.front();
  const Eigen::Vector3f sensor = p.pose ? p.pose->transform(p.origin) : p.origin;
  // A part's loads are pinned while it runs; a colour scan's for the whole scan, all its parts:
  // its last part folds the colours of every part's end points, which must still be on the
  // device.
  const std::string scan = core_.params.payload == Payload::kColor
                               ? std::to_string(p.ticket)
                               : std::to_string(p.ticket) + "/" + std::to_string(p.group) + "/" +
                                     std::to_string(p.groups);
  const bool partly_applied = parts_.ticket == p.ticket && parts_.parts > 0;
  if (counters.status & gpu::kStatusTilesNeeded)
    return tiles_.load(counters, sensor, scan, partly_applied);
  return tiles_.makeRoom(counters.new_blocks, sensor, scan, partly_applied);
}

// ---- scans applied in groups of tiles ----

void ScanPipeline::addCounts(ScanStats& into, const ScanStats& part) noexcept {
  into.free_cells += part.free_cells;
  into.occupied_cells += part.occupied_cells;
  into.aborted_cells += part.aborted_cells;
  into.cell_set_attempts += part.cell_set_attempts;
  into.wall_ms += part.wall_ms;
  into.device.upload_ms += part.device.upload_ms;
  into.device.ray_keys_ms += part.device.ray_keys_ms;
  into.device.classify_ms += part.device.classify_ms;
  into.device.tree_update_ms += part.device.tree_update_ms;
  into.device.prune_ms += part.device.prune_ms;
  into.device.leaf_boxes_ms += part.device.leaf_boxes_ms;
}

ScanPipeline::ScratchFill ScanPipeline::scratchFill(
    const gpu::ScanCounters& counters) const noexcept {
  const MapBuffers& b = core_.buffers;
  const auto slots = [](std::uint32_t log2) {
    return 0.75 * static_cast<double>(std::size_t{1} << log2);
  };
  const std::size_t bound = sizes::touchedBound(
      std::size_t{counters.active_cells} + counters.leaf_cells, counters.brick_entries);
  return {.bricks = static_cast<double>(counters.brick_entries) / slots(b.hashLog2()),
          .blocks = static_cast<double>(counters.new_blocks) / slots(b.endpointLog2()),
          .cells = static_cast<double>(bound) /
                   static_cast<double>(std::max<std::size_t>(b.listEntries(), 1)),
          .cell_list = static_cast<double>(counters.cell_entries) /
                       static_cast<double>(std::max<std::size_t>(b.cellEntries(), 1))};
}

bool ScanPipeline::splitOldest(std::uint32_t parts) {
  const PendingScan& p = pending_.front();
  parts = std::min(parts, kMaxTileGroups / p.groups);
  if (parts < 2) return false;
  // Tiles whose hash is `group` modulo `groups` are those that are `group + i * groups` modulo
  // `parts` times as many, for i below `parts`: the first part now, the others right behind it,
  // from the same input (nothing is staged while recovering).
  std::vector<PendingScan> split(parts, p);
  for (std::uint32_t i = 0; i < parts; ++i) {
    PendingScan& part = split[i];
    part.groups = p.groups * parts;
    part.group = p.group + i * p.groups;
    // The closing part (colours, queries, statistics) is the one that runs last.
    part.closes_scan = p.closes_scan && i + 1 == parts;
    if (!part.closes_scan) {
      part.queries = nullptr;
      part.results = nullptr;
    }
    if (i > 0) {
      part.state = ScanState::kInFlight;  // to be recorded when its turn comes
      part.stats = ScanStats{};
      part.stats.ticket = p.ticket;
      part.stats.points = p.count;
    }
  }
  // A deque keeps references to its other elements across push_front and pop_front.
  pending_.pop_front();
  for (std::uint32_t i = parts; i-- > 0;) pending_.push_front(std::move(split[i]));
  return true;
}

std::uint32_t ScanPipeline::partsNeeded(const gpu::ScanCounters& counters) const {
  const ScratchFill fill = scratchFill(counters);
  // Classify stops at a full cell set or second set: the other counts are then partial. Only
  // short cell lists beside a set with room leave the cells counted in full.
  if (!(counters.status & gpu::kStatusEndpointHashFull) &&
      onlyCellListsShort(counters, core_.buffers.hashLog2()))
    return static_cast<std::uint32_t>(std::clamp(std::ceil(1.15 * fill.cell_list), 2.0, 64.0));
  if (counters.status & (gpu::kStatusHashFull | gpu::kStatusEndpointHashFull)) return 2;
  return static_cast<std::uint32_t>(
      std::clamp(std::ceil(1.15 * std::max({fill.blocks, fill.cells, fill.cell_list})), 2.0, 64.0));
}

std::uint32_t ScanPipeline::groupsFor(std::size_t count) const {
  if (split_groups_ <= 1 || split_points_ == 0) return 1;
  // As many parts for as many points (the cells a scan touches grow with its points).
  const double groups = std::ceil(static_cast<double>(split_groups_) * static_cast<double>(count) /
                                  static_cast<double>(split_points_));
  return static_cast<std::uint32_t>(std::clamp(groups, 1.0, double{kMaxTileGroups}));
}

void ScanPipeline::notePart(const PendingScan& p, const gpu::ScanCounters& counters) noexcept {
  const ScratchFill fill = scratchFill(counters);
  parts_.fill = std::max({parts_.fill, fill.bricks, fill.blocks, fill.cells, fill.cell_list});
  parts_.fewest = parts_.fewest == 0 ? p.groups : std::min(parts_.fewest, p.groups);
  if (!p.closes_scan) return;
  // A part of 1/fewest of the tiles filled `parts_.fill`: the scan needed about fewest * fill
  // parts of this size; a fifth more for the next scans, which may touch more cells (a part
  // refused costs a walk of every ray, a part more a little less; a half more cost the paper
  // building under a quarter cap about a part a scan more than the refusals it saved).
  split_groups_ = static_cast<std::uint32_t>(
      std::clamp(std::ceil(1.2 * parts_.fill * static_cast<double>(parts_.fewest)), 1.0,
                 double{kMaxTileGroups}));
  split_points_ = p.count;
}

// ---- synchronisation --------------------------------------------------------------------------

void ScanPipeline::flush() {
  while (!pending_.empty()) confirmOldest();
}

std::vector<ScanStats> ScanPipeline::takeStats() {
  while (!pending_.empty() && core_.stream.finished(pending_.front().serial)) confirmOldest();
  std::vector<ScanStats> out(finished_stats_.begin(), finished_stats_.end());
  finished_stats_.clear();
  return out;
}

bool ScanPipeline::finished(std::uint64_t ticket) {
  while (!pending_.empty() && pending_.front().ticket <= ticket &&
         core_.stream.finished(pending_.front().serial))
    confirmOldest();
  return ticket < next_ticket_ && (pending_.empty() || pending_.front().ticket > ticket);
}

// The blocking call: the same path, waited for. Its errors leave the map as before the scan.
ScanStats ScanPipeline::insert(const ScanSource& source, const Eigen::Vector3f& origin,
                               const Pose* pose, const ScanOptions& options,
                               const QueryRequest* queries, QueryResults* results) {
  const auto start = std::chrono::steady_clock::now();
  flush();
  if (queries && tiles_.enabled())
    throw Error(ErrorCode::kInvalidArgument,
                "insertPointCloud with queries: this map spills tiles off the device "
                "(spillTilesTo), and queries in the scan's submission would read the tree as "
                "the scan left it on the device; insert the scan, then query (while no tile is "
                "spilled)");
  if (source.count() == 0) {
    checkScan(core_.device, 0, origin, pose, options);
    ScanStats stats;
    stats.ticket = next_ticket_++;
    if (queries) *results = queries_.run(*queries);
    const gpu::PoolState pool = core_.readPool();
    stats.nodes = pool.root_exists ? pool.live_nodes + tiles_.spilledNodes() : 0;
    stats.wall_ms = msSince(start);
    return stats;
  }
  const std::uint64_t ticket =
      enqueue(source, origin, pose, options, ScanCaller::kInsert, queries, results);
  flush();
  // The scan is in the map: from here on nothing may throw, or a caller that retries would
  // insert it twice. Growth for the next scan is best-effort; what fails is asked for again
  // by the next scan, which then reports it with the map unchanged.
  growth_.growAheadBestEffort();
  // Its statistics are the call's result, not left for takeStats().
  ScanStats stats = blocking_stats_;
  if (stats.ticket != ticket)
    throw Error(ErrorCode::kInternal, "internal error: the blocking scan's statistics are missing");
  stats.wall_ms = msSince(start);
  return stats;
}

// ---- a store's captures ----------------------------------------------------------------------

std::shared_ptr<vk::Buffer> ScanPipeline::captureStaging(std::size_t bytes) {
  bytes = std::max<std::size_t>(bytes, 4);
  for (std::shared_ptr<vk::Buffer>& b : capture_buffers_)
    if (b.use_count() == 1 && b->size() >= bytes) return b;
  // Too small or all held: drop the free ones, make one with a quarter more for the growth.
  std::erase_if(capture_buffers_, [](const auto& b) { return b.use_count() == 1; });
  capture_buffers_.push_back(std::make_shared<vk::Buffer>(core_.device, bytes + bytes / 4, true));
  return capture_buffers_.back();
}

void ScanPipeline::keepCapture(const PendingScan& p, const gpu::ScanCounters& counters,
                               const gpu::PoolState& pool) {
  // Nothing here may throw: the scan is in the map. A capture that cannot be kept is missing,
  // and the store's commit of the scan fails for want of host memory (MapWriter::finish).
  try {
    const passes::CaptureLayout& l = p.capture_layout;
    const std::size_t count = std::size_t{pool.bump} * 8;
    const bool change = l.records != 0;
    if (!change && count > l.nodes) return;
    CaptureMirror::Kept k;
    k.ticket = p.ticket;
    k.change = change;
    k.nodes = count;
    PoolCapture& c = k.pool;
    c.version = core_.tree_version;
    k.base = c.version - (changesTree(counters) ? 1 : 0);
    c.root_exists = pool.root_exists != 0;
    c.kind = core_.params.payload;
    const auto* bytes = static_cast<const unsigned char*>(p.capture->mapped());
    std::size_t entries = 0;  // of the touched lists
    for (unsigned level = 0; level < gpu::kTreeDepth; ++level)
      entries += counters.touched_count[level];
    const std::size_t folded = l.folded ? counters.folded_count : 0;
    // The touched lists' entries: copied whole, or one per change record (then the folded
    // list's).
    const std::uint32_t* touched = nullptr;
    if (change) {
      k.complete = entries + folded <= l.records;
      const auto* records = reinterpret_cast<const gpu::CaptureRecord*>(bytes);
      if (k.complete) k.records.assign(records, records + entries + folded);
    } else {
      c.nodes = {reinterpret_cast<const gpu::Node*>(bytes), count};
      if (l.payload_bytes)
        c.payload = {reinterpret_cast<const std::uint32_t*>(bytes + l.node_bytes), count};
      c.memory = p.capture;
      if (entries <= l.touched_bytes / 4)
        touched = reinterpret_cast<const std::uint32_t*>(bytes + l.node_bytes + l.payload_bytes);
    }
    // The nodes at depths 0..capture_depth_ on the scan's updated paths: its own touched lists
    // when it ran in one part (the levels lie one after another from the deepest); and the tiles
    // whose colours the fold changed, from the change's folded records (a whole capture has
    // none: every tile is compared).
    c.incremental = p.groups == 1 && capture_depth_ < gpu::kTreeDepth &&
                    (touched || (change && k.complete)) && (change || folded == 0);
    if (c.incremental) {
      for (std::size_t r = entries; r < entries + folded; ++r)
        c.folded.push_back(PoolCapture::Folded::of(k.records[r].key_xy, k.records[r].key_z_depth));
      std::size_t base = 0;
      for (unsigned level = gpu::kTreeDepth; level-- > 0;) {
        const std::size_t n = counters.touched_count[level];
        if (level <= capture_depth_)
          for (std::size_t e = base; e < base + n; ++e)
            c.changed.push_back(touched ? touched[e] : k.records[e].index);
        base += n;
      }
      std::sort(c.changed.begin(), c.changed.end());
    }
    captures_.keep(std::move(k), core_.stream.frames() + 1);
  } catch (const std::bad_alloc&) {
    // without host memory the capture is dropped
  }
}

bool ScanPipeline::capturing(std::uint64_t ticket) const noexcept {
  if (tiles_.enabled()) return false;
  for (const PendingScan& p : pending_)
    if (p.ticket == ticket && p.closes_scan && p.capture) return true;
  return captures_.holds(ticket);
}

std::optional<PoolCapture> ScanPipeline::takeCapture(std::uint64_t ticket, std::uint64_t since) {
  while (!pending_.empty() && pending_.front().ticket <= ticket) confirmOldest();
  if (tiles_.enabled()) return std::nullopt;
  std::optional<PoolCapture> c = captures_.take(ticket);
  if (!c) return c;
  // The changed nodes are the ones since `since` when the tree was at `since` before the scan
  // (or the scan changed nothing).
  const bool unchanged = c->version == since;
  c->incremental = c->incremental && (unchanged || c->version == since + 1);
  if (!c->incremental || unchanged) {
    c->changed.clear();
    c->folded.clear();
  }
  return c;
}

}  // namespace octovk
