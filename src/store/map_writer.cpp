// MapWriter: the map committed to a store after each scan, only the tiles that changed.
#include <algorithm>
#include <chrono>
#include <future>
#include <memory>
#include <string_view>
#include <thread>
#include <utility>

#include "map/store_access.hpp"
#include "store/store.hpp"

namespace octovk::store {

std::uint64_t bodyHash(const std::string& body) {
  // 64 bits, with the size mixed in: a changed tile mistaken for its old self would be lost.
  const std::uint64_t h = std::hash<std::string_view>{}(body);
  return h ^ (body.size() * 0x9E3779B97F4A7C15ull);
}

bool Store::waitForCommit(const std::string&, double seconds) {
  std::this_thread::sleep_for(std::chrono::duration<double>(seconds));
  return false;
}

void readTileFormat(MapInfo& info, std::int64_t format, const std::string& what) {
  const std::optional<Payload> payload = payloadOfTileFormat(format);
  if (!payload || info.tile_depth < 1 || info.tile_depth > 16)
    throw Error(ErrorCode::kInvalidArgument,
                what + " holds tiles of format " + std::to_string(format) + " at depth " +
                    std::to_string(info.tile_depth) +
                    "; this octovk reads formats 1-3 at depths 1-16: use the octovk that wrote it");
  info.params.payload = *payload;
}

MapInfo requireMap(Store& store, const std::string& name, const std::string& remedy) {
  std::optional<MapInfo> info = store.map(name);
  if (!info)
    throw Error(ErrorCode::kInvalidArgument,
                "store '" + store.location() + "' holds no map '" + name + "'; " +
                    (remedy.empty() ? std::string() : remedy + ", or ") + "'octovk store info " +
                    store.location() + "' lists its maps");
  return *info;
}

namespace {

// treeFromTiles, its errors naming the store and the map the tiles came from.
HostTree storedTree(const Store& store, const std::string& name, std::span<const Tile> tiles,
                    unsigned tile_depth, Payload payload) {
  try {
    return treeFromTiles(tiles, tile_depth, payload);
  } catch (const Error& e) {
    throw Error(e.code(), "store '" + store.location() + "', map '" + name + "': " + e.what());
  }
}

}  // namespace

HostTree loadTree(Store& store, const std::string& name) {
  const MapInfo info = requireMap(store, name);
  return storedTree(store, name, store.tiles(name, nullptr), info.tile_depth, info.params.payload);
}

MapWriter::MapWriter(Store& store, std::string name, const MapParams& params)
    : store_(store), name_(std::move(name)) {
  existed_ = !store_.createMap(name_, params);
  info_ = *store_.map(name_);
}

std::vector<Tile> MapWriter::readAll(bool keep_bodies) {
  std::vector<Tile> tiles = store_.tiles(name_, &last_seq_);
  hashes_.clear();
  bodies_.clear();
  for (const Tile& t : tiles) {
    hashes_[t.key] = bodyHash(t.body);
    if (keep_bodies) bodies_[t.key] = t.body;
  }
  bodies_known_ = keep_bodies;
  return tiles;
}

HostTree MapWriter::load() {
  // The bodies are kept from the first reload on (reload()): a writer alone never needs them.
  return storedTree(store_, name_, readAll(false), info_.tile_depth, info_.params.payload);
}

HostTree MapWriter::reload() {
  if (!bodies_known_)
    return storedTree(store_, name_, readAll(true), info_.tile_depth, info_.params.payload);
  // Only what the other writers' scans wrote since this one's last: the keys that remain,
  // and the tiles whose version is newer.
  TileChanges changes = store_.changesSince(name_, last_seq_);
  for (auto it = bodies_.begin(); it != bodies_.end();) {
    if (std::binary_search(changes.keys.begin(), changes.keys.end(), it->first)) {
      ++it;
    } else {
      hashes_.erase(it->first);
      it = bodies_.erase(it);
    }
  }
  for (Tile& t : changes.changed) {
    hashes_[t.key] = bodyHash(t.body);
    bodies_[t.key] = std::move(t.body);
  }
  last_seq_ = changes.last_seq;
  std::vector<Tile> tiles;
  tiles.reserve(bodies_.size());
  for (const auto& [key, body] : bodies_) tiles.push_back({key, body});
  return storedTree(store_, name_, tiles, info_.tile_depth, info_.params.payload);
}

bool MapWriter::begin(OccupancyMap& map) {
  StoreAccess::attach(map);  // before the scan's recovery, which may move tiles
  finish();                  // a background commit first: its error is this call's
  const std::uint64_t last = store_.lock(name_);
  if (last == last_seq_) return false;
  const auto start = std::chrono::steady_clock::now();
  try {
    const HostTree tree = reload();  // in the locked transaction: sets last_seq_
    map.upload(tree);
    version_ = StoreAccess::version(map);  // the tree the hashes describe
    ++reloads_;
    reload_s_ += std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  } catch (...) {
    store_.unlock();
    forget();  // the map is unknown: the next begin() loads it again
    throw;
  }
  return true;
}

MapWriter::~MapWriter() { abandon(); }

void MapWriter::failed(const Error& e, const PendingCommit& pending) {
  const std::uint64_t row = last_seq_ + 1;
  forget();  // the device map is ahead of the store: the next begin() reloads it
  throw Error(e.code(), "store '" + store_.location() + "' did not commit scan " +
                            std::to_string(pending.scan) + " of '" + pending.source +
                            "' (counted from 0, as 'octovk store log' prints it; log row " +
                            std::to_string(row) + "): " + e.what());
}

template <class Work>
void MapWriter::commitOrForget(const PendingCommit& pending, Work&& work) {
  try {
    work();
  } catch (const Error& e) {
    failed(e, pending);
  } catch (...) {
    forget();
    throw;
  }
}

CommitStats MapWriter::finish() {
  if (deferred_) {
    const Deferred d = std::move(*deferred_);
    deferred_.reset();
    auto c = std::make_unique<PendingCommit>();
    c->source = d.source;
    c->scan = d.scan;
    const auto start = std::chrono::steady_clock::now();
    std::optional<PoolCapture> pool;
    try {
      pool = StoreAccess::takeCapture(*d.map, d.ticket, version_);  // waits for that scan only
    } catch (...) {
      forget();  // the scan's own error: the map does not hold it
      throw;
    }
    if (!pool) {  // dropped for want of host memory (ScanPipeline::keepCapture)
      forget();
      throw Error(ErrorCode::kOutOfHostMemory,
                  "store '" + store_.location() + "' did not commit scan " +
                      std::to_string(d.scan) + " of '" + d.source +
                      "': the host ran out of memory for its copy of the map; the store holds "
                      "the scans before it: free some memory and run again");
    }
    c->pool = std::move(*pool);
    c->stats.find_s =
        std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
    commitOrForget(*c, [&] {
      prepare(*c);
      write(*c);
    });
    apply(*c);
    return c->stats;
  }
  if (!background_.valid()) return {};
  std::future<void> running = std::move(background_);
  // The pending commit (and its captured pool, a device buffer) goes on this thread.
  const std::unique_ptr<PendingCommit> pending = std::move(pending_commit_);
  commitOrForget(*pending, [&] { running.get(); });
  apply(*pending);
  return pending->stats;
}

void MapWriter::abandon() noexcept {
  if (background_.valid()) {
    try {
      background_.get();
    } catch (...) {
      // the run is failing already: its own error is the one to report
    }
  }
  pending_commit_.reset();
  deferred_.reset();
  forget();
}

void MapWriter::apply(PendingCommit& c) {
  // Only once committed: a failed commit leaves the writer as before, to be tried again.
  for (const std::uint64_t key : c.removed) hashes_.erase(key);
  for (const auto& [key, h] : c.updated) hashes_[key] = h;
  last_seq_ = c.entry.seq;
  if (bodies_known_) {
    for (const std::uint64_t key : c.removed) bodies_.erase(key);
    for (const Tile& t : c.changed) bodies_[t.key] = t.body;
  }
  version_ = c.pool.version;
  CommitStats& t = totals_;
  ++t.seq;
  t.tiles_written += c.stats.tiles_written;
  t.tiles_removed += c.stats.tiles_removed;
  t.tiles_compared += c.stats.tiles_compared;
  t.body_bytes += c.stats.body_bytes;
  t.find_s += c.stats.find_s;
  t.write_s += c.stats.write_s;
  max_body_bytes_ = std::max(max_body_bytes_, c.stats.body_bytes);
}

void MapWriter::requireType(const OccupancyMap& map) const {
  if (map.params().payload != info_.params.payload)
    throw Error(ErrorCode::kInvalidArgument,
                "map '" + name_ + "' of store '" + store_.location() + "' is " +
                    std::string(treeTypeName(info_.params.payload)) + "; the map to commit is " +
                    treeTypeName(map.params().payload));
}

std::unique_ptr<MapWriter::PendingCommit> MapWriter::capture(OccupancyMap& map,
                                                             const std::string& source,
                                                             std::uint64_t scan) {
  const auto start = std::chrono::steady_clock::now();
  requireType(map);
  auto c = std::make_unique<PendingCommit>();
  c->source = source;
  c->scan = scan;
  // The pool as the device holds it, and the nodes above the tile depth that the scan changed
  // (when the map is the last commit's plus this one scan).
  c->pool = StoreAccess::capture(map, version_, info_.tile_depth);
  // Tiles off the device (spillTilesTo) are cut at the working set's depth.
  if (info_.tile_depth != gpu::kTileDepth && map.spilledTiles() > 0)
    throw Error(ErrorCode::kInvalidArgument,
                "store: this store cuts its tiles at depth " + std::to_string(info_.tile_depth) +
                    ", and a map that spills tiles off the device commits only to a store cut at " +
                    std::to_string(gpu::kTileDepth) +
                    "; raise --max-device-memory, or integrate into a new store");
  for (auto& [path, subtree] : StoreAccess::takeDirtyTiles(map))
    c->dirty.emplace(tileKey(gpu::kTileDepth, path), std::move(subtree));
  c->stats.find_s = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  return c;
}

void MapWriter::prepare(PendingCommit& c) const {
  const auto start = std::chrono::steady_clock::now();
  const PoolCapture& pool = c.pool;
  CommitStats& stats = c.stats;
  // A tile's body compared with the committed one: written where it differs or is new.
  const auto compare = [&](std::uint64_t key, std::string body) {
    const std::uint64_t h = bodyHash(body);
    const auto old = hashes_.find(key);
    if (old == hashes_.end() || old->second != h) {
      stats.body_bytes += body.size();
      c.updated.emplace_back(key, h);
      c.changed.push_back({key, std::move(body)});
    }
  };
  // The tiles to compare, and the key ranges in which a committed tile not among them is gone.
  // When the map is the last commit's plus one scan, only the tiles under the scan's changed
  // nodes: a walk of its updated paths, not of the map. Tiles that left the device while a scan
  // was partly applied (c.dirty) are found by a walk of every tile.
  const bool incremental = pool.incremental && version_ != kUnknownVersion && c.dirty.empty();
  PoolTileChanges found;
  if (incremental) {
    found = changedPoolTiles(pool, info_.tile_depth,
                             [&](std::uint64_t key) { return hashes_.contains(key); });
  } else {
    found.tiles = poolTiles(pool, info_.tile_depth);
    found.cleared.push_back(tileKeyRange(0, 0));
  }
  for (const PoolTile& t : found.tiles) {
    // A tile off the device (OccupancyMap::spillTilesTo) is as the store holds it when it left
    // between scans, after its last change was captured; one that left while a scan was
    // partly applied comes with its subtree (c.dirty), compared as any tile.
    if (pool.nodes[t.node].link & gpu::kFlagEvicted) {
      if (const auto dirty = c.dirty.find(t.key); dirty != c.dirty.end()) {
        ++stats.tiles_compared;
        compare(t.key, nodeStream(dirty->second));
        continue;
      }
      if (!hashes_.contains(t.key))
        throw Error(ErrorCode::kInternal,
                    "internal error: a tile off the device was never committed; please report "
                    "this with the input");
      continue;
    }
    ++stats.tiles_compared;
    compare(t.key, poolTileBody(pool, t));
  }
  // A stamped map's stamps above the tile depth (kUpperStampsKey), compared like a tile.
  const bool had_upper = hashes_.contains(kUpperStampsKey);
  if (std::string upper = poolUpperStamps(pool, info_.tile_depth); !upper.empty())
    compare(kUpperStampsKey, std::move(upper));
  else if (had_upper)
    c.removed.push_back(kUpperStampsKey);
  std::vector<std::uint64_t> listed;  // in key order, as found.tiles
  listed.reserve(found.tiles.size());
  for (const PoolTile& t : found.tiles) listed.push_back(t.key);
  for (const auto& [first, last] : found.cleared)
    for (auto it = hashes_.lower_bound(first); it != hashes_.end() && it->first < last; ++it)
      if (it->first != kUpperStampsKey &&
          !std::binary_search(listed.begin(), listed.end(), it->first))
        c.removed.push_back(it->first);
  std::sort(c.removed.begin(), c.removed.end());
  c.removed.erase(std::unique(c.removed.begin(), c.removed.end()), c.removed.end());
  c.entry.seq = last_seq_ + 1;
  c.entry.source = c.source;
  c.entry.scan = c.scan;
  c.entry.time_us = std::chrono::duration_cast<std::chrono::microseconds>(
                        std::chrono::system_clock::now().time_since_epoch())
                        .count();
  stats.find_s += std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  stats.seq = c.entry.seq;
  stats.tiles_written = c.changed.size();
  stats.tiles_removed = c.removed.size();
}

void MapWriter::write(PendingCommit& c) {
  const auto start = std::chrono::steady_clock::now();
  store_.commit(name_, c.changed, c.removed, c.entry);
  c.stats.write_s = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
}

CommitStats MapWriter::commit(OccupancyMap& map, const std::string& source, std::uint64_t scan) {
  finish();
  map.flush();
  const std::unique_ptr<PendingCommit> c = capture(map, source, scan);
  prepare(*c);
  write(*c);
  apply(*c);
  return c->stats;
}

void MapWriter::commitInBackground(OccupancyMap& map, const std::string& source,
                                   std::uint64_t scan) {
  finish();
  // The scans after this one bring their capture in their own submission (not while tiles may
  // leave the device); this one may, and is then committed by finish(), with the next scan
  // already submitted.
  StoreAccess::captureScans(map, info_.tile_depth);
  if (const std::uint64_t ticket = StoreAccess::capturingTicket(map); ticket != 0) {
    requireType(map);
    deferred_ = Deferred{&map, source, scan, ticket};
    return;
  }
  map.flush();
  pending_commit_ = capture(map, source, scan);
  // The tiles and the transaction on a thread of their own. Until finish() has waited for it,
  // this thread touches neither the store nor the writer's state (begin(), commit() and the
  // destructor call finish() first).
  background_ = std::async(std::launch::async, [this, c = pending_commit_.get()] {
    prepare(*c);
    write(*c);
  });
}

}  // namespace octovk::store
